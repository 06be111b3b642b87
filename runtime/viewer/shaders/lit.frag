#version 330 core
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_color;
uniform vec3 u_eye;
out vec4 frag;

#include "shade.glsl"

void main() {
    float ao = mix(0.72, 1.0, clamp(v_pos.y / 0.6, 0.0, 1.0));   // darker towards the ground
    vec3 to_eye = u_eye - v_pos;
    float d = length(to_eye);
    vec3 c = shade(v_color * ao, normalize(v_normal), to_eye / d, 0.08);
    frag = vec4(fog(c, d), 1.0);
}
