"""OpenGL 3.3 core renderer for the viewer (pyglet's GL bindings; import only after
:func:`runtime.viewer.headless.configure`).

A frame is a handful of draw calls, none per character or per bone:

* backdrop, painted without depth: a sky gradient above the horizon line, the ground (a static
  plane whose cells grow away from the world's centre; lighting per vertex, fog from the view
  depth, which interpolates exactly over a triangle), the world's "plaza" (its bounds) in a
  lighter tone, and a line grid (1 m over the plaza, 5 m around it) fading with distance;
* static environment: obstacle footprints extruded to prisms, seats, boxes, spawn points,
  regions (one static vertex buffer, per-pixel lighting);
* characters, by level of detail (``Renderer.character_bones``):
  - figures at least ``LOD_NEAR_PX`` tall on screen: ONE non-instanced draw of ``6 * bones``
    vertices; each bone is a capsule drawn as a ray-cast impostor -- the vertex shader pulls the
    bone's endpoints and radius from texture buffers (``gl_VertexID / 6`` is the bone) and spans
    a camera-facing quad over the capsule's projection; the fragment shader intersects the view
    ray with the capsule, writes the true depth (limbs and characters intersect correctly) and
    shades the exact normal. Per frame the CPU uploads the bone endpoints with one
    ``glBufferSubData``;
  - smaller figures: ONE draw of one screen-space quad per figure; the CPU projects the figure's
    6 capsules (body, head, whole legs and arms) to pixels, and the fragment shader keeps the
    nearest capsule covering the pixel.
  (Instanced capsule meshes cost about 17 us per instance on llvmpipe, 0.2-0.6 s a frame for
  2000 characters; on llvmpipe the cost of small figures is per primitive and per 4x4 pixel
  block touched, hence impostors and one quad per distant figure. ``runtime.viewer.baseline``
  keeps the instanced-mesh renderer for the benchmark.)
* flock agents: arrowheads expanded on the CPU into one vertex buffer;
* decals: blob shadows under characters at least ``SHADOW_PX`` tall, selection and go-to rings.

Lighting: a warm key light, sky/ground hemisphere ambient, a little specular and rim light,
fog towards the horizon colour.
"""
from __future__ import annotations

import ctypes
import math

import numpy as np

from . import headless as _headless

_headless.ensure()                      # pyglet's backend must be chosen before pyglet.gl loads
from pyglet import gl  # noqa: E402

from .meshes import CARDBOARD, FigureStyle, arrow_mesh, box_mesh, character_palette, environment_mesh

__all__ = ["Renderer", "SKY_HORIZON", "GROUND", "PLAZA"]

SKY_HORIZON = (0.80, 0.85, 0.90)
SKY_ZENITH = (0.42, 0.60, 0.86)
GROUND = (0.50, 0.52, 0.49)
PLAZA = (0.68, 0.66, 0.62)
LIGHT_DIR = np.array([0.45, 0.80, 0.35]) / np.linalg.norm([0.45, 0.80, 0.35])
GROUND_EXTENT = 600.0
FIGURE_HEIGHT = 1.75       # metres, for the on-screen size of a figure
LOD_NEAR_PX = 70.0         # figures at least this tall on screen get every limb segment
SHADOW_PX = 28.0           # and at least this tall a blob shadow

_SHADE = """
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
    float spec = pow(max(dot(n, h), 0.0), 24.0) * spec_amount;
    float rim = pow(1.0 - max(dot(n, to_eye), 0.0), 3.0) * 0.16;
    return base * (ambient * 0.62 + vec3(1.0, 0.95, 0.86) * diff * 0.72) + vec3(spec)
           + rim * vec3(0.75, 0.82, 1.0);
}
vec3 fog(vec3 c, float dist) {
    float f = clamp((dist - u_fog.x) / (u_fog.y - u_fog.x), 0.0, 1.0);
    return mix(c, u_fog_color, f * f);
}
"""

# -- ground and grid: lighting per vertex (the normal is constant, and the lighting is linear in
# the colour); fog by view depth, which is linear over a triangle and so interpolates exactly; the
# grid lines' fade into the ground by eye distance per pixel. So the ground and the plaza are a few
# large triangles and every grid line is one segment: llvmpipe's cost is per primitive ----------
_FLAT_VS = """#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_color;     // rgb, fade distance (0 = no fade)
uniform mat4 u_vp;
uniform vec3 u_eye;
uniform vec3 u_ground;
uniform vec3 u_forward;                   // camera forward: view depth is linear over a triangle
uniform float u_fade_scale;               // grid fade distances grow with the camera distance
out vec3 v_color;
out vec3 v_ground;
out vec3 v_pos;
out float v_fade;
out float v_dist;
""" + _SHADE + """
void main() {
    v_color = lit(a_color.rgb, vec3(0.0, 1.0, 0.0));   // no view-dependent terms
    v_ground = lit(u_ground, vec3(0.0, 1.0, 0.0));
    v_pos = a_pos;
    v_fade = a_color.a * u_fade_scale;
    v_dist = dot(a_pos - u_eye, u_forward);
    gl_Position = u_vp * vec4(a_pos, 1.0);
}
"""
_FLAT_FS = """#version 330 core
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
"""

