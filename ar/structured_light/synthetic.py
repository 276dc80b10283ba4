"""The synthetic rig showing the Gray-code sequence: board, table and boxes, with known truth.

Method: the scene is the table plane (``z = 0`` in the board frame, the printed board on
it) and axis-aligned boxes standing on it (``z`` from ``-height`` to 0; "up" is ``-z``).
Per pose, every supersampled camera pixel's undistorted ray
(:attr:`ar.synthetic.SyntheticCamera.rays`) is cast into the board frame and meets the
nearest surface: the plane, or a box (slab test). Its projector light is sampled by
projecting that 3-D point into the projector (:meth:`~ar.synthetic.SyntheticCamera.projector_light`),
and it is lit only if the segment from the projector's centre to it crosses no box
(cast shadows, and box faces turned away from the projector, stay dark). The camera sees
``albedo * (ambient + gain * projector)``, area-averaged to its resolution with the same
noise as every other synthetic frame (:meth:`~ar.synthetic.SyntheticCamera.finish`).

The geometry is computed once per pose; each of the sequence's images then costs one
remap and one resize, so a 42-image pose renders in about a second.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import cv2
import numpy as np

from ar.boards import Board
from ar.camera_sources import CameraSource
from ar.geometry import invert, look_at
from ar.synthetic import Degradation, SyntheticCamera
from ar.structured_light.patterns import graycode_sequence


@dataclass(frozen=True)
class Box:
    """An axis-aligned box on the table, in board-frame metres: ``x0..x1`` by ``y0..y1``,
    ``height`` tall (it occupies ``z`` from ``-height`` to 0)."""

    x0: float
    y0: float
    x1: float
    y1: float
    height: float
    albedo: tuple[float, float, float] = (0.55, 0.62, 0.70)  # BGR, light cardboard

    @property
    def lo(self) -> np.ndarray:
        return np.array([self.x0, self.y0, -self.height])

    @property
    def hi(self) -> np.ndarray:
        return np.array([self.x1, self.y1, 0.0])


def _slab(o: np.ndarray, d: tuple[np.ndarray, np.ndarray, np.ndarray], box: Box) -> tuple[np.ndarray, np.ndarray]:
    """Ray ``o + s d`` against a box: entry and exit parameters (entry > exit where it misses).
    ``o`` is one point (3,) or per-ray points (3, ...)."""
    lo, hi = box.lo, box.hi
    near = np.full(d[0].shape, -np.inf, np.float32)
    far = np.full(d[0].shape, np.inf, np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k in range(3):
            inv = np.float32(1.0) / d[k]
            a = (lo[k] - o[k]) * inv
            b = (hi[k] - o[k]) * inv
            near = np.maximum(near, np.nan_to_num(np.minimum(a, b), nan=-np.inf))
            far = np.minimum(far, np.nan_to_num(np.maximum(a, b), nan=np.inf))
    return near, far


class GrayCodeScene:
    """Renders what the synthetic rig's camera sees while the projector shows images onto
    the table and the boxes on it (truth: the camera's and projector's models and the
    boxes; poses are ``T_cam_from_board``)."""

    def __init__(self, camera: SyntheticCamera, boxes: Sequence[Box] = ()):
        self.cam = camera
        self.boxes = tuple(boxes)
        self._cached: tuple[bytes, dict[str, np.ndarray]] | None = None

    def surface(self, T_cam_from_board: np.ndarray) -> dict[str, np.ndarray]:
        """Per supersampled pixel: the board-frame point its ray meets (``x``, ``y``, ``z``),
        whether it meets anything (``valid``), its albedo (H, W, 3) and whether the
        projector reaches it (``lit``). The last pose's surface is kept (read-only)."""
        key = np.asarray(T_cam_from_board, np.float64).tobytes()
        if self._cached is None or self._cached[0] != key:
            self._cached = (key, self._surface(T_cam_from_board))
        return self._cached[1]

    def _surface(self, T_cam_from_board: np.ndarray) -> dict[str, np.ndarray]:
        T = invert(T_cam_from_board)
        R, o = T[:3, :3].astype(np.float32), T[:3, 3].astype(np.float32)
        rays = self.cam.rays
        xn, yn = rays[..., 0], rays[..., 1]
        d = tuple(R[k, 0] * xn + R[k, 1] * yn + R[k, 2] for k in range(3))
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -o[2] / d[2]
        valid = s > 0
        s = np.where(valid, s, np.inf).astype(np.float32)
        which = np.full(s.shape, -1, np.int16)  # -1 plane, else the box index
        for i, box in enumerate(self.boxes):
            near, far = _slab(o, d, box)
            hit = (near <= far) & (near > 0) & (near < s)
            s = np.where(hit, near, s)
            which[hit] = i
        valid |= which >= 0
        s = np.where(valid, s, 0).astype(np.float32)
        x, y, z = (o[k] + s * d[k] for k in range(3))
        albedo = self.cam.albedo(x, y)
        for i, box in enumerate(self.boxes):
            albedo[which == i] = np.asarray(box.albedo, np.float32)
        return {"x": x, "y": y, "z": z, "valid": valid, "albedo": albedo, "lit": self._lit(T_cam_from_board, x, y, z)}

    def _lit(self, T_cam_from_board: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """True where the segment from the projector's centre to the point crosses no box."""
        lit = np.ones(x.shape, bool)
        if not self.boxes:
            return lit
        c = invert(self.cam.proj_from_cam @ T_cam_from_board)[:3, 3].astype(np.float32)  # projector centre, board frame
        seg = (x - c[0], y - c[1], z - c[2])
        for box in self.boxes:
            near, far = _slab(c, seg, box)
            lit &= ~((near <= far) & (far > 0) & (near < 1 - 1e-5))
        return lit

    def render_sequence(self, T_cam_from_board: np.ndarray, images: Sequence[np.ndarray],
                        degradation: Degradation | None = None,
                        rng: np.random.Generator | None = None) -> list[np.ndarray]:
        """The camera's BGR uint8 frames while the projector shows each of ``images``."""
        deg = degradation or Degradation()
        rng = rng or np.random.default_rng(0)
        surf = self.surface(T_cam_from_board)
        albedo = surf["albedo"] * deg.exposure  # a copy: the cached surface stays as it is
        albedo[~surf["valid"]] = 0
        ambient = self.cam.ambient_light(albedo.shape, deg)
        gain = (self.cam.projector_gain * surf["lit"]).astype(np.float32)[..., None]
        frames = []
        for image in images:
            light = ambient + gain * self.cam.projector_light(T_cam_from_board, surf["x"], surf["y"], image, surf["z"])
            frames.append(self.cam.finish(albedo * light, T_cam_from_board, deg, rng))
        return frames

    def capture_graycode(self, T_cam_from_board: np.ndarray, degradation: Degradation | None = None,
                         seed: int = 0) -> list[np.ndarray]:
        """One pose's Gray-code captures (patterns, white, black) for the rig's projector."""
        return self.render_sequence(T_cam_from_board, graycode_sequence(self.cam.projector.size), degradation,
                                    np.random.default_rng(seed))

    def height_truth(self, T_cam_from_board: np.ndarray) -> np.ndarray:
        """True height above the table (metres, ``-z``) seen at each camera pixel (output
        resolution, nearest supersample), NaN where the ray meets nothing."""
        surf = self.surface(T_cam_from_board)
        h = np.where(surf["valid"], -surf["z"], np.nan)
        ss = self.cam.ss
        return h[ss // 2::ss, ss // 2::ss]


def graycode_poses(board: Board, proj_from_cam: np.ndarray, n_poses: int = 5, distance_m: float = 0.5,
                   seed: int = 3, spread_m: float = 0.05) -> list[np.ndarray]:
    """``T_cam_from_board`` for a Gray-code calibration: the *projector* looks at the board's
    centre from ``distance_m`` (so its light covers the board), tilted 15-40 degrees toward
    directions spread around the board and rolled differently -- the varied views that
    separate focal length from distance -- and the camera rides along, rigidly.
    ``spread_m`` aims each pose that far beside the centre, in turn around it, so the
    board's corners reach different parts of both images (the lens models are then fitted
    over more of the image than its middle)."""
    rng = np.random.default_rng(seed)
    centre = board.centre
    poses = []
    for i in range(n_poses):
        phi = 2 * np.pi * i / n_poses + np.pi / 4
        c = centre + spread_m * np.array([np.cos(phi), np.sin(phi), 0.0])
        az = 2 * np.pi * (i + 0.5) / n_poses + rng.uniform(-0.25, 0.25)
        tilt = np.radians(15 + 25 * ((i * 0.618) % 1.0))
        d = distance_m * rng.uniform(0.9, 1.1)
        eye = c + d * np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), -np.cos(tilt)])
        roll = np.radians(rng.uniform(-20, 20))
        up = np.array([-np.cos(roll), np.sin(roll), 0.0])
        T_proj_from_board = look_at(eye, c, up)
        poses.append(invert(proj_from_cam) @ T_proj_from_board)
    return poses


