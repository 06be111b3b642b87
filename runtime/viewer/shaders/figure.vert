#version 330 core
layout(location = 0) in vec4 a_pos;          // ndc x, y, z, fog factor
layout(location = 1) in vec4 a_seg0;         // segments in window pixels: ax, ay, bx, by
layout(location = 2) in vec4 a_seg1;
layout(location = 3) in vec4 a_seg2;
layout(location = 4) in vec4 a_seg3;
layout(location = 5) in vec4 a_seg4;
layout(location = 6) in vec4 a_seg5;
layout(location = 7) in vec4 a_r0123;        // radii in pixels
layout(location = 8) in vec4 a_r45w01;       // r4, r5, depth 0, depth 1
layout(location = 9) in vec4 a_w2345;        // depths 2..5
layout(location = 10) in vec4 a_skin;
layout(location = 11) in vec4 a_shirt;
layout(location = 12) in vec4 a_legs;
flat out vec4 v_seg[6];
flat out float v_r[6];
flat out float v_w[6];
flat out vec3 v_skin;
flat out vec3 v_shirt;
flat out vec3 v_legs;
flat out float v_fog;
void main() {
    v_seg[0] = a_seg0; v_seg[1] = a_seg1; v_seg[2] = a_seg2;
    v_seg[3] = a_seg3; v_seg[4] = a_seg4; v_seg[5] = a_seg5;
    v_r[0] = a_r0123.x; v_r[1] = a_r0123.y; v_r[2] = a_r0123.z; v_r[3] = a_r0123.w;
    v_r[4] = a_r45w01.x; v_r[5] = a_r45w01.y;
    v_w[0] = a_r45w01.z; v_w[1] = a_r45w01.w;
    v_w[2] = a_w2345.x; v_w[3] = a_w2345.y; v_w[4] = a_w2345.z; v_w[5] = a_w2345.w;
    v_skin = a_skin.rgb; v_shirt = a_shirt.rgb; v_legs = a_legs.rgb;
    v_fog = a_pos.w;
    gl_Position = vec4(a_pos.xyz, 1.0);
}
