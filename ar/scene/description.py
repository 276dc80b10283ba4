"""The renderer-agnostic scene: what to draw, from where, under which light.

A :class:`SceneDescription` is the one thing both renderers draw -- pyrender
(:mod:`ar.render`, the headless reference and the MP4 export) and Kivy's OpenGL ES 2
pipeline (:mod:`app.ui.gl`, the tablet) -- so the scene logic (characters, poses, the
tracked view) is written once. It is plain numpy: no GL, no trimesh.

Frames
    *board frame* (:mod:`ar.boards`): origin at the pattern's top-left outer corner, +x
    right, +y down the page, +z into the table.
    *scene frame*: **Y-up, metres, origin at the board centre on the table surface**:
    +X = board +x, +Y = up off the table (= board -z), +Z = board +y.

The view is an OpenCV pinhole (``K``, pixel centres at integers) with extrinsics
``T_view_from_scene``. For OpenGL the camera axes flip (:data:`CV_TO_GL`) and
:meth:`View.gl_projection` is the projection pyrender's ``IntrinsicsCamera`` builds with
``cx + 0.5, cy + 0.5`` (OpenGL pixel centres sit at half-integers): a scene point that
projects to OpenCV pixel ``(u, v)`` lands in the centre of pixel ``(u, v)`` of the image
(row ``v`` counted from the top).

Shading (both renderers): pyrender's metallic-roughness model with metallic 0 -- one
directional key light shining along the view direction (from the viewer, as the
projector's light does) with radiance ``key_intensity``, plus ``ambient`` times the base
colour, then gamma ``1/2.2``. Colours are RGB 0..255 used as linear base colours (as
pyrender does with ``baseColorFactor``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ar.boards import Board
from ar.geometry import invert, look_at, make_transform, scale_intrinsics
from ar.height_map import HeightMap
from ar.scene.mesh import MeshData
from ar.synthetic import PinholeModel

#: OpenCV camera axes (x right, y down, z forward) -> OpenGL camera axes (x right, y up, z back)
CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])

#: rotation part of T_board_from_scene (columns: scene X, Y, Z written in board axes)
_R_BOARD_FROM_SCENE = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

Colour = tuple[int, int, int]


def board_from_scene(board: Board) -> np.ndarray:
    """``T_board_from_scene`` for ``board`` (scene = Y-up, origin at the board centre)."""
    return make_transform(_R_BOARD_FROM_SCENE, board.centre)


def scene_to_board_points(points_scene: np.ndarray, board: Board) -> np.ndarray:
    """(N,3) scene-frame points -> board-frame points."""
    T = board_from_scene(board)
    return np.asarray(points_scene, np.float64) @ T[:3, :3].T + T[:3, 3]


def board_to_scene_points(points_board: np.ndarray, board: Board) -> np.ndarray:
    """(N,3) board-frame points -> scene-frame points."""
    T = invert(board_from_scene(board))
    return np.asarray(points_board, np.float64) @ T[:3, :3].T + T[:3, 3]


def scene_ground(height_map: HeightMap, board: Board):
    """The scanned table as the animation's ground: ``ground(X, Z) -> Y`` in the scene
    frame (arrays of any shape), the height map's height at board ``(x, y) = (X, Z) +``
    the board centre; 0 (the table) where the scan knows nothing
    (:func:`retrieval.animation.surface.follow_surface` takes it)."""
    cx, cy = (float(v) for v in board.centre[:2])

    def ground(x_scene: np.ndarray, z_scene: np.ndarray) -> np.ndarray:
        return np.asarray(height_map.height_at(np.asarray(x_scene) + cx, np.asarray(z_scene) + cy), np.float64)
    return ground


def projector_from_scene(T_cam_from_board: np.ndarray, T_proj_from_cam: np.ndarray, board: Board) -> np.ndarray:
    """``T_proj_from_scene``: chain tracked board pose, rig extrinsics and the scene frame."""
    return T_proj_from_cam @ T_cam_from_board @ board_from_scene(board)


def scaled_model(model: PinholeModel, width: int, height: int) -> PinholeModel:
    """The same lens at another resolution (:meth:`ar.synthetic.PinholeModel.scaled`)."""
    return model.scaled(width, height)


@dataclass
class View:
    """An OpenCV pinhole view of the scene: ``width`` x ``height`` pixels, intrinsics
    ``K``, extrinsics ``T_view_from_scene`` (scene -> camera, OpenCV axes)."""

    width: int
    height: int
    K: np.ndarray
    T_view_from_scene: np.ndarray = field(default_factory=lambda: np.eye(4))
    znear: float = 0.02
    zfar: float = 10.0

    def __post_init__(self) -> None:
        self.K = np.asarray(self.K, np.float64)
        self.T_view_from_scene = np.asarray(self.T_view_from_scene, np.float64)

    def gl_projection(self) -> np.ndarray:
        """The 4x4 OpenGL projection (pyrender ``IntrinsicsCamera`` with ``c + 0.5``)."""
        w, h, K, n, f = self.width, self.height, self.K, self.znear, self.zfar
        P = np.zeros((4, 4))
        P[0, 0] = 2.0 * K[0, 0] / w
        P[1, 1] = 2.0 * K[1, 1] / h
        P[0, 2] = 1.0 - 2.0 * (K[0, 2] + 0.5) / w
        P[1, 2] = 2.0 * (K[1, 2] + 0.5) / h - 1.0
        P[2, 2] = (f + n) / (n - f)
        P[2, 3] = 2.0 * f * n / (n - f)
        P[3, 2] = -1.0
        return P

    def gl_view(self) -> np.ndarray:
        """The OpenGL view matrix (scene -> camera in GL axes)."""
        return CV_TO_GL @ self.T_view_from_scene

    def scaled(self, width: int, height: int) -> "View":
        """The same view at another resolution (intrinsics scaled about pixel edges, as
        :func:`scaled_model` does: the image covers the same field of view)."""
        K = scale_intrinsics(self.K, width / self.width, height / self.height)
        return View(int(width), int(height), K, self.T_view_from_scene.copy(), self.znear, self.zfar)

    @property
    def eye(self) -> np.ndarray:
        """The camera's position in the scene frame."""
        return invert(self.T_view_from_scene)[:3, 3]

    @property
    def forward(self) -> np.ndarray:
        """The viewing direction (the key light's direction) in the scene frame."""
        return self.T_view_from_scene[2, :3].copy()

    def project(self, points_scene: np.ndarray) -> np.ndarray:
        """(N, 2) OpenCV pixel coordinates of (N, 3) scene points (no distortion)."""
        p = np.asarray(points_scene, np.float64) @ self.T_view_from_scene[:3, :3].T + self.T_view_from_scene[:3, 3]
        uv = p @ self.K.T
        return uv[:, :2] / uv[:, 2:3]


