// Receivers: the object pixels of the G-buffer, compacted in image order (app/pbgi/gbuffer.py).
// Four vec4 per receiver, the G-buffer's MRT layout plus the pixel index:
//   r0 = (position relative to the hierarchy origin, uintBitsToFloat(pixel index in the tile))
//   r1 = (shading normal, material id)     r2 = (tangent orthogonal to the normal, roughness)
//   r3 = (base colour, metallic)           (base colour / roughness / metallic include textures)
#ifndef SCANLIGHT_RECEIVERS_GLSL
#define SCANLIGHT_RECEIVERS_GLSL
#ifndef RECEIVER_BINDING
#define RECEIVER_BINDING 0
#endif
layout(std430, binding = RECEIVER_BINDING) readonly buffer Receivers { vec4 receivers[]; };

vec3 receiver_position(uint i) { return receivers[4u * i].xyz; }
uint receiver_pixel(uint i) { return floatBitsToUint(receivers[4u * i].w); }
vec3 receiver_normal(uint i) { return receivers[4u * i + 1u].xyz; }
uint receiver_material(uint i) { return uint(receivers[4u * i + 1u].w + 0.5); }
vec4 receiver_tangent_roughness(uint i) { return receivers[4u * i + 2u]; }
vec4 receiver_base_metallic(uint i) { return receivers[4u * i + 3u]; }
#endif