# the ground and the plaza themselves: one colour per mesh (flat), so a pixel interpolates only
# its view depth (llvmpipe's cost per pixel grows with every interpolated value)
_GROUND_VS = """#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_color;
uniform mat4 u_vp;
uniform vec3 u_eye;
uniform vec3 u_forward;
flat out vec3 v_color;
out float v_dist;
""" + _SHADE + """
void main() {
    v_color = lit(a_color.rgb, vec3(0.0, 1.0, 0.0));
    v_dist = dot(a_pos - u_eye, u_forward);
    gl_Position = u_vp * vec4(a_pos, 1.0);
}
"""
_GROUND_FS = """#version 330 core
flat in vec3 v_color;
in float v_dist;
uniform vec3 u_fog_color;
uniform vec2 u_fog;
out vec4 frag;
void main() {
    float f = clamp((v_dist - u_fog.x) / (u_fog.y - u_fog.x), 0.0, 1.0);
    frag = vec4(mix(v_color, u_fog_color, f * f), 1.0);
}
"""

# -- sky: a screen quad from just below the horizon line up, drawn first ---------------------------------
_SKY_VS = """#version 330 core
uniform float u_horizon_y;   // NDC y of the horizon
out float v_y;
void main() {
    int k = gl_VertexID;
    float x = (k == 1 || k == 2 || k == 4) ? 1.0 : -1.0;
    float y = (k == 2 || k == 4 || k == 5) ? 1.0 : clamp(u_horizon_y - 0.02, -1.0, 1.0);
    v_y = y;
    gl_Position = vec4(x, y, 0.0, 1.0);
}
"""
_SKY_FS = """#version 330 core
in float v_y;
uniform float u_horizon_y;   // NDC y of the horizon
uniform vec3 u_horizon;
uniform vec3 u_zenith;
out vec4 frag;
void main() {
    float t = clamp((v_y - u_horizon_y) / 1.6, 0.0, 1.0);
    frag = vec4(mix(u_horizon, u_zenith, sqrt(t)), 1.0);
}
"""

# -- static lit geometry (environment, flock agents) -----------------------------------------------------
_LIT_VS = """#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec3 a_color;
uniform mat4 u_vp;
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_color;
void main() {
    v_pos = a_pos;
    v_normal = a_normal;
    v_color = a_color;
    gl_Position = u_vp * vec4(a_pos, 1.0);
}
"""
_LIT_FS = """#version 330 core
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_color;
uniform vec3 u_eye;
out vec4 frag;
""" + _SHADE + """
void main() {
    float ao = mix(0.72, 1.0, clamp(v_pos.y / 0.6, 0.0, 1.0));   // darker towards the ground
    vec3 to_eye = u_eye - v_pos;
    float d = length(to_eye);
    vec3 c = shade(v_color * ao, normalize(v_normal), to_eye / d, 0.08);
    frag = vec4(fog(c, d), 1.0);
}
"""

# -- decals: blob shadows and rings ------------------------------------------------------------------------
_DECAL_VS = """#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_uvk;       // corner u, v, kind (0 blob, 1 ring)
layout(location = 2) in vec4 a_color;
uniform mat4 u_vp;
out vec3 v_uvk;
out vec4 v_color;
void main() {
    v_uvk = a_uvk;
    v_color = a_color;
    gl_Position = u_vp * vec4(a_pos, 1.0);
}
"""
_DECAL_FS = """#version 330 core
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
"""

# -- characters: capsule impostors pulled from texture buffers -------------------------------------------
# One vertex shader for both levels of detail. NEAR: the fragment shader ray-casts the capsule
# and writes its depth. FAR (small figures): the fragment shader tests a 2D capsule in the quad's
# own coordinates and shades a sphere-like normal; no depth write, so early depth testing stays on.
_CAPSULE_VS_BODY = """
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
    float grow = 1.2;
    float R = max(ra, rb) * grow;
    vec3 q = (corner.x < 0.5 ? pa - u * (ra * grow) : pb + u * (rb * grow)) + v * (corner.y * R);
#ifdef FAR
    v_st = vec2(corner.x < 0.5 ? -ra * grow : lu + rb * grow, corner.y * R);
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
"""
_CAPSULE_VS = "#version 330 core\n" + _CAPSULE_VS_BODY
_CAPSULE_FAR_VS = "#version 330 core\n#define FAR\n" + _CAPSULE_VS_BODY
_CAPSULE_FAR_FS = """#version 330 core
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
"""
_CAPSULE_FS = """#version 330 core
in vec3 v_q;
flat in vec3 v_a;
flat in vec3 v_b;
flat in float v_r;
flat in vec3 v_color;
uniform mat4 u_proj;
out vec4 frag;
""" + _SHADE + """
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
"""


