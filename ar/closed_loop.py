"""Closed-loop check: where does projected light actually land on the table?

The chain under test: camera frame -> board pose -> (calibration) -> projector view ->
rendered projector image. We render bright flat dots at known table points, find each
dot's centroid in the projector image, and cast that pixel through the *true*
projector (intrinsics and pose of the synthetic rig) onto the table plane. The
distance between where the light lands and where the dot should be is the landing
error -- what a child would see as "the character is off its spot".

It renders through :mod:`ar.render` (pyrender), so ``ar/__init__`` does not import it:
``from ar.closed_loop import LandingCheck``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from ar.boards import Board
from ar.geometry import pixels_to_plane, project_points
from ar.render import ProjectorRenderer, add_dots, board_to_scene_points, projector_from_scene


def default_dot_points(board: Board, spacing_m: float = 0.06, n: int = 3) -> np.ndarray:
    """An n x n grid of table points (board frame, z = 0) around the board centre."""
    offsets = (np.arange(n) - (n - 1) / 2) * spacing_m
    xs, ys = np.meshgrid(offsets, offsets)
    c = board.centre
    return np.stack([c[0] + xs.ravel(), c[1] + ys.ravel(), np.zeros(xs.size)], 1)


def dot_centroids(image: np.ndarray, threshold: int = 30, min_area: int = 4) -> np.ndarray:
    """Intensity-weighted centroids (N,2) of bright blobs in a projector image."""
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    n, labels, stats, _ = cv2.connectedComponentsWithStats((gray > threshold).astype(np.uint8), connectivity=8)
    out = []
    w = gray.astype(np.float64)
    for k in range(1, n):
        if stats[k, cv2.CC_STAT_AREA] < min_area:
            continue
        ys, xs = np.nonzero(labels == k)
        wk = w[ys, xs]
        out.append([np.sum(xs * wk) / wk.sum(), np.sum(ys * wk) / wk.sum()])
    return np.array(out).reshape(-1, 2)


@dataclass
class LandingResult:
    errors_mm: np.ndarray  # per dot; NaN where the dot was not found
    landed_board: np.ndarray  # (N,3) where the light landed (board frame)
    projector_image: np.ndarray
    render_ms: float  # time of the projector render alone


class LandingCheck:
    """Renders the dots through a :class:`ProjectorRenderer` and measures landing errors."""

    def __init__(self, renderer: ProjectorRenderer, board: Board, dot_points_board: np.ndarray | None = None,
                 dot_radius_m: float = 0.004):
        self.renderer = renderer
        self.board = board
        self.points = default_dot_points(board) if dot_points_board is None else np.asarray(dot_points_board, np.float64)
        add_dots(renderer, board_to_scene_points(self.points, board), dot_radius_m, name="landing_dots")

    def measure(self, T_cam_from_board_est: np.ndarray, T_proj_from_cam_est: np.ndarray,
                K_proj_true: np.ndarray, dist_proj_true: np.ndarray, T_proj_from_board_true: np.ndarray) -> LandingResult:
        """Render with the estimated chain, land through the true projector."""
        self.renderer.set_board_pose(T_cam_from_board_est, T_proj_from_cam_est, self.board)
        t0 = time.perf_counter()
        image = self.renderer.render(flat=True)
        render_ms = (time.perf_counter() - t0) * 1000.0
        found = dot_centroids(image)
        errors = np.full(len(self.points), np.nan)
        landed = np.full((len(self.points), 3), np.nan)
        if len(found):
            T_ps = projector_from_scene(T_cam_from_board_est, T_proj_from_cam_est, self.board)
            expected_px = project_points(board_to_scene_points(self.points, self.board), T_ps, self.renderer.K)
            lands = pixels_to_plane(found, T_proj_from_board_true, K_proj_true, dist_proj_true)
            for i, e in enumerate(expected_px):
                j = int(np.argmin(np.linalg.norm(found - e, axis=1)))
                if np.linalg.norm(found[j] - e) < 10.0:
                    landed[i] = lands[j]
                    errors[i] = float(np.linalg.norm(lands[j, :2] - self.points[i, :2]) * 1000.0)
        return LandingResult(errors, landed, image, render_ms)
