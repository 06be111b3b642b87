#version 330 core
// shade.glsl's shade() for the normal (0, 1, 0), specular 0.08, with its view-dependent terms
// (specular and rim light) per pixel. For unit vectors e (to the eye) and l (to the light),
// the half vector's y is (e.y + l.y) / sqrt(2 + 2 e.l), so no vector is normalised; the
// powers are products.
flat in vec3 v_lit;
in vec3 v_to_eye;
out vec4 frag;

#include "shade.glsl"

void main() {
    float k = inversesqrt(dot(v_to_eye, v_to_eye));
    float d = 1.0 / k;
    float ey = v_to_eye.y * k;
    float s = max((ey + u_light.y) * inversesqrt(2.0 + 2.0 * k * dot(v_to_eye, u_light)), 0.0);
    s *= s; s *= s; s *= s;                      // ^8
    float r = 1.0 - max(ey, 0.0);
    vec3 c = v_lit + vec3(s * s * s * 0.08) + (r * r * r * 0.16) * vec3(0.75, 0.82, 1.0);
    frag = vec4(fog(c, d), 1.0);
}