# -- far figures: one screen-space quad per character ----------------------------------------------------
# The CPU projects the figure's capsules to pixels; each vertex carries the figure's 6 segments,
# pixel radii, depths and colours (flat), and the fragment shader keeps the nearest capsule that
# covers the pixel. One quad per figure instead of one per bone: on llvmpipe the cost of tiny
# figures is per primitive, not per pixel.
FIGURE_CAPSULES = 6
_FIGURE_VS = """#version 330 core
layout(location = 0) in vec4 a_pos;          // ndc x, y, z, fog factor
layout(location = 1) in vec4 a_seg0;         // segments in window pixels: ax, ay, bx, by
layout(location = 2) in vec4 a_seg1;
layout(location = 3) in vec4 a_seg2;
layout(location = 4) in vec4 a_seg3;
layout(location = 5) in vec4 a_seg4;
layout(location = 6) in vec4 a_seg5;
layout(location = 7) in vec4 a_r0123;        // radii in pixels
layout(location = 8) in vec4 a_r45w01;       // r4, r5, depth 0, depth 1
layout(location = 9) in vec4 a_w2345;        // depths 2..5
layout(location = 10) in vec4 a_skin;
layout(location = 11) in vec4 a_shirt;
layout(location = 12) in vec4 a_legs;
flat out vec4 v_seg[6];
flat out float v_r[6];
flat out float v_w[6];
flat out vec3 v_skin;
flat out vec3 v_shirt;
flat out vec3 v_legs;
flat out float v_fog;
void main() {
    v_seg[0] = a_seg0; v_seg[1] = a_seg1; v_seg[2] = a_seg2;
    v_seg[3] = a_seg3; v_seg[4] = a_seg4; v_seg[5] = a_seg5;
    v_r[0] = a_r0123.x; v_r[1] = a_r0123.y; v_r[2] = a_r0123.z; v_r[3] = a_r0123.w;
    v_r[4] = a_r45w01.x; v_r[5] = a_r45w01.y;
    v_w[0] = a_r45w01.z; v_w[1] = a_r45w01.w;
    v_w[2] = a_w2345.x; v_w[3] = a_w2345.y; v_w[4] = a_w2345.z; v_w[5] = a_w2345.w;
    v_skin = a_skin.rgb; v_shirt = a_shirt.rgb; v_legs = a_legs.rgb;
    v_fog = a_pos.w;
    gl_Position = vec4(a_pos.xyz, 1.0);
}
"""
_FIGURE_FS = """#version 330 core
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
"""


class _Program:
    """A linked GL program with cached uniform locations (raw GL: pyglet's ShaderProgram does not
    know ``samplerBuffer`` uniforms)."""

    def __init__(self, vs: str, fs: str, name: str):
        self.name = name
        self.id = gl.glCreateProgram()
        shaders = []
        for src, kind in ((vs, gl.GL_VERTEX_SHADER), (fs, gl.GL_FRAGMENT_SHADER)):
            sh = gl.glCreateShader(kind)
            b = src.encode()
            buf = ctypes.create_string_buffer(b)
            ptr = ctypes.cast(ctypes.pointer(ctypes.pointer(buf)), ctypes.POINTER(ctypes.POINTER(gl.GLchar)))
            gl.glShaderSource(sh, 1, ptr, None)
            gl.glCompileShader(sh)
            ok = gl.GLint()
            gl.glGetShaderiv(sh, gl.GL_COMPILE_STATUS, ctypes.byref(ok))
            if not ok.value:
                raise RuntimeError(f"{name}: shader compile failed: {self._log(sh, True)}")
            gl.glAttachShader(self.id, sh)
            shaders.append(sh)
        gl.glLinkProgram(self.id)
        ok = gl.GLint()
        gl.glGetProgramiv(self.id, gl.GL_LINK_STATUS, ctypes.byref(ok))
        if not ok.value:
            raise RuntimeError(f"{name}: program link failed: {self._log(self.id, False)}")
        for sh in shaders:
            gl.glDetachShader(self.id, sh)
            gl.glDeleteShader(sh)
        self._loc = {}

    @staticmethod
    def _log(obj, shader: bool) -> str:
        n = gl.GLint()
        (gl.glGetShaderiv if shader else gl.glGetProgramiv)(obj, gl.GL_INFO_LOG_LENGTH, ctypes.byref(n))
        buf = ctypes.create_string_buffer(max(n.value, 1))
        (gl.glGetShaderInfoLog if shader else gl.glGetProgramInfoLog)(obj, max(n.value, 1), None, buf)
        return buf.value.decode(errors="replace")

    def loc(self, name: str) -> int:
        if name not in self._loc:
            self._loc[name] = gl.glGetUniformLocation(self.id, name.encode())
        return self._loc[name]

    def use(self):
        gl.glUseProgram(self.id)
        return self

    def set(self, **values) -> None:
        """Set uniforms of the program in use: floats, vec2/3/4 tuples, 4x4 numpy matrices,
        ints (samplers)."""
        for k, v in values.items():
            loc = self.loc(k)
            if loc < 0:
                continue   # optimised away
            if isinstance(v, np.ndarray) and v.shape == (4, 4):
                arr = (gl.GLfloat * 16)(*np.asarray(v, dtype=np.float64).T.reshape(-1))
                gl.glUniformMatrix4fv(loc, 1, gl.GL_FALSE, arr)
            elif isinstance(v, int):
                gl.glUniform1i(loc, v)
            elif isinstance(v, float):
                gl.glUniform1f(loc, v)
            else:
                v = [float(x) for x in v]
                getattr(gl, f"glUniform{len(v)}f")(loc, *v)


class _Buffer:
    """A GL buffer that grows by reallocation and is otherwise updated with glBufferSubData."""

    def __init__(self, target=gl.GL_ARRAY_BUFFER, usage=gl.GL_DYNAMIC_DRAW):
        self.id = gl.GLuint()
        gl.glGenBuffers(1, ctypes.byref(self.id))
        self.target = target
        self.usage = usage
        self.capacity = 0

    def upload(self, data: np.ndarray) -> None:
        data = np.ascontiguousarray(data, dtype=np.float32)
        gl.glBindBuffer(self.target, self.id)
        n = data.nbytes
        if n > self.capacity or self.capacity == 0:
            cap = max(n, int(self.capacity * 1.5), 64)
            gl.glBufferData(self.target, cap, None, self.usage)
            self.capacity = cap
        if n:
            gl.glBufferSubData(self.target, 0, n, data.ctypes.data_as(ctypes.c_void_p))


