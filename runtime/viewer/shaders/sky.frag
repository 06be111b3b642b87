#version 330 core
in float v_y;
uniform float u_horizon_y;   // NDC y of the horizon
uniform vec3 u_horizon;
uniform vec3 u_zenith;
out vec4 frag;
void main() {
    float t = clamp((v_y - u_horizon_y) / 1.6, 0.0, 1.0);
    frag = vec4(mix(u_horizon, u_zenith, sqrt(t)), 1.0);
}
