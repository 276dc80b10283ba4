"""Board detection + planar pose (IPPE, then Levenberg-Marquardt refinement).

``estimate_board_pose`` turns one camera frame into ``T_cam_from_board`` (see
:mod:`ar.geometry` for the convention) with a confidence in 0..1. IPPE
(``cv2.SOLVEPNP_IPPE``) is the closed-form solver made for planar targets: it returns
the two candidate poses of a plane and picks the one with the lower reprojection
error, avoiding the flips iterative PnP can fall into. ``solvePnPRefineLM`` then
polishes it on all points.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import cv2
import numpy as np

from ar.boards import Board, BoardDetection
from ar.geometry import from_rvec_tvec

#: fewer matched points than this and a pose is not attempted (4 = a single ArUco marker)
MIN_POINTS = 6
#: reprojection RMS (px) above which a pose is rejected as a mismatch
MAX_RMS_PX = 3.0


@dataclass
class PoseEstimate:
    """One frame's board pose with quality figures."""

    T_cam_from_board: np.ndarray
    rms_px: float  # reprojection RMS of the matched points
    n_points: int
    coverage: float  # matched points / points on the board
    confidence: float  # 0..1, see :func:`pose_confidence`
    detection: BoardDetection
    covariance: np.ndarray | None = None  # 6x6, [local rotation (rad), translation (m)], see pose_covariance


def pose_covariance(T_cam_from_board: np.ndarray, object_points: np.ndarray, K: np.ndarray, dist: np.ndarray,
                    sigma_px: float) -> np.ndarray:
    """First-order 6x6 covariance of a PnP pose: ``sigma^2 (J^T J)^-1``.

    Parametrisation: ``R = R_est @ exp(dtheta)`` (local rotation, rad) and
    ``t = t_est + dt`` (m). The Jacobian is taken numerically (6 extra projections),
    which avoids the singularities of the global Rodrigues vector. It tells the
    Kalman filter how much to trust this frame: few points, one-sided coverage,
    steep views or noisy corners all show up here.
    """
    obj = np.asarray(object_points, np.float64).reshape(-1, 1, 3)
    d = np.asarray(dist, np.float64).ravel()
    R, t = T_cam_from_board[:3, :3], T_cam_from_board[:3, 3]

    def proj(Rx, tx):
        px, _ = cv2.projectPoints(obj, cv2.Rodrigues(Rx)[0], tx, K, d)
        return px.reshape(-1)

    base = proj(R, t)
    eps = 1e-6
    J = np.empty((base.size, 6))
    for k in range(3):
        e = np.zeros(3)
        e[k] = eps
        J[:, k] = (proj(R @ cv2.Rodrigues(e)[0], t) - base) / eps
        J[:, 3 + k] = (proj(R, t + e) - base) / eps
    return sigma_px ** 2 * np.linalg.pinv(J.T @ J)


def pose_confidence(n_points: int, coverage: float, rms_px: float) -> float:
    """Heuristic 0..1: many points, much of the board, and a low reprojection error.

    Saturates at 12 points, 60 % coverage, and falls off as rms grows past 0.5 px.
    """
    points_term = min(1.0, n_points / 12.0)
    coverage_term = min(1.0, coverage / 0.6)
    rms_term = 1.0 / (1.0 + (rms_px / 0.5) ** 2)
    return float(points_term * (0.5 + 0.5 * coverage_term) * rms_term)


def solve_board_pose(detection: BoardDetection, K: np.ndarray, dist: np.ndarray) -> PoseEstimate | None:
    """Planar PnP on a detection; ``None`` when too few points or the fit is implausible."""
    if detection.n < MIN_POINTS:
        return None
    obj = detection.object_points.reshape(-1, 1, 3).astype(np.float64)
    img = detection.image_points.reshape(-1, 1, 2).astype(np.float64)
    d = np.asarray(dist, np.float64).ravel()
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, d, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return None
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, d, rvec, tvec)
    return pose_estimate(from_rvec_tvec(rvec, tvec), detection, K, d)


