#version 330 core
in vec2 v_st;
flat in vec3 v_len;
flat in vec3 v_lq;
flat in vec3 v_uq;
flat in vec3 v_color;
flat in float v_fog;
uniform vec3 u_fog_color;
out vec4 frag;
void main() {
    float L = v_len.x;
    float h = clamp(v_st.x / max(L, 1e-6), 0.0, 1.0);
    float r = mix(v_len.y, v_len.z, h);
    vec2 d = vec2(v_st.x - h * L, v_st.y) / r;
    float q = dot(d, d);
    if (q > 1.0) discard;
    vec3 n = vec3(d, sqrt(1.0 - q));
    float diff = max(dot(n, v_lq), 0.0);
    float hemi = 0.5 + 0.5 * dot(n, v_uq);
    vec3 amb = mix(vec3(0.34, 0.31, 0.28), vec3(0.62, 0.68, 0.78), hemi);
    vec3 c = v_color * (amb * 0.62 + vec3(1.0, 0.95, 0.86) * diff * 0.72);
    frag = vec4(mix(c, u_fog_color, v_fog), 1.0);
}