@dataclass(frozen=True)
class Lighting:
    """Ambient level and the key light's radiance (pyrender's ``ambient_light`` and
    ``DirectionalLight.intensity``); the key light shines along the view direction."""

    ambient: float = 0.35
    key_intensity: float = 3.0


@dataclass
class DrawItem:
    """One mesh of one colour at a 4x4 pose in the scene frame."""

    mesh: MeshData
    colour: Colour
    pose: np.ndarray
    roughness: float = 0.7


@dataclass
class SceneDescription:
    """Everything a renderer needs for one frame; black background = no light."""

    view: View
    items: list[DrawItem] = field(default_factory=list)
    lighting: Lighting = field(default_factory=Lighting)
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def add(self, mesh: MeshData, colour: Colour, pose: np.ndarray | None = None, roughness: float = 0.7) -> None:
        self.items.append(DrawItem(mesh, tuple(int(c) for c in colour),
                                   np.eye(4) if pose is None else np.asarray(pose, np.float64), roughness))


def overhead_view(width: int = 640, height: int = 480, eye=(0.0, 0.32, 0.30), target=(0.0, 0.0, 0.0),
                  focal: float = 0.9) -> View:
    """An authoring view from above and in front of the scene origin (focal = ``focal``
    times the width)."""
    f = focal * width
    K = np.array([[f, 0, width / 2 - 0.5], [0, f, height / 2 - 0.5], [0, 0, 1.0]])
    return View(width, height, K, look_at(np.asarray(eye, float), np.asarray(target, float), np.array([0.0, 1.0, 0.0])))


__all__ = ["CV_TO_GL", "Colour", "board_from_scene", "scene_to_board_points", "board_to_scene_points",
           "projector_from_scene", "scaled_model", "View", "Lighting", "DrawItem", "SceneDescription",
           "overhead_view"]
