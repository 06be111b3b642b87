#version 330 core
flat in vec4 v_seg[6];
flat in float v_r[6];
flat in float v_w[6];
flat in vec3 v_skin;
flat in vec3 v_shirt;
flat in vec3 v_legs;
flat in float v_fog;
uniform int u_part[6];       // 0 skin, 1 shirt, 2 trousers
uniform vec3 u_light;        // view space: x right, y up, z towards the eye
uniform vec3 u_up;
uniform vec3 u_fog_color;
out vec4 frag;
void main() {
    vec2 p = gl_FragCoord.xy;
    float best = 1e20;
    int k = -1;
    vec3 n = vec3(0.0, 0.0, 1.0);
    for (int i = 0; i < 6; i++) {
        vec2 a = v_seg[i].xy;
        vec2 ba = v_seg[i].zw - a;
        float h = clamp(dot(p - a, ba) / max(dot(ba, ba), 1e-6), 0.0, 1.0);
        vec2 d = p - a - h * ba;
        float q = dot(d, d) / (v_r[i] * v_r[i]);
        if (q < 1.0 && v_w[i] < best) {
            best = v_w[i];
            k = i;
            n = vec3(d / v_r[i], sqrt(1.0 - q));
        }
    }
    if (k < 0) discard;
    int part = u_part[k];
    vec3 base = part == 0 ? v_skin : (part == 1 ? v_shirt : v_legs);
    float diff = max(dot(n, u_light), 0.0);
    float hemi = 0.5 + 0.5 * dot(n, u_up);
    vec3 amb = mix(vec3(0.34, 0.31, 0.28), vec3(0.62, 0.68, 0.78), hemi);
    vec3 c = base * (amb * 0.62 + vec3(1.0, 0.95, 0.86) * diff * 0.72);
    frag = vec4(mix(c, u_fog_color, v_fog), 1.0);
}
