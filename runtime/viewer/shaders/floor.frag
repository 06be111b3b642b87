#version 330 core
// shade.glsl's shade() for the normal (0, 1, 0), specular 0.08, with its view-dependent terms
// (specular and rim light) per pixel and the powers as products.
flat in vec3 v_lit;
in vec3 v_to_eye;
out vec4 frag;

#include "shade.glsl"

void main() {
    float d = length(v_to_eye);
    vec3 e = v_to_eye / d;
    vec3 h = normalize(e + u_light);
    float s = max(h.y, 0.0);
    s *= s; s *= s; s *= s;                      // ^8
    float r = 1.0 - max(e.y, 0.0);
    vec3 c = v_lit + vec3(s * s * s * 0.08) + (r * r * r * 0.16) * vec3(0.75, 0.82, 1.0);
    frag = vec4(fog(c, d), 1.0);
}
