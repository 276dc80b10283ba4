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
    proj, _ = cv2.projectPoints(obj, rvec, tvec, K, d)
    rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img.reshape(-1, 2)) ** 2, 1))))
    T = from_rvec_tvec(rvec, tvec)
    if not np.all(np.isfinite(T)) or T[2, 3] <= 0 or rms > MAX_RMS_PX:
        return None
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
