// Shared constants and helpers for every Scanlight shader.
#ifndef SCANLIGHT_COMMON_GLSL
#define SCANLIGHT_COMMON_GLSL
const float PI = 3.14159265358979323846;
const float TWO_PI = 6.28318530717958647692;
const float INV_PI = 0.31830988618379067154;

float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// Clamp before pow(1 - x, 5): llvmpipe returns NaN for x slightly above 1.
float schlick_weight(float cos_theta) {
    float m = clamp(1.0 - cos_theta, 0.0, 1.0);
    float m2 = m * m;
    return m2 * m2 * m;
}
#endif
