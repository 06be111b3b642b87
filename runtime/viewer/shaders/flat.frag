#version 330 core
in vec3 v_color;
in vec3 v_ground;
in vec3 v_pos;
in float v_fade;
in float v_dist;
uniform vec3 u_eye;
uniform vec3 u_fog_color;
uniform vec2 u_fog;
out vec4 frag;
void main() {
    vec3 c = v_color;
    if (v_fade > 0.0) {      // grid lines fade into the ground colour with distance
        c = mix(c, v_ground, clamp(length(u_eye - v_pos) / v_fade, 0.0, 1.0));
    }
    float f = clamp((v_dist - u_fog.x) / (u_fog.y - u_fog.x), 0.0, 1.0);
    frag = vec4(mix(c, u_fog_color, f * f), 1.0);
}