class _TextureBuffer:
    """A buffer texture (``samplerBuffer``) over a :class:`_Buffer`."""

    def __init__(self, fmt):
        self.buffer = _Buffer(gl.GL_TEXTURE_BUFFER)
        self.tex = gl.GLuint()
        gl.glGenTextures(1, ctypes.byref(self.tex))
        self.fmt = fmt
        self._bound_cap = -1

    def upload(self, data: np.ndarray) -> None:
        self.buffer.upload(data)
        if self.buffer.capacity != self._bound_cap:   # (re)attach after reallocation
            gl.glBindTexture(gl.GL_TEXTURE_BUFFER, self.tex)
            gl.glTexBuffer(gl.GL_TEXTURE_BUFFER, self.fmt, self.buffer.id)
            gl.glBindTexture(gl.GL_TEXTURE_BUFFER, 0)
            self._bound_cap = self.buffer.capacity

    def bind(self, unit: int) -> None:
        gl.glActiveTexture(gl.GL_TEXTURE0 + unit)
        gl.glBindTexture(gl.GL_TEXTURE_BUFFER, self.tex)


def _vao():
    v = gl.GLuint()
    gl.glGenVertexArrays(1, ctypes.byref(v))
    return v


def _attribs(layout, stride_floats: int) -> None:
    """Float attributes ``[(location, size), ...]`` packed in that order."""
    off = 0
    for loc, size in layout:
        gl.glEnableVertexAttribArray(loc)
        gl.glVertexAttribPointer(loc, size, gl.GL_FLOAT, gl.GL_FALSE, stride_floats * 4, ctypes.c_void_p(off * 4))
        off += size


class _Mesh:
    """A VAO + vertex buffer of interleaved floats drawn as GL_TRIANGLES or GL_LINES."""

    def __init__(self, layout, mode=gl.GL_TRIANGLES, usage=gl.GL_DYNAMIC_DRAW):
        self.vao = _vao()
        self.stride = sum(s for _, s in layout)
        gl.glBindVertexArray(self.vao)
        self.buf = _Buffer(usage=usage)
        self.buf.upload(np.zeros((1, self.stride), np.float32))
        _attribs(layout, self.stride)
        gl.glBindVertexArray(0)
        self.mode = mode
        self.count = 0

    def upload(self, data: np.ndarray) -> None:
        data = np.asarray(data, dtype=np.float32).reshape(-1, self.stride)
        self.buf.upload(data if len(data) else np.zeros((1, self.stride), np.float32))
        self.count = len(data)

    def draw(self) -> None:
        if self.count:
            gl.glBindVertexArray(self.vao)
            gl.glDrawArrays(self.mode, 0, self.count)


# -- static ground geometry ----------------------------------------------------------------------------

def _ground_mesh(area, extent=GROUND_EXTENT):
    """Triangles (V, 7) of the ground plane around the area's centre, with a hole where the
    plaza (the area) lies, and the plaza. Their shading is exact on any triangles (see
    ``_FLAT_VS``), so both are a few large quads; no pixel is drawn twice (llvmpipe's cost is per
    pixel shaded). The ground is the 3 x 3 grid with lines at the plaza's edges minus its middle
    cell, so every edge is shared whole (no T-junctions, no cracks)."""
    x0, z0, x1, z1 = area
    cx, cz = (x0 + x1) / 2, (z0 + z1) / 2
    xs = (cx - extent, x0, x1, cx + extent)
    zs = (cz - extent, z0, z1, cz + extent)

    def quad(xa, za, xb, zb, col):
        P = np.array([[xa, 0.0, za], [xb, 0.0, za], [xb, 0.0, zb], [xa, 0.0, za], [xb, 0.0, zb], [xa, 0.0, zb]])
        return np.concatenate([P, np.broadcast_to(np.r_[col, 0.0], (6, 4))], axis=1)

    ground = np.concatenate([quad(xs[i], zs[j], xs[i + 1], zs[j + 1], GROUND)
                             for i in range(3) for j in range(3) if (i, j) != (1, 1)])
    plaza = quad(x0, z0, x1, z1, PLAZA)
    return ground.astype(np.float32), plaza.astype(np.float32)


