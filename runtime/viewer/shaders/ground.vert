#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_color;
uniform mat4 u_vp;
uniform vec3 u_eye;
uniform vec3 u_forward;
flat out vec3 v_color;
out float v_dist;

#include "shade.glsl"

void main() {
    v_color = lit(a_color.rgb, vec3(0.0, 1.0, 0.0));
    v_dist = dot(a_pos - u_eye, u_forward);
    gl_Position = u_vp * vec4(a_pos, 1.0);
}
