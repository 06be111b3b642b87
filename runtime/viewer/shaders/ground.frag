#version 330 core
flat in vec3 v_color;
in float v_dist;
uniform vec3 u_fog_color;
uniform vec2 u_fog;
out vec4 frag;
void main() {
    float f = clamp((v_dist - u_fog.x) / (u_fog.y - u_fog.x), 0.0, 1.0);
    frag = vec4(mix(v_color, u_fog_color, f * f), 1.0);
}