def _grid_lines(area, extent=150.0):
    """Line segments (V, 7): 1 m lines over the plaza and 5 m lines out to ``extent`` (returned
    separately: they fade into different colours), in 25 m pieces (the fade is per pixel and the
    fog linear, so any pieces shade exactly; but llvmpipe drops lines that reach far outside the
    view, so they are not drawn whole)."""
    x0, z0, x1, z1 = area
    out = []

    def lines(lo_x, lo_z, hi_x, hi_z, spacing, colour, fade, seg):
        xs = np.arange(math.ceil(lo_x / spacing), math.floor(hi_x / spacing) + 1) * spacing
        zs = np.arange(math.ceil(lo_z / spacing), math.floor(hi_z / spacing) + 1) * spacing
        tz = np.linspace(lo_z, hi_z, max(2, int((hi_z - lo_z) / seg) + 1))
        tx = np.linspace(lo_x, hi_x, max(2, int((hi_x - lo_x) / seg) + 1))
        for x in xs:
            if spacing < 5 and abs(x / 5 - round(x / 5)) < 1e-6:
                continue
            col = colour if abs(x) > 1e-6 else (0.64, 0.40, 0.36)
            p = np.column_stack([np.full(len(tz), x), np.full(len(tz), 0.004), tz])
            out.append(_segments(p, col, fade))
        for z in zs:
            if spacing < 5 and abs(z / 5 - round(z / 5)) < 1e-6:
                continue
            col = colour if abs(z) > 1e-6 else (0.36, 0.46, 0.66)
            p = np.column_stack([tx, np.full(len(tx), 0.004), np.full(len(tx), z)])
            out.append(_segments(p, col, fade))

    cx, cz = (x0 + x1) / 2, (z0 + z1) / 2
    lines(x0, z0, x1, z1, 1.0, np.array(PLAZA) * 0.90, 60.0, 25.0)
    minor = np.concatenate(out).astype(np.float32)
    out.clear()
    lines(cx - extent, cz - extent, cx + extent, cz + extent, 5.0, np.array(GROUND) * 0.84, 90.0, 25.0)
    major = np.concatenate(out)
    # dissolve into the ground towards the edge of the grid
    rr = np.hypot(major[:, 0] - cx, major[:, 2] - cz) / extent
    k = np.clip((rr - 0.55) / 0.4, 0.0, 1.0)[:, None]
    major[:, 3:6] = major[:, 3:6] * (1 - k) + np.array(GROUND) * k
    return minor, major.astype(np.float32)


def _segments(p, col, fade):
    a, b = p[:-1], p[1:]
    v = np.stack([a, b], axis=1).reshape(-1, 3)
    c = np.broadcast_to(np.r_[col, fade], (len(v), 4))
    return np.concatenate([v, c], axis=1)