def reprojection_residuals(T_cam_from_board: np.ndarray, detection: BoardDetection, K: np.ndarray,
                           dist: np.ndarray) -> np.ndarray:
    """(N,) pixel distance between each matched image point and its board point projected by the pose."""
    obj = detection.object_points.reshape(-1, 1, 3).astype(np.float64)
    rvec, _ = cv2.Rodrigues(np.ascontiguousarray(T_cam_from_board[:3, :3]))
    proj, _ = cv2.projectPoints(obj, rvec, T_cam_from_board[:3, 3].astype(np.float64), K,
                                np.asarray(dist, np.float64).ravel())
    return np.linalg.norm(proj.reshape(-1, 2) - detection.image_points.reshape(-1, 2), axis=1)


def pose_estimate(T: np.ndarray, detection: BoardDetection, K: np.ndarray, dist: np.ndarray,
                  max_rms_px: float = MAX_RMS_PX) -> PoseEstimate | None:
    """The quality figures of a solved pose (RMS, coverage, covariance, confidence); ``None``
    when it is implausible (not finite, behind the camera, RMS over ``max_rms_px``). Shared by
    the detector's poses and the followed ones (:mod:`ar.corner_flow`)."""
    if not np.all(np.isfinite(T)) or T[2, 3] <= 0:
        return None
    rms = float(np.sqrt(np.mean(reprojection_residuals(T, detection, K, dist) ** 2)))
    if rms > max_rms_px:
        return None
    d = np.asarray(dist, np.float64).ravel()
    coverage = detection.n / max(1, detection.total_points)
    # residual rms underestimates noise with few points (6 dof absorbed); floor it at 0.05 px
    dof = max(1, 2 * detection.n - 6)
    sigma = max(0.05, rms * np.sqrt(2 * detection.n / dof))
    cov = pose_covariance(T, detection.object_points, K, d, sigma)
    return PoseEstimate(T, rms, detection.n, coverage, pose_confidence(detection.n, coverage, rms), detection, cov)


def estimate_board_pose(image: np.ndarray, board: Board, K: np.ndarray, dist: np.ndarray) -> PoseEstimate | None:
    """Detect ``board`` in ``image`` and return its pose, or ``None`` if not found."""
    detection = board.detect(image)
    if detection is None:
        return None
    return solve_board_pose(detection, K, dist)


