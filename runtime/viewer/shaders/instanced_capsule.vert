#version 330 core
layout(location = 0) in vec4 a_vert;     // unit normal in the bone frame (u, v, w), end s
layout(location = 1) in vec3 i_p0;
layout(location = 2) in vec3 i_p1;
layout(location = 3) in vec4 i_style;    // radius, r, g, b
uniform mat4 u_vp;
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_color;
void main() {
    vec3 axis = i_p1 - i_p0;
    float len = length(axis);
    vec3 W = len > 1e-6 ? axis / len : vec3(0.0, 1.0, 0.0);
    vec3 h = abs(W.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 U = normalize(cross(h, W));
    vec3 V = cross(W, U);
    vec3 n = a_vert.x * U + a_vert.y * V + a_vert.z * W;
    vec3 p = mix(i_p0, i_p1, a_vert.w) + i_style.x * n;
    v_pos = p;
    v_normal = n;
    v_color = i_style.yzw;
    gl_Position = u_vp * vec4(p, 1.0);
}
