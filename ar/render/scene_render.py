"""pyrender draws a :class:`ar.scene.SceneDescription` -- the reference renderer.

:class:`PyrenderSceneRenderer` keeps one :class:`ar.render.projector_view.ProjectorRenderer`
(one pyrender scene, one offscreen EGL context) and, per frame, only moves nodes: a mesh
(:class:`ar.scene.MeshData`, by ``uid``) is turned into a ``pyrender.Mesh`` once, and a node
is kept per (mesh, colour, roughness, occurrence) and re-posed while the description
keeps drawing it; items that disappear are removed. The view's intrinsics, size, pose and
light levels are set from the description each frame. The Kivy GL renderer
(:mod:`app.ui.gl`) draws the same descriptions; ``tests/app/test_kivy_gl_parity.py``
holds the two to the same silhouettes.

Render from one thread only (EGL contexts are per thread), as with ``ProjectorRenderer``.
"""
from __future__ import annotations

import numpy as np
import pyrender

from ar.render.characters import part_mesh
from ar.render.projector_view import ProjectorRenderer
from ar.scene import SceneDescription


class PyrenderSceneRenderer:
    """``render(desc) -> (H, W, 3) uint8`` (optionally with depth in metres)."""

    def __init__(self) -> None:
        self._renderer: ProjectorRenderer | None = None
        self._meshes: dict[tuple, pyrender.Mesh] = {}
        self._live: set[str] = set()

    def _ensure(self, desc: SceneDescription) -> ProjectorRenderer:
        v = desc.view
        r = self._renderer
        if r is None or (r.width, r.height) != (v.width, v.height):
            if r is not None:
                r.close()
            r = self._renderer = ProjectorRenderer(v.width, v.height, v.K, v.znear, v.zfar)
            self._live.clear()
        cam = r.camera_node.camera
        cam.fx, cam.fy = float(v.K[0, 0]), float(v.K[1, 1])
        cam.cx, cam.cy = float(v.K[0, 2]) + 0.5, float(v.K[1, 2]) + 0.5
        cam.znear, cam.zfar = float(v.znear), float(v.zfar)
        r.scene.ambient_light = np.full(3, desc.lighting.ambient)
        r.light_node.light.intensity = float(desc.lighting.key_intensity)
        r.scene.bg_color = np.array([*desc.background, 1.0])
        return r

    def render(self, desc: SceneDescription, with_depth: bool = False):
        r = self._ensure(desc)
        seen: dict[tuple, int] = {}
        wanted: set[str] = set()
        for item in desc.items:
            key = (item.mesh.uid, item.colour, float(item.roughness))
            k = seen.get(key, 0)
            seen[key] = k + 1
            name = f"{key[0]}/{key[1]}/{key[2]}#{k}"
            wanted.add(name)
            if name not in self._live:
                if key not in self._meshes:
                    self._meshes[key] = part_mesh(item.mesh, item.colour, item.roughness)
                r.add(name, self._meshes[key], item.pose)
                self._live.add(name)
            else:
                r.set_pose(name, item.pose)
        for name in self._live - wanted:
            r.remove(name)
        self._live = wanted
        r.set_view(desc.view.T_view_from_scene)
        if with_depth:
            color, depth = r.render(with_depth=True)
            return np.ascontiguousarray(color[..., :3]), depth
        return np.ascontiguousarray(r.render()[..., :3])

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._live.clear()
        self._meshes.clear()


__all__ = ["PyrenderSceneRenderer"]
