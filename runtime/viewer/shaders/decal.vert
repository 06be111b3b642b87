#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_uvk;       // corner u, v, kind (0 blob, 1 ring)
layout(location = 2) in vec4 a_color;
uniform mat4 u_vp;
out vec3 v_uvk;
out vec4 v_color;
void main() {
    v_uvk = a_uvk;
    v_color = a_color;
    gl_Position = u_vp * vec4(a_pos, 1.0);
}
