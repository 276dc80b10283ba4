"""Render 3-D content from the projector's viewpoint (pyrender, headless EGL).

Frames: the *board frame* and the Y-up *scene frame* are defined in
:mod:`ar.scene.description` (re-exported here: ``board_from_scene``,
``projector_from_scene``, ...). The scene frame matches the retrieval code's Y-up metre
skeletons, so a character placed at the origin stands in the middle of the board.

The projector is an inverse camera: to make projected light land on the table where a
virtual object would be, render the scene with the projector's intrinsics from the
projector's pose. Black pixels are "no light". OpenCV -> OpenGL camera conversion:
``camera node pose = inv(T_proj_from_scene) @ diag(1, -1, -1, 1)``; pyrender's
``IntrinsicsCamera`` puts pixel centres at +0.5, so ``cx, cy`` get +0.5.

Threading: EGL contexts belong to the thread that made them. :class:`ProjectorRenderer`
creates its ``OffscreenRenderer`` lazily on the first :meth:`~ProjectorRenderer.render`
call and refuses calls from any other thread afterwards -- construct it anywhere, then
render only from one dedicated render thread (the app's pattern).

Draw order: pyrender draws opaque meshes farthest node first, and nodes at the same
distance (a character's parts posed around one joint) in the iteration order of its
node *set*, which follows object addresses and so changes from process to process.
Where parts overlap at equal depth the first drawn wins, so the same scene rendered in
two processes differed in 1–3 pixels a frame (the kid character), enough to move a
tracked take's detection rate by up to 4 points. :class:`ProjectorRenderer` breaks those
ties by node name (:func:`stable_mesh_order`): the same scene gives the same pixels in
every process.
"""
from __future__ import annotations

import threading
import types

import numpy as np
import pyrender
import trimesh

from ar import Board, CalibrationError, invert, make_transform
from ar.scene import (CV_TO_GL, board_from_scene, board_to_scene_points, projector_from_scene,  # noqa: F401 (re-exported)
                      scene_to_board_points)

def opencv_to_pyrender_pose(T_cam_from_world: np.ndarray) -> np.ndarray:
    """OpenCV extrinsics (world -> camera) -> pyrender camera node pose (camera -> world, GL axes)."""
    return invert(T_cam_from_world) @ CV_TO_GL


def pyrender_to_opencv_pose(camera_node_pose: np.ndarray) -> np.ndarray:
    """Inverse of :func:`opencv_to_pyrender_pose`."""
    return invert(camera_node_pose @ CV_TO_GL)


def stable_mesh_order(renderer, scene: pyrender.Scene) -> list[pyrender.Node]:
    """pyrender's draw order (opaque then transparent, each farthest node first from the
    main camera) with ties broken by node name, then by the order of the meshes'
    primitives' vertex counts: independent of the node set's iteration order."""
    cam = scene.get_pose(scene.main_camera_node)[:3, 3]

    def key(node: pyrender.Node):
        far = -float(np.linalg.norm(scene.get_pose(node)[:3, 3] - cam))
        return (bool(node.mesh.is_transparent), far, node.name or "",
                tuple(len(p.positions) for p in node.mesh.primitives))

    return sorted(scene.mesh_nodes, key=key)


def _use_stable_order(offscreen: pyrender.OffscreenRenderer) -> None:
    """Make ``offscreen`` draw in :func:`stable_mesh_order` (its inner renderer's
    ``_sorted_mesh_nodes``, pyrender-maintained 1.0.1's one draw-order hook)."""
    inner = getattr(offscreen, "_renderer", None)
    if inner is None or not hasattr(inner, "_sorted_mesh_nodes"):
        raise RuntimeError("pyrender changed: OffscreenRenderer._renderer._sorted_mesh_nodes is gone "
                           "(ar.render.projector_view relies on it for a stable draw order)")
    inner._sorted_mesh_nodes = types.MethodType(stable_mesh_order, inner)


