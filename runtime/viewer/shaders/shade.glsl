uniform vec3 u_light;      // towards the key light, in the frame the normals are in
uniform vec3 u_up;         // world up, same frame
uniform vec3 u_fog_color;
uniform vec2 u_fog;        // fog start, end (metres from the eye)
vec3 lit(vec3 base, vec3 n) {          // diffuse key light + hemisphere ambient
    float diff = max(dot(n, u_light), 0.0);
    float hemi = 0.5 + 0.5 * dot(n, u_up);
    vec3 ambient = mix(vec3(0.34, 0.31, 0.28), vec3(0.62, 0.68, 0.78), hemi);
    return base * (ambient * 0.62 + vec3(1.0, 0.95, 0.86) * diff * 0.72);
}
vec3 shade(vec3 base, vec3 n, vec3 to_eye, float spec_amount) {
    float diff = max(dot(n, u_light), 0.0);
    float hemi = 0.5 + 0.5 * dot(n, u_up);
    vec3 ambient = mix(vec3(0.34, 0.31, 0.28), vec3(0.62, 0.68, 0.78), hemi);
    vec3 h = normalize(to_eye + u_light);
    float s = max(dot(n, h), 0.0);
    s *= s; s *= s; s *= s;                      // ^8: the powers as products (no exp2/log2)
    float spec = s * s * s * spec_amount;        // ^24
    float r = 1.0 - max(dot(n, to_eye), 0.0);
    float rim = r * r * r * 0.16;
    return base * (ambient * 0.62 + vec3(1.0, 0.95, 0.86) * diff * 0.72) + vec3(spec)
           + rim * vec3(0.75, 0.82, 1.0);
}
vec3 fog(vec3 c, float dist) {
    float f = clamp((dist - u_fog.x) / (u_fog.y - u_fog.x), 0.0, 1.0);
    return mix(c, u_fog_color, f * f);
}
