#version 330 core
in vec3 v_uvk;
in vec4 v_color;
out vec4 frag;
void main() {
    float r = length(v_uvk.xy);
    float a;
    if (v_uvk.z < 0.5) {
        a = 1.0 - smoothstep(0.2, 1.0, r);
    } else {
        float w = fwidth(r) * 1.5;
        a = smoothstep(0.70 - w, 0.70, r) * (1.0 - smoothstep(1.0 - w, 1.0, r));
    }
    if (a <= 0.004) discard;
    frag = vec4(v_color.rgb, v_color.a * a);
}