class Renderer:
    """Owns the GL objects; :meth:`draw` renders one frame into the current framebuffer."""

    def __init__(self, skeleton):
        self.style = FigureStyle.for_skeleton(skeleton)
        self.p_flat = _Program(_FLAT_VS, _FLAT_FS, "grid")
        self.p_ground = _Program(_GROUND_VS, _GROUND_FS, "ground")
        self.p_sky = _Program(_SKY_VS, _SKY_FS, "sky")
        self.p_lit = _Program(_LIT_VS, _LIT_FS, "lit")
        self.p_decal = _Program(_DECAL_VS, _DECAL_FS, "decal")
        self.p_capsule = _Program(_CAPSULE_VS, _CAPSULE_FS, "capsule")
        self.p_capsule_far = _Program(_CAPSULE_FAR_VS, _CAPSULE_FAR_FS, "capsule (far)")
        self.p_figure = _Program(_FIGURE_VS, _FIGURE_FS, "far figures")
        self.m_figures = _Mesh([(loc, 4) for loc in range(13)])
        self._figure_parts = [int(min(p, 2)) for p in self.style.far.part] + [0] * FIGURE_CAPSULES
        self._figure_parts = self._figure_parts[:FIGURE_CAPSULES]
        self.num_figures = 0
        self.vao_empty = _vao()
        flat = [(0, 3), (1, 4)]
        self.m_ground = _Mesh(flat, usage=gl.GL_STATIC_DRAW)
        self.m_plaza = _Mesh(flat, usage=gl.GL_STATIC_DRAW)
        self.m_lines = _Mesh(flat, mode=gl.GL_LINES, usage=gl.GL_STATIC_DRAW)
        self.m_major = _Mesh(flat, mode=gl.GL_LINES, usage=gl.GL_STATIC_DRAW)
        lit = [(0, 3), (1, 3), (2, 3)]
        self.m_env = _Mesh(lit, usage=gl.GL_STATIC_DRAW)
        self.m_agents = _Mesh(lit)
        self.m_boxes = _Mesh(lit)
        self.m_decals = _Mesh([(0, 3), (1, 3), (2, 4)])
        self.t_bones = _TextureBuffer(gl.GL_RGB32F)
        self.t_style = _TextureBuffer(gl.GL_RGBA32F)
        self.t_bones.upload(np.zeros((2, 3), np.float32))
        self.t_style.upload(np.zeros((1, 4), np.float32))
        self._palette_key = None
        self._pal = None
        self.num_bones = 0
        self.lod_counts = {"near": 0, "far": 0}
        self._arrow = arrow_mesh()
        self._box = box_mesh(0.4)
        self.area = (-15.0, -15.0, 15.0, 15.0)
        self._set_ground(self.area)

    # -- static content -----------------------------------------------------------------------------
    def _set_ground(self, area):
        g, p = _ground_mesh(area)
        self.m_ground.upload(g)
        self.m_plaza.upload(p)
        minor, major = _grid_lines(area)
        self.m_lines.upload(minor)
        self.m_major.upload(major)

    def set_environment(self, env, heights=None, draw_boxes: bool = True) -> None:
        self.m_env.upload(environment_mesh(env, heights, draw_boxes=draw_boxes))
        if env.num_obstacles or env.markers:
            self.area = env.bounds(1.5)
        self._set_ground(self.area)

    # -- per frame ----------------------------------------------------------------------------------------
    def _palette(self, n: int, selected) -> np.ndarray:
        key = (n, selected)
        if key != self._palette_key:
            pal = character_palette(n)                       # (N, parts, 3)
            if selected is not None and 0 <= selected < n:
                pal[selected, 1] = np.minimum(pal[selected, 1] * 0.3 + np.array([1.0, 0.85, 0.2]) * 0.8, 1.0)
            self._pal = pal
            self._palette_key = key
        return self._pal

    def _lod(self, P, view, proj, height):
        """On-screen height (pixels) and view depth of every figure."""
        root = P[:, 0].astype(np.float64)
        depth = -(root @ view[2, :3] + view[2, 3])
        px = FIGURE_HEIGHT * proj[1, 1] * 0.5 * height / np.maximum(depth, 1e-3)
        return px, depth

    def character_bones(self, positions: np.ndarray, view: np.ndarray, proj: np.ndarray, height: int,
                        selected=None, far_figures: bool | None = None):
        """Split the characters by level of detail and build their GPU data.

        A character at least ``LOD_NEAR_PX`` pixels tall on screen is drawn bone by bone as
        ray-cast capsules (14 for the CMU skeleton); smaller ones as one screen-space quad per
        figure with 6 capsules (``figure_vertices``; or, for styles whose far set is not 6
        capsules, bone by bone with the far shader). llvmpipe's cost is per primitive and per
        4x4 pixel block touched, and tiny figures need no knees and hands. Characters at least
        ``SHADOW_PX`` tall get a blob shadow (``self.shadowed``).

        Returns (bone endpoints (bones * 2, 3), bone styles (bones, 4) = radius, rgb, indices of
        the characters drawn as far figures). ``self.near_bones`` bones come first."""
        st = self.style
        P = st.points(positions)                                         # (N, J + V, 3)
        n = len(P)
        px, depth = self._lod(P, view, proj, height)
        near = (px >= LOD_NEAR_PX) & (depth > 0)
        visible = depth > 0
        pal = self._palette(n, selected)
        self.shadowed = np.flatnonzero((px >= SHADOW_PX) & (depth > 0))
        if far_figures is None:
            far_figures = len(st.far) == FIGURE_CAPSULES
        near_idx = np.flatnonzero(near)
        far_idx = np.flatnonzero(~near & visible)
        self.lod_counts = {"near": len(near_idx), "far": len(far_idx)}
        groups = [(near_idx, st.near)] + ([] if far_figures else [(far_idx, st.far)])
        ends, style = [], []
        for idx, bs in groups:
            if not len(idx) or not len(bs):
                continue
            Q = P[idx]
            e = np.empty((len(idx), len(bs), 2, 3), dtype=np.float32)
            e[:, :, 0] = Q[:, bs.a]
            e[:, :, 1] = Q[:, bs.b]
            y = np.empty((len(idx), len(bs), 4), dtype=np.float32)
            y[:, :, 0] = bs.radius
            y[:, :, 1:] = pal[idx][:, bs.part]
            ends.append(e.reshape(-1, 3))
            style.append(y.reshape(-1, 4))
        self.near_bones = len(near_idx) * len(st.near)
        self._P = P
        if not ends:
            return np.zeros((0, 3), np.float32), np.zeros((0, 4), np.float32), (far_idx if far_figures else None)
        return np.concatenate(ends), np.concatenate(style), (far_idx if far_figures else None)

    def figure_vertices(self, P, idx, view, proj, width, height, fog, selected=None) -> np.ndarray:
        """Vertex data (6 per figure, 52 floats each) of far figures ``idx`` of the points ``P``
        (N, J + V, 3): a screen-space quad around the figure's projected capsules, and the
        capsules themselves in window pixels (see ``_FIGURE_VS``)."""
        bs = self.style.far
        m, k = len(idx), len(bs)
        ends = np.concatenate([bs.a, bs.b])                               # (2k,)
        Q = P[idx][:, ends].reshape(-1, 3).astype(np.float64)             # (M * 2k, 3)
        V = Q @ view[:3, :3].T + view[:3, 3]                              # 2-D matmul (BLAS)
        w = np.maximum(-V[:, 2], 1e-3)
        fx = proj[0, 0] * 0.5 * width
        fy = proj[1, 1] * 0.5 * height
        px = ((V[:, 0] * proj[0, 0] + V[:, 2] * proj[0, 2]) / w + 1.0) * (0.5 * width)
        py = ((V[:, 1] * proj[1, 1] + V[:, 2] * proj[1, 2]) / w + 1.0) * (0.5 * height)
        px, py, w = px.reshape(m, 2 * k), py.reshape(m, 2 * k), w.reshape(m, 2 * k)
        wm = 0.5 * (w[:, :k] + w[:, k:])                                  # (M, k)
        r = np.maximum(bs.radius[None, :] * fy / wm, 0.6)                 # pixels
        del fx
        x0 = np.minimum(px[:, :k], px[:, k:]) - r
        x1 = np.maximum(px[:, :k], px[:, k:]) + r
        y0 = np.minimum(py[:, :k], py[:, k:]) - r
        y1 = np.maximum(py[:, :k], py[:, k:]) + r
        lox, hix, loy, hiy = x0[:, 0], x1[:, 0], y0[:, 0], y1[:, 0]
        for c in range(1, k):                                             # (M,) pixel box
            lox, hix = np.minimum(lox, x0[:, c]), np.maximum(hix, x1[:, c])
            loy, hiy = np.minimum(loy, y0[:, c]), np.maximum(hiy, y1[:, c])
        root = P[idx, 0].astype(np.float64)
        Vr = root @ view[:3, :3].T + view[:3, 3]
        zr = (Vr @ proj[2, :3] + proj[2, 3]) / np.maximum(-Vr[:, 2], 1e-3)
        dist = np.sqrt(np.einsum("ij,ij->i", Vr, Vr))
        f = np.clip((dist - fog[0]) / (fog[1] - fog[0]), 0.0, 1.0) ** 2
        pal = self._palette(len(P), selected)[idx]                        # (M, parts, 3)
        data = np.zeros((m, 52), dtype=np.float32)
        data[:, 2] = zr
        data[:, 3] = f
        seg = data[:, 4:28].reshape(m, k, 4)
        seg[:, :, 0], seg[:, :, 1] = px[:, :k], py[:, :k]
        seg[:, :, 2], seg[:, :, 3] = px[:, k:], py[:, k:]
        data[:, 28:34] = r
        data[:, 34:36] = wm[:, 0:2]
        data[:, 36:40] = wm[:, 2:6]
        data[:, 40:43] = pal[:, 0]
        data[:, 44:47] = pal[:, 1]
        data[:, 48:51] = pal[:, 2]
        out = np.repeat(data[:, None, :], 6, axis=1)                      # (M, 6, 52)
        sx, sy = 2.0 / width, 2.0 / height
        ax, bx = lox * sx - 1.0, hix * sx - 1.0
        ay, by = loy * sy - 1.0, hiy * sy - 1.0
        for v, (cx, cy) in enumerate(((ax, ay), (bx, ay), (bx, by), (ax, ay), (bx, by), (ax, by))):
            out[:, v, 0] = cx
            out[:, v, 1] = cy
        return out.reshape(-1, 52)

    def _decals(self, roots, rings):
        n = len(roots)
        items = np.zeros((n + len(rings), 8), dtype=np.float32)     # x, z, radius, kind, rgba
        if n:
            items[:n, 0] = roots[:, 0]
            items[:n, 1] = roots[:, 2]
            items[:n, 2] = 0.42
            items[:n, 7] = 0.36
        for k, (x, z, r, col) in enumerate(rings):
            items[n + k] = (x, z, r, 1.0, *col)
        corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, -1], [1, 1], [-1, 1]], dtype=np.float32)
        m = len(items)
        v = np.empty((m, 6, 10), dtype=np.float32)
        v[:, :, 0] = items[:, None, 0] + corners[None, :, 0] * items[:, None, 2]
        v[:, :, 1] = 0.012
        v[:, :, 2] = items[:, None, 1] + corners[None, :, 1] * items[:, None, 2]
        v[:, :, 3:5] = corners[None]
        v[:, :, 5] = items[:, None, 3]
        v[:, :, 6:10] = items[:, None, 4:8]
        return v.reshape(-1, 10)

    def _agents(self, pos, heading, mesh=None, colour=(0.96, 0.56, 0.16)):
        """Copies of ``mesh`` (K, 6) position+normal (default: the flock arrowhead) turned by
        ``heading`` and moved to ``pos`` (M, 3): lit vertices (M * K, 9)."""
        m = len(pos)
        A = self._arrow if mesh is None else mesh          # (K, 6)
        c, s = np.cos(heading), np.sin(heading)
        px, pz = A[:, 0], A[:, 2]
        nx, nz = A[:, 3], A[:, 5]
        v = np.empty((m, len(A), 9), dtype=np.float32)
        v[:, :, 0] = pos[:, 0:1] + c[:, None] * px + s[:, None] * pz
        v[:, :, 1] = pos[:, 1:2] + A[:, 1]
        v[:, :, 2] = pos[:, 2:3] - s[:, None] * px + c[:, None] * pz
        v[:, :, 3] = c[:, None] * nx + s[:, None] * nz
        v[:, :, 4] = A[:, 4]
        v[:, :, 5] = -s[:, None] * nx + c[:, None] * nz
        v[:, :, 6:9] = colour
        return v.reshape(-1, 9)

    def draw_characters(self, view, proj, width: int, height: int, positions, selected=None,
                        fog=(70.0, 220.0)) -> None:
        """The character pass alone (depth test on): near figures bone by bone, then the far
        figures (one quad each)."""
        ends, style, far_idx = self.character_bones(positions, view, proj, height, selected)
        self.num_bones = len(style)
        V3 = view[:3, :3]
        light, up = tuple(V3 @ LIGHT_DIR), tuple(V3 @ np.array([0.0, 1.0, 0.0]))
        if self.num_bones:
            self.t_bones.upload(ends)
            self.t_style.upload(style)
            self.t_bones.bind(0)
            self.t_style.bind(1)
            gl.glBindVertexArray(self.vao_empty)
            for prog, first, count in ((self.p_capsule, 0, self.near_bones),
                                       (self.p_capsule_far, self.near_bones, self.num_bones - self.near_bones)):
                if count <= 0:
                    continue
                p = prog.use()
                p.set(u_view=view, u_proj=proj, u_bones=0, u_style=1, u_first=int(first), u_light=light,
                      u_up=up, u_fog_color=SKY_HORIZON, u_fog=tuple(fog))
                gl.glDrawArrays(gl.GL_TRIANGLES, 0, 6 * int(count))
            gl.glBindTexture(gl.GL_TEXTURE_BUFFER, 0)
            gl.glActiveTexture(gl.GL_TEXTURE0)
            gl.glBindTexture(gl.GL_TEXTURE_BUFFER, 0)
        self.num_figures = 0 if far_idx is None else len(far_idx)
        if self.num_figures:
            self.m_figures.upload(self.figure_vertices(self._P, far_idx, view, proj, width, height, fog, selected))
            p = self.p_figure.use()
            gl.glUniform1iv(p.loc("u_part"), FIGURE_CAPSULES, (gl.GLint * FIGURE_CAPSULES)(*self._figure_parts))
            p.set(u_light=light, u_up=up, u_fog_color=SKY_HORIZON)
            self.m_figures.draw()
        gl.glBindVertexArray(0)

    def draw(self, view: np.ndarray, proj: np.ndarray, eye, width: int, height: int, positions=None,
             flock=None, selected=None, rings=(), boxes=None) -> None:
        """One frame. ``positions`` (N, J, 3) joint positions; ``flock`` = (positions (M, 3),
        headings (M,)) or None; ``rings`` = iterable of (x, z, radius, (r, g, b, a)); ``boxes``
        (K, 4) = bottom centre x, y, z and heading of movable boxes, or None."""
        vp = proj @ view
        eye = np.asarray(eye, dtype=np.float64)
        gl.glViewport(0, 0, width, height)
        gl.glClearColor(*SKY_HORIZON, 1.0)
        gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LEQUAL)
        gl.glDepthMask(gl.GL_TRUE)
        gl.glDisable(gl.GL_BLEND)
        gl.glDisable(gl.GL_CULL_FACE)
        centre = np.array([0.5 * (self.area[0] + self.area[2]), 0.0, 0.5 * (self.area[1] + self.area[3])])
        dist = float(np.linalg.norm(eye - centre))
        fog = (max(70.0, dist * 2.5), max(220.0, dist * 7.0))
        shade = dict(u_light=tuple(LIGHT_DIR), u_up=(0.0, 1.0, 0.0), u_fog_color=SKY_HORIZON, u_fog=fog)
        # sky, ground, plaza, grid: the backdrop, painted in order without depth (everything
        # else stands on or above the ground)
        gl.glDisable(gl.GL_DEPTH_TEST)
        p = self.p_sky.use()
        horizon = eye + 1e4 * _horizontal_forward(view)
        hc = vp @ np.r_[horizon, 1.0]
        hy = float(hc[1] / hc[3]) if hc[3] > 0 else -1.0
        if hy < 1.0:
            p.set(u_horizon_y=hy, u_horizon=SKY_HORIZON, u_zenith=SKY_ZENITH)
            gl.glBindVertexArray(self.vao_empty)
            gl.glDrawArrays(gl.GL_TRIANGLES, 0, 6)
        ground = dict(u_vp=vp, u_eye=tuple(eye), u_forward=tuple(-view[2, :3]), **shade)
        grid = dict(ground, u_fade_scale=float(max(1.0, dist / 40.0)))
        self.p_ground.use().set(**ground)
        self.m_ground.draw()
        self.p_flat.use().set(u_ground=GROUND, **grid)     # 5 m lines, hidden by the plaza
        self.m_major.draw()
        self.p_ground.use()
        self.m_plaza.draw()
        self.p_flat.use().set(u_ground=PLAZA, **grid)      # 1 m lines on the plaza
        self.m_lines.draw()
        gl.glEnable(gl.GL_DEPTH_TEST)
        # environment
        n = 0 if positions is None else len(positions)
        if self.m_env.count:
            p = self.p_lit.use()
            p.set(u_vp=vp, u_eye=tuple(eye), **shade)
            self.m_env.draw()
        # flock agents
        m = 0
        if flock is not None and len(flock[0]):
            fpos = np.asarray(flock[0], dtype=np.float64)
            m = len(fpos)
            p = self.p_lit.use()
            p.set(u_vp=vp, u_eye=tuple(eye), **shade)
            self.m_agents.upload(self._agents(fpos, np.asarray(flock[1], dtype=np.float64)))
            self.m_agents.draw()
        # movable boxes (carried or put down), one buffer
        if boxes is not None and len(boxes):
            b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
            p = self.p_lit.use()
            p.set(u_vp=vp, u_eye=tuple(eye), **shade)
            self.m_boxes.upload(self._agents(b[:, :3], b[:, 3], self._box, tuple(CARDBOARD)))
            self.m_boxes.draw()
        # characters: one draw per level of detail, 6 vertices per bone
        if n:
            self.draw_characters(view, proj, width, height, positions, selected, fog)
        else:
            self.num_bones = 0
            self.shadowed = np.zeros(0, dtype=np.int64)
        # decals: shadows and rings (blended, no depth writes)
        roots = np.zeros((0, 3)) if not n else np.asarray(positions[self.shadowed, 0])
        if len(roots) or rings:
            gl.glEnable(gl.GL_BLEND)
            gl.glBlendFunc(gl.GL_SRC_ALPHA, gl.GL_ONE_MINUS_SRC_ALPHA)
            gl.glDepthMask(gl.GL_FALSE)
            p = self.p_decal.use()
            p.set(u_vp=vp)
            self.m_decals.upload(self._decals(roots, list(rings)))
            self.m_decals.draw()
            gl.glDepthMask(gl.GL_TRUE)
            gl.glDisable(gl.GL_BLEND)
        gl.glBindVertexArray(0)
        gl.glUseProgram(0)
        gl.glDisable(gl.GL_DEPTH_TEST)
        self.stats = {"bones": self.num_bones, "agents": m}


def _horizontal_forward(view: np.ndarray) -> np.ndarray:
    f = -view[2, :3]                 # camera forward in world coordinates
    h = np.array([f[0], 0.0, f[2]])
    L = np.linalg.norm(h)
    return h / L if L > 1e-9 else np.array([0.0, 0.0, -1.0])
