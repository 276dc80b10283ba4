"""GLSL ES 1.00 shaders (OpenGL ES 2, what Android runs) for :mod:`app.ui.gl.renderer`.

The fragment shader is pyrender's ``mesh.frag`` (pyrender 0.1.45) reduced to what a
:class:`ar.scene.SceneDescription` uses -- a metallic-roughness material with metallic
0, one directional light, an ambient term, no textures, no shadows -- so the Kivy image
matches the reference renderer's: for light direction ``l``, view direction ``v``,
normal ``n`` and half vector ``h``,

    F = f0 + (1 - f0) (1 - v.h)^5,  f0 = 0.04
    G = g(n.v) g(n.l),  g(x) = x / (x (1 - k) + k),  k = (r + 1)^2 / 8
    D = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2),  a = r^2
    colour = (n.l) E ((1 - F) c_diff / pi + F G D / (4 (n.l)(n.v) + 0.001)) + ambient * base
    c_diff = 0.96 base, output = clamp(colour^(1/2.2))

with pyrender's clamps (``n.l`` and ``|n.v|`` at least 0.001) and ``r`` the roughness
clamped to [0.04, 1]. Uniform names are ours; the vertex attributes follow Kivy's
``v_`` convention.
"""
from __future__ import annotations

VERTEX = """
#ifdef GL_ES
precision highp float;
#endif
attribute vec3 v_pos;
attribute vec3 v_normal;
uniform mat4 model_mat;
uniform mat4 view_mat;
uniform mat4 proj_mat;
varying vec3 frag_position;
varying vec3 frag_normal;
void main(void) {
    vec4 world = model_mat * vec4(v_pos, 1.0);
    frag_position = world.xyz;
    frag_normal = (model_mat * vec4(v_normal, 0.0)).xyz;  /* rigid poses: no inverse-transpose needed */
    gl_Position = proj_mat * view_mat * world;
}
"""

FRAGMENT = """
#ifdef GL_ES
#ifdef GL_FRAGMENT_PRECISION_HIGH
precision highp float;
#else
precision mediump float;  /* ES 2 fragment shaders need not support highp */
#endif
#endif
varying vec3 frag_position;
varying vec3 frag_normal;
uniform vec3 base_color;
uniform float roughness;
uniform vec3 cam_pos;
uniform vec3 light_dir;
uniform float light_intensity;
uniform float ambient;
const float PI = 3.141592653589793;
const float MIN_ROUGHNESS = 0.04;
void main(void) {
    float r = clamp(roughness, MIN_ROUGHNESS, 1.0);
    vec3 c_diff = base_color * (1.0 - MIN_ROUGHNESS);
    vec3 f0 = vec3(MIN_ROUGHNESS);
    vec3 n = normalize(frag_normal);
    vec3 v = normalize(cam_pos - frag_position);
    vec3 l = normalize(-light_dir);
    vec3 h = normalize(l + v);
    float nl = clamp(dot(n, l), 0.001, 1.0);
    float nv = clamp(abs(dot(n, v)), 0.001, 1.0);
    float nh = clamp(dot(n, h), 0.0, 1.0);
    float vh = clamp(dot(v, h), 0.0, 1.0);
    vec3 F = f0 + (1.0 - f0) * pow(clamp(1.0 - vh, 0.0, 1.0), 5.0);
    float rk = r + 1.0;
    float k = rk * rk / 8.0;
    float G = (nv / (nv * (1.0 - k) + k)) * (nl / (nl * (1.0 - k) + k));
    float a = r * r;
    float a2 = a * a;
    float denom = nh * nh * (a2 - 1.0) + 1.0;
    float D = a2 / (PI * denom * denom);
    vec3 diffuse = (1.0 - F) * c_diff / PI;
    vec3 spec = F * G * D / (4.0 * nl * nv + 0.001);
    vec3 color = nl * light_intensity * (diffuse + spec) + base_color * ambient;
    gl_FragColor = clamp(vec4(pow(color, vec3(1.0 / 2.2)), 1.0), 0.0, 1.0);
}
"""

__all__ = ["VERTEX", "FRAGMENT"]
