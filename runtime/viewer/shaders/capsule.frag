#version 330 core
in vec3 v_q;
flat in vec3 v_a;
flat in vec3 v_b;
flat in float v_r;
flat in vec3 v_color;
uniform mat4 u_proj;
out vec4 frag;

#include "shade.glsl"

float sphere(vec3 rd, vec3 c, float r) {   // first hit of the ray from the origin, or 1e20
    float b = dot(rd, c);
    float h = b * b - dot(c, c) + r * r;
    return h > 0.0 ? b - sqrt(h) : 1e20;
}
void main() {
    vec3 rd = normalize(v_q);
    vec3 ba = v_b - v_a;
    vec3 oa = -v_a;
    float baba = dot(ba, ba);
    float bard = dot(ba, rd);
    float baoa = dot(ba, oa);
    float rdoa = dot(rd, oa);
    float oaoa = dot(oa, oa);
    float A = baba - bard * bard;
    float B = baba * rdoa - baoa * bard;
    float C = baba * oaoa - baoa * baoa - v_r * v_r * baba;
    float H = B * B - A * C;
    float t = 1e20;
    if (H < 0.0 && A > 1e-9) discard;          // misses the infinite cylinder: misses the capsule
    if (A > 1e-9) {
        float tb = (-B - sqrt(max(H, 0.0))) / A;
        float y = baoa + tb * bard;
        if (y > 0.0 && y < baba) t = tb;
    }
    if (t > 1e19) t = min(sphere(rd, v_a, v_r), sphere(rd, v_b, v_r));
    if (t > 1e19 || t <= 0.0) discard;
    vec3 p = t * rd;
    float hh = baba > 0.0 ? clamp(dot(p - v_a, ba) / baba, 0.0, 1.0) : 0.0;
    vec3 nrm = (p - v_a - hh * ba) / v_r;
    vec4 clip = u_proj * vec4(p, 1.0);
    gl_FragDepth = 0.5 * (clip.z / clip.w) + 0.5;
    vec3 c = shade(v_color, normalize(nrm), -rd, 0.12);
    frag = vec4(fog(c, t), 1.0);
}