class RegionPoseEstimator:
    """Board pose frame after frame, searching where the last pose says the board is.

    Method: after a frame with a pose, the board's pattern is projected with that pose
    and the next frame is searched only inside its bounding box, grown by a margin
    (``margin_px`` plus ``margin_motion`` times how far the projected corners moved
    between the last two poses, so a fast hand widens it). When the projected markers
    are large (``min_marker_px`` times ``scale`` and more) the markers are found on an
    image shrunk ``scale`` times and the corners refined at full resolution (see
    :meth:`ar.boards.Board.detect`). If the region search finds nothing, or there is
    no recent pose (``max_gap`` frames without one), the whole frame is searched, so the
    result can only differ from :func:`estimate_board_pose` when the board is found in
    the region: the same detector, then on a crop. When both miss, the rescue pass
    (contrast normalisation, upsampling, wider detector settings:
    :meth:`ar.boards.Board.detect_enhanced`) searches the region (or the whole frame) once
    more (upsampled when the markers are small). ``counts`` records which path each frame took (``region``, ``full``,
    ``fallback`` = region missed then full frame, ``rescued`` = found by the rescue pass,
    ``lost``), ``last_path`` the latest frame's.
    """

    def __init__(self, board: Board, K: np.ndarray, dist: np.ndarray, margin_px: float = 24.0,
                 margin_motion: float = 2.0, min_marker_px: float = 24.0, max_scale: int = 2, max_gap: int = 2,
                 rescue: bool = True):
        """``rescue``: when the region and the whole frame both miss, search once more with the
        rescue pass for dim, small and blurred boards (:meth:`ar.boards.Board.detect_enhanced`)."""
        self.board = board
        self.rescue = rescue
        #: the rescue pass upsamples the region twice when the markers were smaller than this (px)
        self.rescue_upsample_below_px = 16.0
        self._plan: tuple[tuple[int, int, int, int], int] | None = None
        self.K = np.asarray(K, np.float64)
        self.dist = np.asarray(dist, np.float64).ravel()
        self.margin_px = margin_px
        self.margin_motion = margin_motion
        self.min_marker_px = min_marker_px
        self.max_scale = max(1, int(max_scale))
        self.max_gap = max_gap
        w, h = board.pattern_size_m
        self._quad = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]], np.float64)
        self.counts = {"region": 0, "full": 0, "fallback": 0, "rescued": 0, "lost": 0}
        self.last_path = "full"
        self.reset()

    def reset(self) -> None:
        """Forget the last pose (the next frame is searched whole)."""
        self._last_px: np.ndarray | None = None
        self._motion_px = 0.0
        self._gap = 0

    def predicted_region(self, image_size: tuple[int, int]) -> tuple[tuple[int, int, int, int], int] | None:
        """``((x0, y0, x1, y1), scale)`` to search next, or ``None`` for the whole frame."""
        if self._last_px is None or self._gap > self.max_gap:
            return None
        q = self._last_px
        margin = self.margin_px + self.margin_motion * self._motion_px * (1 + self._gap)
        x0, y0 = np.floor(q.min(0) - margin)
        x1, y1 = np.ceil(q.max(0) + margin)
        w, h = image_size
        box = (int(max(0, x0)), int(max(0, y0)), int(min(w, x1)), int(min(h, y1)))
        if box[2] - box[0] < 32 or box[3] - box[1] < 32:
            return None
        scale = 1
        if self.board.spec.kind != "checker":
            marker_px = self._marker_px(q)
            while scale < self.max_scale and marker_px / (scale + 1) >= self.min_marker_px:
                scale += 1
        return box, scale

    def estimate(self, image: np.ndarray, select: Callable[[BoardDetection], BoardDetection] | None = None,
                 rescue: bool | None = None, whole: bool = True) -> PoseEstimate | None:
        """This frame's pose (``None`` when the board is not found anywhere).

        ``select``: applied to each detection before its pose is solved (the rig leaves out
        the corners its own projector lit, :class:`ar.rig.ProjectedLight`); None keeps all.
        ``rescue``: whether the rescue pass runs when the region and the whole frame miss
        (default: the estimator's ``rescue``); ``whole``: whether the whole frame is searched
        when the region misses. The rig defers both while it follows the board's corners
        (the region follows the board) and runs them with :meth:`retry` when following fails."""
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        h, w = gray.shape[:2]
        plan = self._plan = self.predicted_region((w, h))
        estimate = None
        if plan is not None:
            box, scale = plan
            estimate = self._solve(self.board.detect(gray, box, scale), select)
            path = "region" if estimate is not None else "fallback"
        else:
            path = "full"
        if estimate is None and (whole or plan is None):
            estimate = self._solve(self.board.detect(gray), select)
        if estimate is None and (self.rescue if rescue is None else rescue):
            estimate = self._rescue(gray, select)
            path = "rescued"
        if estimate is None:
            self.counts["lost"] += 1
            self.last_path = "lost"
            self._gap += 1
            return None
        return self._found(path, estimate)

    def retry(self, image: np.ndarray, select: Callable[[BoardDetection], BoardDetection] | None = None,
              whole: bool = True) -> PoseEstimate | None:
        """What :meth:`estimate` left out on the frame it has just missed: the whole frame
        (``whole``, when a region was searched) and the rescue pass (if the estimator has it); a
        pose found now counts that frame as ``fallback`` or ``rescued`` instead of ``lost``."""
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        estimate, path = None, "fallback"
        if whole and self._plan is not None:
            estimate = self._solve(self.board.detect(gray), select)
        if estimate is None and self.rescue:
            estimate, path = self._rescue(gray, select), "rescued"
        if estimate is None:
            return None
        self.counts["lost"] -= 1
        return self._found(path, estimate)

    def _rescue(self, gray: np.ndarray, select) -> PoseEstimate | None:
        """:meth:`ar.boards.Board.detect_enhanced` on the predicted region (else the whole frame),
        upsampled when the last pose's markers were under ``rescue_upsample_below_px``."""
        plan = self._plan
        if plan is None:
            return self._solve(self.board.detect_enhanced(gray), select)
        up = 2 if self._marker_px(self._last_px) < self.rescue_upsample_below_px else 1
        return self._solve(self.board.detect_enhanced(gray, plan[0], up), select)

    def _marker_px(self, quad: np.ndarray) -> float:
        """Side of a marker (checker: a square) in pixels, from the pattern's projected outline."""
        s = self.board.spec
        edges = np.linalg.norm(np.roll(quad, -1, 0) - quad, axis=1)  # top, right, bottom, left
        if s.kind == "checker":
            return float(min(edges[0] / (s.cols + 1), edges[2] / (s.cols + 1), edges[1] / (s.rows + 1),
                             edges[3] / (s.rows + 1)))
        square_px = min(edges[0] / s.cols, edges[2] / s.cols, edges[1] / s.rows, edges[3] / s.rows)
        return float(square_px * (s.marker_m / s.square_m if s.kind == "charuco" else 1.0))

    def _found(self, path: str, estimate: PoseEstimate) -> PoseEstimate:
        self.last_path = path
        self.counts[path] += 1
        self.observe(estimate.T_cam_from_board)
        return estimate

    def observe(self, T_cam_from_board: np.ndarray) -> None:
        """Take ``T_cam_from_board`` as this frame's pose: the next frame is searched around it.
        Called with each detected pose, and by the rig with a pose found otherwise (corners
        followed between detections, :mod:`ar.corner_flow`), so the region follows the board
        through frames the detector missed."""
        px = cv2.projectPoints(self._quad.reshape(-1, 1, 3), cv2.Rodrigues(T_cam_from_board[:3, :3])[0],
                               T_cam_from_board[:3, 3], self.K, self.dist)[0].reshape(-1, 2)
        if not np.all(np.isfinite(px)):
            self.reset()
            return
        if self._last_px is not None and self._gap == 0:
            self._motion_px = float(np.max(np.linalg.norm(px - self._last_px, axis=1)))
        self._last_px = px
        self._gap = 0

    def _solve(self, detection: BoardDetection | None,
               select: Callable[[BoardDetection], BoardDetection] | None) -> PoseEstimate | None:
        if detection is None:
            return None
        return solve_board_pose(select(detection) if select is not None else detection, self.K, self.dist)


def draw_pose(image: np.ndarray, estimate: PoseEstimate | None, K: np.ndarray, dist: np.ndarray,
              axis_len_m: float = 0.06) -> np.ndarray:
    """Camera frame with detected corners and the board axes drawn (x red, y green, z blue)."""
    out = image.copy() if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if estimate is None:
        cv2.putText(out, "board not found", (10, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (0, 0, 255), 2)
        return out
    for p in estimate.detection.image_points:
        cv2.circle(out, (int(round(p[0])), int(round(p[1]))), 3, (0, 255, 255), 1)
    rvec, _ = cv2.Rodrigues(estimate.T_cam_from_board[:3, :3])
    cv2.drawFrameAxes(out, K, np.asarray(dist, np.float64).ravel(), rvec, estimate.T_cam_from_board[:3, 3], axis_len_m, 2)
    return out
