"""Temporal pose filtering and tracking state (tracking / holding / lost).

Default filter: :class:`PoseKalmanFilter`, an error-state Kalman filter whose
measurement noise is each frame's PnP covariance. Why not a fixed low-pass: on this
rig the projector shakes *with* the camera, so real hand tremor must be followed
exactly (filtering it away makes the projection shake on the table); only the
*estimation* noise should be removed, and that noise varies a lot from frame to frame
(clean vs. dim, occluded or steep views). The Kalman gain follows it. Measured on the
bench (see docs/design/ar.md) it lowers jitter in every condition without raising the error.

Alternative: a One-Euro filter (Casiez et al., CHI 2012) applied on the pose manifold:
translation is filtered per axis; rotation is filtered in the tangent space of the
current filtered rotation (``R_f <- R_f exp(alpha * log(R_f^T R_meas))``). One-Euro
adapts its cut-off to speed (low cut-off at rest, higher when moving). It suits a
still camera; on a handheld projector rig it lags the real 8-12 Hz tremor, which
*raises* translation jitter on clean frames (measured while choosing the default).

:class:`PoseTracker` wraps detection results: it filters good poses, *holds* the last
filtered pose for ``hold_s`` seconds when the board is lost (so a hand passing over the
board does not make the character vanish), then reports *lost*; the next good frame
restarts the filter from that measurement (no smoothing across a gap).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ar.geometry import invert, make_transform
from ar.pose import PoseEstimate

TRACKING, HOLDING, LOST = "tracking", "holding", "lost"


def _alpha(cutoff_hz: float, dt: float) -> float:
    tau = 1.0 / (2 * math.pi * cutoff_hz)
    return 1.0 / (1.0 + tau / dt)


@dataclass
class OneEuroParams:
    """One-Euro settings; units: Hz for cut-offs, ``beta`` in 1/(unit of speed)."""

    min_cutoff_t: float = 1.5  # translation cut-off at rest (Hz)
    beta_t: float = 20.0  # per (m/s)
    min_cutoff_r: float = 1.5  # rotation cut-off at rest (Hz)
    beta_r: float = 0.5  # per (deg/s)
    d_cutoff: float = 1.0  # cut-off for the speed estimate (Hz)


class PoseOneEuroFilter:
    """One-Euro filter of a rigid pose (translation in metres, rotation on SO(3))."""

    def __init__(self, params: OneEuroParams | None = None):
        self.p = params or OneEuroParams()
        self.reset()

    def reset(self) -> None:
        self._t: np.ndarray | None = None
        self._R: np.ndarray | None = None
        self._dt_speed = 0.0
        self._dr_speed = 0.0

    def __call__(self, T_cam_from_board: np.ndarray, dt: float, covariance: np.ndarray | None = None) -> np.ndarray:
        """Filter one ``T_cam_from_board`` measurement taken ``dt`` s after the previous one.

        Filtering happens on the *camera pose in the board frame*: a handheld rig mostly
        rotates, and a rotation moves the board origin in camera coordinates but not
        the camera centre in board coordinates, so translation and rotation speeds are
        decoupled and each gets its own adaptive cut-off.
        """
        return invert(self._filter(invert(T_cam_from_board), dt))

    def _filter(self, T_meas: np.ndarray, dt: float) -> np.ndarray:
        t_meas, R_meas = T_meas[:3, 3], T_meas[:3, :3]
        if self._t is None or dt <= 0:
            self._t, self._R = t_meas.copy(), R_meas.copy()
            return make_transform(self._R, self._t)
        p = self.p
        a_d = _alpha(p.d_cutoff, dt)
        # translation
        delta_t = t_meas - self._t
        self._dt_speed = (1 - a_d) * self._dt_speed + a_d * np.linalg.norm(delta_t) / dt
        a_t = _alpha(p.min_cutoff_t + p.beta_t * self._dt_speed, dt)
        self._t = self._t + a_t * delta_t
        # rotation, in the tangent space of the filtered rotation
        rvec, _ = cv2.Rodrigues(np.ascontiguousarray(self._R.T @ R_meas))
        ang_deg = math.degrees(float(np.linalg.norm(rvec)))
        self._dr_speed = (1 - a_d) * self._dr_speed + a_d * ang_deg / dt
        a_r = _alpha(p.min_cutoff_r + p.beta_r * self._dr_speed, dt)
        step, _ = cv2.Rodrigues(rvec * a_r)
        self._R = self._R @ step
        return make_transform(self._R, self._t)


@dataclass
class KalmanParams:
    """Random-walk process noise of the handheld rig, per square-root second.

    Defaults follow the synthetic handheld model (tremor ~0.1 deg and ~0.5 mm of board
    motion per frame at 30 fps): the filter must be able to follow that real motion.
    """

    rot_deg_per_sqrt_s: float = 0.7
    trans_m_per_sqrt_s: float = 0.003
    default_meas_rot_deg: float = 0.2  # used when an estimate carries no covariance
    default_meas_trans_m: float = 0.001


class PoseKalmanFilter:
    """Error-state Kalman filter of ``T_cam_from_board`` with per-frame measurement covariance.

    Unlike a fixed low-pass, the gain follows how trustworthy each frame is (the PnP
    covariance from :func:`ar.pose.pose_covariance`): a clean frame with many sharp
    corners is taken almost as is (no lag), a noisy, occluded or steep frame is
    blended with the prediction. Same call signature as :class:`PoseOneEuroFilter`.
    """

    def __init__(self, params: KalmanParams | None = None):
        self.p = params or KalmanParams()
        self.reset()

    def reset(self) -> None:
        self._T: np.ndarray | None = None
        self._P = np.eye(6)

    def __call__(self, T_meas: np.ndarray, dt: float, covariance: np.ndarray | None = None) -> np.ndarray:
        p = self.p
        if covariance is None or not np.all(np.isfinite(covariance)):
            covariance = np.diag([math.radians(p.default_meas_rot_deg) ** 2] * 3 + [p.default_meas_trans_m ** 2] * 3)
        if self._T is None or dt <= 0:
            self._T = T_meas.copy()
            self._P = covariance.copy()
            return self._T.copy()
        Q = np.diag([math.radians(p.rot_deg_per_sqrt_s) ** 2] * 3 + [p.trans_m_per_sqrt_s ** 2] * 3) * dt
        P = self._P + Q
        R_f, t_f = self._T[:3, :3], self._T[:3, 3]
        rvec, _ = cv2.Rodrigues(np.ascontiguousarray(R_f.T @ T_meas[:3, :3]))
        residual = np.concatenate([rvec.ravel(), T_meas[:3, 3] - t_f])
        gain = P @ np.linalg.inv(P + covariance)
        delta = gain @ residual
        self._T = make_transform(R_f @ cv2.Rodrigues(delta[:3])[0], t_f + delta[3:])
        self._P = (np.eye(6) - gain) @ P
        return self._T.copy()


@dataclass
class TrackerOutput:
    """What the app needs per frame: a pose to render with (or None), the state, a confidence."""

    state: str  # TRACKING, HOLDING or LOST
    T_cam_from_board: np.ndarray | None  # filtered (or held) pose
    confidence: float  # 0..1; decays linearly to 0 over the hold time
    raw: PoseEstimate | None  # this frame's unfiltered estimate
    seconds_since_seen: float


class PoseTracker:
    """Per-frame state machine: filter good poses, hold briefly when lost, recover on the next good frame."""

    def __init__(self, hold_s: float = 0.5, min_confidence: float = 0.2, pose_filter=None,
                 filter_enabled: bool = True, jump_reset_m: float = 0.05, jump_reset_deg: float = 15.0):
        """``pose_filter``: a :class:`PoseKalmanFilter` (default) or :class:`PoseOneEuroFilter`."""
        self.hold_s = hold_s
        self.min_confidence = min_confidence
        self.filter_enabled = filter_enabled
        self.filter = pose_filter if pose_filter is not None else PoseKalmanFilter()
        self.jump_reset_m = jump_reset_m
        self.jump_reset_deg = jump_reset_deg
        self._last_seen: float | None = None
        self._last_pose: np.ndarray | None = None
        self._last_conf = 0.0

    def update(self, estimate: PoseEstimate | None, timestamp_s: float) -> TrackerOutput:
        """Feed this frame's estimate (``None`` = board not found) taken at ``timestamp_s``."""
        good = estimate is not None and estimate.confidence >= self.min_confidence
        if good:
            restart = self._last_seen is None or timestamp_s - self._last_seen > self.hold_s
            if not restart and self._last_pose is not None:
                restart = self._is_jump(self._last_pose, estimate.T_cam_from_board)
            if restart:
                self.filter.reset()
            since = 0.0 if self._last_seen is None else timestamp_s - self._last_seen
            pose = (self.filter(estimate.T_cam_from_board, since if not restart else 0.0, estimate.covariance)
                    if self.filter_enabled else estimate.T_cam_from_board.copy())
            self._last_seen = timestamp_s
            self._last_pose = pose
            self._last_conf = estimate.confidence
            return TrackerOutput(TRACKING, pose, estimate.confidence, estimate, 0.0)
        if self._last_seen is None:
            return TrackerOutput(LOST, None, 0.0, estimate, math.inf)
        since = timestamp_s - self._last_seen
        if since <= self.hold_s:
            conf = self._last_conf * max(0.0, 1.0 - since / self.hold_s)
            return TrackerOutput(HOLDING, self._last_pose, conf, estimate, since)
        self.filter.reset()
        return TrackerOutput(LOST, None, 0.0, estimate, since)

    def _is_jump(self, T_prev: np.ndarray, T_new: np.ndarray) -> bool:
        """A big sudden change (re-detection after occlusion, other board) restarts the filter."""
        dt = np.linalg.norm(T_new[:3, 3] - T_prev[:3, 3])
        rvec, _ = cv2.Rodrigues(np.ascontiguousarray(T_prev[:3, :3].T @ T_new[:3, :3]))
        return dt > self.jump_reset_m or math.degrees(float(np.linalg.norm(rvec))) > self.jump_reset_deg
