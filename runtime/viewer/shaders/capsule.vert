#version 330 core

uniform samplerBuffer u_bones;   // RGB32F, 2 texels per bone: p0, p1 (world)
uniform samplerBuffer u_style;   // RGBA32F, 1 texel per bone: radius, r, g, b
uniform mat4 u_view;
uniform mat4 u_proj;
uniform int u_first;             // first bone of this draw
flat out vec3 v_color;
#ifdef FAR
uniform vec3 u_light;
uniform vec3 u_up;
uniform vec2 u_fog;
out vec2 v_st;
flat out vec3 v_len;
flat out vec3 v_lq;
flat out vec3 v_uq;
flat out float v_fog;
#else
out vec3 v_q;
flat out vec3 v_a;
flat out vec3 v_b;
flat out float v_r;
#endif
const vec2 CORNERS[6] = vec2[6](vec2(0.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
                                vec2(0.0, -1.0), vec2(1.0, 1.0), vec2(0.0, 1.0));
void main() {
    int k = gl_VertexID / 6;
    vec2 corner = CORNERS[gl_VertexID - k * 6];
    int bone = u_first + k;
    vec3 a = (u_view * vec4(texelFetch(u_bones, 2 * bone).xyz, 1.0)).xyz;
    vec3 b = (u_view * vec4(texelFetch(u_bones, 2 * bone + 1).xyz, 1.0)).xyz;
    vec4 st = texelFetch(u_style, bone);
    float r = st.x;
    v_color = st.yzw;
    // quad in the plane through the bone's centre facing the eye, covering the central
    // projections of both end spheres (grown for the perspective silhouette)
    vec3 c = 0.5 * (a + b);
    float lc = max(length(c), 1e-4);
    vec3 n = -c / lc;
    float dc = dot(c, n);
    float da = min(dot(a, n), -1e-3);
    float db = min(dot(b, n), -1e-3);
    float ka = dc / da, kb = dc / db;
    vec3 pa = a * ka, pb = b * kb;
    float persp = lc / max(lc - r, 1e-3);
    float ra = r * ka * persp, rb = r * kb * persp;
    vec3 u = pb - pa;
    float lu = length(u);
    if (lu < 1e-5) {
        vec3 h = abs(n.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
        u = normalize(cross(h, n));
    } else {
        u /= lu;
    }
    vec3 v = cross(n, u);
    // an end sphere's outline on the plane is an ellipse stretched by 1 / cos of the angle
    // between its direction and the plane's normal; the quad reaches the larger one's extent
    // on every side (plus 2 %: sampled outlines need at most 0.9995 of it)
    float ca = max(-da / max(length(a), 1e-4), 0.2);
    float cb = max(-db / max(length(b), 1e-4), 0.2);
    float R = max(ra / ca, rb / cb) * 1.02;
    vec3 q = (corner.x < 0.5 ? pa - u * R : pb + u * R) + v * (corner.y * R);
#ifdef FAR
    v_st = vec2(corner.x < 0.5 ? -R : lu + R, corner.y * R);
    v_len = vec3(lu, ra, rb);
    v_lq = vec3(dot(u_light, u), dot(u_light, v), dot(u_light, n));
    v_uq = vec3(dot(u_up, u), dot(u_up, v), dot(u_up, n));
    float f = clamp((lc - u_fog.x) / (u_fog.y - u_fog.x), 0.0, 1.0);
    v_fog = f * f;
#else
    v_q = q;
    v_a = a; v_b = b; v_r = r;
#endif
    gl_Position = u_proj * vec4(q, 1.0);
}