class ProjectorRenderer:
    """A persistent offscreen renderer with a named scene graph, viewed through the projector.

    Other code adds meshes/nodes by name (:meth:`add`), moves them per frame
    (:meth:`set_pose`), sets the view from the tracked pose (:meth:`set_view` /
    :meth:`set_board_pose`) and calls :meth:`render`. Render from one thread only.
    """

    def __init__(self, width: int, height: int, K: np.ndarray, znear: float = 0.02, zfar: float = 10.0,
                 ambient: float = 0.35, light_intensity: float = 3.0):
        K = np.asarray(K, np.float64)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise CalibrationError("projector camera_matrix must be a finite 3x3 matrix with positive focal lengths")
        self.width, self.height = int(width), int(height)
        self.K = K
        self.scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 1.0], ambient_light=[ambient] * 3)
        cam = pyrender.IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5, znear=znear, zfar=zfar)
        self.camera_node = self.scene.add(cam, name="projector", pose=np.eye(4))
        light = pyrender.DirectionalLight(color=np.ones(3), intensity=light_intensity)
        # light comes from the projector's side, slightly above it, so shapes read as 3-D
        self.light_node = self.scene.add(light, name="key_light", parent_node=self.camera_node,
                                         pose=make_transform(np.eye(3), [0, 0.2, 0]))
        self._nodes: dict[str, pyrender.Node] = {}
        self._renderer: pyrender.OffscreenRenderer | None = None
        self._thread: int | None = None

    # ---------------------------------------------------------------- scene graph
    def add(self, name: str, content, pose: np.ndarray | None = None, parent: str | None = None) -> pyrender.Node:
        """Add a trimesh / pyrender.Mesh / pyrender.Node under ``name`` (replacing any node of that name)."""
        if name in self._nodes:
            self.remove(name)
        if isinstance(content, trimesh.Trimesh):
            content = pyrender.Mesh.from_trimesh(content, smooth=False)
        pose = np.eye(4) if pose is None else np.asarray(pose, np.float64)
        parent_node = self._nodes[parent] if parent else None
        if isinstance(content, pyrender.Node):
            content.matrix = pose
            self.scene.add_node(content, parent_node=parent_node)
            node = content
        else:
            node = self.scene.add(content, name=name, pose=pose, parent_node=parent_node)
        self._nodes[name] = node
        return node

    def remove(self, name: str) -> None:
        node = self._nodes.pop(name, None)
        if node is not None:
            self.scene.remove_node(node)

    def set_pose(self, name: str, pose: np.ndarray) -> None:
        """Move node ``name`` (scene frame) -- called per frame for animation."""
        self.scene.set_pose(self._nodes[name], np.asarray(pose, np.float64))

    def node(self, name: str) -> pyrender.Node:
        return self._nodes[name]

    @property
    def node_names(self) -> list[str]:
        return list(self._nodes)

    # ---------------------------------------------------------------- view
    def set_view(self, T_proj_from_scene: np.ndarray) -> None:
        """Place the virtual projector: OpenCV extrinsics scene -> projector."""
        self.scene.set_pose(self.camera_node, opencv_to_pyrender_pose(T_proj_from_scene))

    def set_board_pose(self, T_cam_from_board: np.ndarray, T_proj_from_cam: np.ndarray, board: Board) -> None:
        """Place the projector from a tracked board pose and the rig calibration."""
        self.set_view(projector_from_scene(T_cam_from_board, T_proj_from_cam, board))

    # ---------------------------------------------------------------- rendering
    def render(self, flat: bool = False, with_depth: bool = False):
        """RGB uint8 (H, W, 3) projector image (black = no light); optionally also depth (m)."""
        me = threading.get_ident()
        if self._renderer is None:
            self._renderer = pyrender.OffscreenRenderer(self.width, self.height)
            _use_stable_order(self._renderer)
            self._thread = me
        elif self._thread != me:
            raise RuntimeError("ProjectorRenderer: render() must always be called from the thread that first called it "
                               "(EGL contexts are per thread)")
        flags = pyrender.RenderFlags.FLAT if flat else pyrender.RenderFlags.NONE
        color, depth = self._renderer.render(self.scene, flags=flags)
        return (color, depth) if with_depth else color

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.delete()
            self._renderer = None
            self._thread = None

    def __enter__(self) -> "ProjectorRenderer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# ---------------------------------------------------------------------- test content
def _coloured(mesh: trimesh.Trimesh, rgb: tuple[float, float, float]) -> pyrender.Mesh:
    material = pyrender.MetallicRoughnessMaterial(baseColorFactor=[*rgb, 1.0], metallicFactor=0.0, roughnessFactor=0.8)
    return pyrender.Mesh.from_trimesh(mesh, material=material, smooth=False)


def axes_mesh(length: float = 0.08, radius: float = 0.003) -> list[tuple[str, pyrender.Mesh, np.ndarray]]:
    """Three coloured bars along scene +X (red), +Y/up (green), +Z (blue)."""
    out = []
    for name, axis, rgb in (("axis_x", 0, (1, 0, 0)), ("axis_y", 1, (0, 1, 0)), ("axis_z", 2, (0, 0.3, 1))):
        extents = [radius * 2] * 3
        extents[axis] = length
        centre = np.zeros(3)
        centre[axis] = length / 2
        out.append((name, _coloured(trimesh.creation.box(extents=extents), rgb), make_transform(np.eye(3), centre)))
    return out


def add_test_scene(renderer: ProjectorRenderer, board: Board, cube_m: float = 0.05) -> None:
    """Coloured axes at the board centre, a cube standing on the table, and a grid over the board."""
    for name, mesh, pose in axes_mesh():
        renderer.add(name, mesh, pose)
    renderer.add("cube", _coloured(trimesh.creation.box(extents=[cube_m] * 3), (1.0, 0.8, 0.2)),
                 make_transform(np.eye(3), [0.05, cube_m / 2, 0.06]))
    w, h = board.pattern_size_m
    bars = []
    for x in np.linspace(-w / 2, w / 2, 5):
        bars.append(trimesh.creation.box(extents=[0.002, 0.0005, h], transform=make_transform(np.eye(3), [x, 0, 0])))
    for z in np.linspace(-h / 2, h / 2, 7):
        bars.append(trimesh.creation.box(extents=[w, 0.0005, 0.002], transform=make_transform(np.eye(3), [0, 0, z])))
    renderer.add("grid", _coloured(trimesh.util.concatenate(bars), (0.6, 0.6, 1.0)))


def add_dots(renderer: ProjectorRenderer, points_scene: np.ndarray, radius: float = 0.004, name: str = "dots") -> None:
    """Flat white discs lying on the table at ``points_scene`` (for the closed-loop check)."""
    discs = []
    for p in np.asarray(points_scene, np.float64):
        disc = trimesh.creation.cylinder(radius=radius, height=0.0004, sections=48)
        disc.apply_transform(make_transform(np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]), p))  # axis -> +Y
        discs.append(disc)
    renderer.add(name, _coloured(trimesh.util.concatenate(discs), (1.0, 1.0, 1.0)))
