#version 330 core
uniform float u_horizon_y;   // NDC y of the horizon
out float v_y;
void main() {
    int k = gl_VertexID;
    float x = (k == 1 || k == 2 || k == 4) ? 1.0 : -1.0;
    float y = (k == 2 || k == 4 || k == 5) ? 1.0 : clamp(u_horizon_y - 0.02, -1.0, 1.0);
    v_y = y;
    gl_Position = vec4(x, y, 0.0, 1.0);
}
