// Shared constants and helpers for every Scanlight shader.
#ifndef SCANLIGHT_COMMON_GLSL
#define SCANLIGHT_COMMON_GLSL
const float PI = 3.14159265358979323846;
const float TWO_PI = 6.28318530717958647692;
const float INV_PI = 0.31830988618379067154;

// PCG-style integer hash (the lobe frames' and the micro-buffer frames' per-receiver seeds).
uint hash_pcg(uint x) {
    x = x * 747796405u + 2891336453u;
    uint w = ((x >> ((x >> 28u) + 4u)) ^ x) * 277803737u;
    return (w >> 22u) ^ w;
}
float hash_unit(uint h) { return float(h >> 8u) * (1.0 / 16777216.0); }   // [0, 1)

// A receiver's pixel in the whole image from its pixel in a tile (tile = x0, y0, tile width,
// image width): per-receiver seeds follow the image, so a tile's receivers get the seeds one
// render of the image gives those pixels, not the same seeds in every tile.
uint image_pixel(uvec4 tile, uint tile_pixel) {
    uint w = max(tile.z, 1u);
    return (tile.y + tile_pixel / w) * tile.w + tile.x + tile_pixel % w;
}

float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// Clamp before pow(1 - x, 5): llvmpipe returns NaN for x slightly above 1.
float schlick_weight(float cos_theta) {
    float m = clamp(1.0 - cos_theta, 0.0, 1.0);
    float m2 = m * m;
    return m2 * m2 * m;
}
#endif
