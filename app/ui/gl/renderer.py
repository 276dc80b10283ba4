"""Kivy's own OpenGL ES 2 pipeline draws an :class:`ar.scene.SceneDescription`.

What runs on Android (no pyrender, no PyOpenGL): an :class:`kivy.graphics.Fbo` with a
depth buffer is the render target; it is itself a ``RenderContext`` running the GLSL ES
1.00 shaders of :mod:`app.ui.gl.shaders`. Inside it, per description item, a
``ChangeState`` sets the item's model matrix and colour and a ``Mesh`` (positions and
normals interleaved, ``triangles``) draws it; depth testing is switched on around the
items by ``Callback`` s. Meshes are uploaded once per :attr:`ar.scene.MeshData.uid` and
kept; a frame only makes new per-item states and sets the view uniforms.

Matrices: the projection and view come from :meth:`ar.scene.View.gl_projection` and
:meth:`ar.scene.View.gl_view`, the same numbers pyrender uses, so the two renderers put
every vertex on the same pixel; Kivy matrices are column-major (``Matrix.set(flat=M.T)``).
The framebuffer's row 0 is the image's bottom row, so :meth:`KivyGLRenderer.render` flips
the read-back pixels to the usual top-down order; :meth:`KivyGLRenderer.draw` returns the
texture for the screen as is (Kivy textures are bottom-up too).

Everything here must run on Kivy's main thread (the thread that owns the window's GL
context): the app computes descriptions on its render thread and draws them here.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from kivy.graphics import Callback, ChangeState, ClearBuffers, ClearColor, Color, Fbo, Mesh, Rectangle
from kivy.graphics.opengl import GL_DEPTH_TEST, glDisable, glEnable
from kivy.graphics.texture import Texture
from kivy.graphics.transformation import Matrix

from app.ui.gl.shaders import FRAGMENT, VERTEX

if TYPE_CHECKING:  # the descriptions arrive from the render thread: no need to load ar.scene at start-up
    from ar.scene import MeshData, SceneDescription

#: Kivy's vertex format for :class:`ar.scene.MeshData` (interleaved position, normal)
VERTEX_FORMAT = [(b"v_pos", 3, "float"), (b"v_normal", 3, "float")]
#: default supersampling per axis: 2 x 2 samples per pixel (pyrender multisamples 4 per pixel);
#: what the Play preview draws with
SUPERSAMPLE = 2
#: what the projector stage draws with: one sample per pixel. The projector's light is
#: the latency-critical path (camera frame -> light on the table, budget 16 ms) and the
#: projector's optics soften edges anyway; measured, the projector view's silhouettes
#: still match pyrender's (4 multisamples) with IoU >= 0.98 and centroids within 0.3 px
#: in every parity case (tests/app/test_kivy_gl_parity.py), and a 640x480 rig frame on
#: one core of the development machine (Mesa llvmpipe) takes 9.6 ms median against
#: 16.5 ms at 2 x 2 (storybeam bench ar --frame-only --renderers kivy-gl,kivy-gl-2x).
PROJECTOR_SUPERSAMPLE = 1
#: a mesh no frame has drawn for this many frames is let go (its GPU buffer freed)
EVICT_AFTER_FRAMES = 300
#: Kivy meshes index with unsigned shorts (OpenGL ES 2)
MAX_VERTICES = 65535


class KivyGLError(RuntimeError):
    """The GL ES shaders did not compile or a mesh cannot be drawn."""


def kivy_matrix(M: np.ndarray) -> Matrix:
    """A Kivy ``Matrix`` of the 4x4 numpy matrix ``M`` (row-major maths, column-major GL)."""
    m = Matrix()
    m.set(flat=[float(x) for x in np.asarray(M, np.float64).T.ravel()])
    return m


def _depth_on(_instruction) -> None:
    glEnable(GL_DEPTH_TEST)


def _depth_off(_instruction) -> None:
    glDisable(GL_DEPTH_TEST)


class KivyGLRenderer:
    """``draw(desc) -> Texture`` (for the screen) and ``render(desc) -> (H, W, 3) uint8``."""

    name = "kivy-gl"

    def __init__(self, supersample: int = SUPERSAMPLE) -> None:
        """``supersample``: draw at that many times the view's width and height (the
        ES 2 framebuffer has no multisampling), then scale down to the view's size in a
        second pass: a quad drawn with the large texture, linearly filtered; at 2x each
        output pixel centre falls on the corner of four samples, so bilinear filtering
        is their mean -- a box filter, each pixel the mean of a regular 2 x 2 grid of
        samples over it (an estimate of the fraction of it the geometry covers)."""
        if supersample not in (1, 2):
            raise ValueError(f"supersample must be 1 or 2, not {supersample}")
        self.supersample = supersample
        self.fbo: Fbo | None = None  # where the scene is drawn (supersampled)
        self.out: Fbo | None = None  # the view's size (the same as fbo without supersampling)
        self._size: tuple[int, int] | None = None
        self._meshes: dict[int, list[Mesh]] = {}  # uid -> its Mesh instructions (each holds its own VBO)
        self.uploads = 0  # meshes uploaded so far (each uid once while it stays in use)
        self.frames = 0
        self._last_used: dict[int, int] = {}  # uid -> the last frame that drew it

    # -- set-up ---------------------------------------------------------------------
    def _ensure_fbo(self, width: int, height: int) -> Fbo:
        if self.fbo is None or self._size != (width, height):
            s = self.supersample
            fbo = Fbo(size=(width * s, height * s), with_depthbuffer=True, vs=VERTEX, fs=FRAGMENT)
            if not fbo.shader.success:
                raise KivyGLError("the GL ES 2 shaders of app.ui.gl did not compile (see Kivy's log)")
            self.fbo, self._size = fbo, (width, height)
            self.out = fbo
            if s > 1:
                fbo.texture.min_filter = fbo.texture.mag_filter = "linear"
                self.out = Fbo(size=(width, height))
                with self.out:
                    ClearColor(0, 0, 0, 1)
                    ClearBuffers()
                    Color(1, 1, 1, 1)
                    Rectangle(texture=fbo.texture, pos=(0, 0), size=(width, height))
        return self.fbo

    def _mesh(self, mesh: MeshData, copy: int) -> Mesh:
        """The ``copy``-th Mesh instruction of ``mesh`` (made, hence uploaded, once)."""
        made = self._meshes.setdefault(mesh.uid, [])
        while len(made) <= copy:
            if len(mesh.vertices) > MAX_VERTICES:
                raise KivyGLError(f"mesh {mesh.uid}: {len(mesh.vertices)} vertices; GL ES 2 indexes at most "
                                  f"{MAX_VERTICES}")
            inter = np.concatenate([mesh.vertices, mesh.normals], axis=1).astype(np.float32).ravel()
            made.append(Mesh(vertices=inter.tolist(), indices=mesh.faces.astype(np.int64).ravel().tolist(),
                             fmt=VERTEX_FORMAT, mode="triangles"))
            self.uploads += 1
        return made[copy]

    # -- drawing ----------------------------------------------------------------------
    def draw(self, desc: SceneDescription) -> Texture:
        """Draw ``desc`` into the offscreen buffer now; its texture (bottom-up rows).

        The instruction list is remade per frame (a ``ChangeState`` holds its uniforms
        from construction on), but the ``Mesh`` instructions -- and so the vertex
        buffers on the GPU -- are the ones made on a mesh's first frame."""
        fbo = self._ensure_fbo(desc.view.width, desc.view.height)
        v = desc.view if self.supersample == 1 else desc.view.scaled(*fbo.size)
        fbo.clear()
        used: dict[int, int] = {}
        with fbo:
            ClearColor(*desc.background, 1.0)
            ClearBuffers(clear_color=True, clear_depth=True)
            Callback(_depth_on)
        for item in desc.items:
            copy = used.get(item.mesh.uid, 0)
            used[item.mesh.uid] = copy + 1
            fbo.add(ChangeState(model_mat=kivy_matrix(item.pose), base_color=[c / 255.0 for c in item.colour],
                                roughness=float(item.roughness)))
            fbo.add(self._mesh(item.mesh, copy))
        fbo.add(Callback(_depth_off))
        self.frames += 1
        for uid in used:
            self._last_used[uid] = self.frames
        for uid in [u for u, f in self._last_used.items() if self.frames - f > EVICT_AFTER_FRAMES]:
            del self._last_used[uid], self._meshes[uid]  # a scene left long ago: free its buffers
        fbo["proj_mat"] = kivy_matrix(v.gl_projection())
        fbo["view_mat"] = kivy_matrix(v.gl_view())
        fbo["cam_pos"] = [float(x) for x in v.eye]
        fbo["light_dir"] = [float(x) for x in v.forward]
        fbo["light_intensity"] = float(desc.lighting.key_intensity)
        fbo["ambient"] = float(desc.lighting.ambient)
        fbo.draw()
        if self.out is not fbo:
            self.out.ask_update()  # its instructions did not change, its texture did
            self.out.draw()
        return self.out.texture

    def render(self, desc: SceneDescription) -> np.ndarray:
        """Draw ``desc`` and read it back: (H, W, 3) uint8, rows top to bottom."""
        self.draw(desc)
        w, h = self._size
        return np.ascontiguousarray(np.frombuffer(self.out.pixels, np.uint8).reshape(h, w, 4)[::-1, :, :3])

    def __call__(self, desc: SceneDescription) -> np.ndarray:
        return self.render(desc)

    def close(self) -> None:
        if self.fbo is not None:
            self.fbo.clear()
        self.fbo, self.out, self._size = None, None, None
        self._meshes.clear()
        self._last_used.clear()


__all__ = ["KivyGLRenderer", "KivyGLError", "VERTEX_FORMAT", "SUPERSAMPLE", "kivy_matrix"]
