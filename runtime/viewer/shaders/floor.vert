#version 330 core
// Floor markings (flat, facing up, a few mm above the ground): the view-independent part of
// shade.glsl's lighting is constant over them, so it is done here once per vertex.
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec3 a_color;
uniform mat4 u_vp;
uniform vec3 u_eye;
flat out vec3 v_lit;
out vec3 v_to_eye;

#include "shade.glsl"

void main() {
    float ao = mix(0.72, 1.0, clamp(a_pos.y / 0.6, 0.0, 1.0));   // as lit.frag
    v_lit = lit(a_color * ao, a_normal);
    v_to_eye = u_eye - a_pos;
    gl_Position = u_vp * vec4(a_pos, 1.0);
}
