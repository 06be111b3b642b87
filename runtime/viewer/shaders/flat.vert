#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_color;     // rgb, fade distance (0 = no fade)
uniform mat4 u_vp;
uniform vec3 u_eye;
uniform vec3 u_ground;
uniform vec3 u_forward;                   // camera forward: view depth is linear over a triangle
uniform float u_fade_scale;               // grid fade distances grow with the camera distance
out vec3 v_color;
out vec3 v_ground;
out vec3 v_pos;
out float v_fade;
out float v_dist;

#include "shade.glsl"

void main() {
    v_color = lit(a_color.rgb, vec3(0.0, 1.0, 0.0));   // no view-dependent terms
    v_ground = lit(u_ground, vec3(0.0, 1.0, 0.0));
    v_pos = a_pos;
    v_fade = a_color.a * u_fade_scale;
    v_dist = dot(a_pos - u_eye, u_forward);
    gl_Position = u_vp * vec4(a_pos, 1.0);
}