def default_scan_box(board: Board) -> Box:
    """A 60 x 80 x 30 mm box standing on the table just right of the board (in every
    synthetic pose's view, clear of the board's corners)."""
    w = board.sheet_size_m[0]
    return Box(w + 0.01, 0.06, w + 0.07, 0.14, 0.03)


def write_graycode_captures(folder: str | Path, scene: GrayCodeScene, poses: Sequence[np.ndarray],
                            degradation: Degradation | None = None,
                            progress: Callable[[str], None] | None = None, scan_pose: int | None = None) -> Path:
    """Render each pose's Gray-code captures into ``folder/pose_XX/NN.png`` (grey, names
    sorting in sequence order) and the truth into ``folder/truth.json`` (``scan_pose``: the
    index of the pose meant for scanning, recorded there); returns ``folder``."""
    folder = Path(folder)
    cam = scene.cam
    for i, T in enumerate(poses):
        pose_dir = folder / f"pose_{i:02d}"
        pose_dir.mkdir(parents=True, exist_ok=True)
        for k, frame in enumerate(scene.capture_graycode(T, degradation, seed=i)):
            cv2.imwrite(str(pose_dir / f"{k:02d}.png"), cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
        if progress:
            progress(f"rendered {pose_dir.name} ({i + 1}/{len(poses)})")
    truth = {"camera": {"camera_matrix": cam.camera.K.tolist(), "dist_coeffs": cam.camera.dist.tolist(),
                        "image_size": list(cam.camera.size)},
             "projector": {"camera_matrix": cam.projector.K.tolist(), "dist_coeffs": cam.projector.dist.tolist(),
                           "image_size": list(cam.projector.size)},
             "R": cam.proj_from_cam[:3, :3].tolist(), "T": cam.proj_from_cam[:3, 3].tolist(),
             "board": str(cam.board.spec), "T_cam_from_board": {f"pose_{i:02d}": T.tolist() for i, T in enumerate(poses)},
             "scan_pose": None if scan_pose is None else f"pose_{scan_pose:02d}",
             "boxes": [{"x0": b.x0, "y0": b.y0, "x1": b.x1, "y1": b.y1, "height": b.height} for b in scene.boxes]}
    (folder / "truth.json").write_text(json.dumps(truth, indent=1))
    return folder


class ProjectedSceneSource(CameraSource):
    """The synthetic rig as a live camera source with a projector window: :meth:`show` is
    the projector's callback (what it shows from now on), :meth:`read` renders the scene
    under that light at the current board pose, and :meth:`next_pose` stands for the
    teacher moving the board (it cycles through ``poses``)."""

    live = True

    def __init__(self, scene: GrayCodeScene, poses: Sequence[np.ndarray], degradation: Degradation | None = None,
                 seed: int = 0):
        super().__init__("synthetic rig (projector showing the sequence)")
        self.scene = scene
        self.poses = list(poses)
        self.pose_index = 0
        self.degradation = degradation
        self._rng = np.random.default_rng(seed)
        w, h = scene.cam.projector.size
        self._shown = np.zeros((h, w), np.uint8)
        self.shown_count = 0

    def show(self, image: np.ndarray) -> None:
        """The projector window's callback: show ``image`` (projector resolution, grey or RGB)."""
        self._shown = np.asarray(image)
        self.shown_count += 1

    def next_pose(self) -> None:
        self.pose_index = (self.pose_index + 1) % len(self.poses)

    @property
    def T_cam_from_board(self) -> np.ndarray:
        return self.poses[self.pose_index]

    def _grab(self) -> np.ndarray | None:
        return self.scene.render_sequence(self.T_cam_from_board, [self._shown], self.degradation, self._rng)[0]


def scan_view(board: Board, box: Box, proj_from_cam: np.ndarray, projector_fov: tuple[float, float] = (0.79, 0.59),
              distance_m: float = 0.5, tilt_deg: float = 20.0, fill: float = 0.85) -> np.ndarray:
    """``T_cam_from_board`` of a scan: the projector aims at the centre of the box and the
    printed sheet together, tilted ``tilt_deg`` toward the board's -y side, from
    ``distance_m`` or farther -- as far as it takes for both to fill at most ``fill`` of the
    projector's view (``projector_fov``: its width and height over distance; image up is
    the board's -x) -- so the whole board is seen and lit beside the box."""
    sw, sh = board.sheet_size_m
    m = board.margin_m
    x0, x1 = min(-m, box.x0), max(sw - m, box.x1)
    y0, y1 = min(-m, box.y0), max(sh - m, box.y1)
    aim = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    d = max(distance_m, (x1 - x0) / (fill * projector_fov[1]), (y1 - y0) / (fill * projector_fov[0]))
    t = np.radians(tilt_deg)
    eye = aim + d * np.array([0.0, -np.sin(t), -np.cos(t)])
    return invert(proj_from_cam) @ look_at(eye, aim, np.array([-1.0, 0.0, 0.0]))


def height_map_errors(height_map, boxes: Sequence[Box], inset_m: float = 0.004, clear_m: float = 0.01) -> dict:
    """A scanned height map against the scene's truth: per box, the known cells of its
    top (``inset_m`` in from its edges) and their median height (mm) and its error; for
    the table (known cells ``clear_m`` or more from every box) the median and 95th
    percentile of ``|height|`` (mm), which is 0 on the true table."""
    xs, ys = height_map.cell_centres()
    known = height_map.known
    out: dict = {"boxes": []}
    table = known.copy()
    for b in boxes:
        top = known & (xs > b.x0 + inset_m) & (xs < b.x1 - inset_m) & (ys > b.y0 + inset_m) & (ys < b.y1 - inset_m)
        h = height_map.heights[top]
        median = float(np.median(h)) if h.size else float("nan")
        out["boxes"].append({"height_mm": b.height * 1000, "top_cells": int(top.sum()), "median_mm": median * 1000,
                             "error_mm": (median - b.height) * 1000})
        table &= ~((xs > b.x0 - clear_m) & (xs < b.x1 + clear_m) & (ys > b.y0 - clear_m) & (ys < b.y1 + clear_m))
    t = np.abs(height_map.heights[table]) * 1000
    out["table"] = {"cells": int(table.sum()), "abs_median_mm": float(np.median(t)) if t.size else float("nan"),
                    "abs_p95_mm": float(np.percentile(t, 95)) if t.size else float("nan")}
    return out


def boxes_from_truth(truth: dict) -> list[Box]:
    """The boxes of a ``truth.json`` written by :func:`write_graycode_captures`."""
    return [Box(float(b["x0"]), float(b["y0"]), float(b["x1"]), float(b["y1"]), float(b["height"]))
            for b in truth.get("boxes", [])]
