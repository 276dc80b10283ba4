"""Pose filters reduce estimation jitter without lag; tracker holds, loses and recovers."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from ar.boards import DEFAULT_BOARD_SPEC, Board
from ar.filtering import HOLDING, LOST, TRACKING, PoseKalmanFilter, PoseOneEuroFilter, PoseTracker
from ar.geometry import make_transform, pose_error
from ar.pose import PoseEstimate
from ar.synthetic import TrajectoryConfig, handheld_trajectory

SIGMA_ROT = np.radians(0.15)
SIGMA_T = 0.0008


def _noisy(T, rng):
    dR = cv2.Rodrigues(rng.normal(0, SIGMA_ROT, 3))[0]
    return make_transform(T[:3, :3] @ dR, T[:3, 3] + rng.normal(0, SIGMA_T, 3))


def _estimate(T, confidence=0.9):
    cov = np.diag([SIGMA_ROT ** 2] * 3 + [SIGMA_T ** 2] * 3)
    return PoseEstimate(T, 0.2, 24, 1.0, confidence, None, cov)


def _frame_to_frame_error_change(poses, truth):
    errs = np.array([pose_error(p, t) for p, t in zip(poses, truth)])
    return np.sqrt(np.mean(np.diff(errs, axis=0) ** 2, axis=0))


@pytest.fixture(scope="module")
def truth():
    return handheld_trajectory(Board(DEFAULT_BOARD_SPEC), 150, TrajectoryConfig(seed=9))


@pytest.mark.parametrize("make_filter", [PoseKalmanFilter, PoseOneEuroFilter])
def test_filter_reduces_jitter_of_noisy_measurements(truth, make_filter):
    rng = np.random.default_rng(0)
    measured = [_noisy(T, rng) for T in truth]
    f = make_filter()
    filtered = [f(m, 1 / 30, np.diag([SIGMA_ROT ** 2] * 3 + [SIGMA_T ** 2] * 3)) for m in measured]
    raw_jit = _frame_to_frame_error_change(measured, truth)
    filt_jit = _frame_to_frame_error_change(filtered, truth)
    assert filt_jit[0] < 0.7 * raw_jit[0]
    # smoothing must not buy jitter with lag: the error itself must not grow
    raw_err = np.median([pose_error(m, t)[0] for m, t in zip(measured, truth)])
    filt_err = np.median([pose_error(m, t)[0] for m, t in zip(filtered, truth)])
    assert filt_err < 1.1 * raw_err


def test_kalman_follows_precise_measurements_without_lag(truth):
    """When each frame is precise (tiny covariance), the filter takes it as is."""
    f = PoseKalmanFilter()
    tiny = np.diag([1e-12] * 6)
    out = [f(T, 1 / 30, tiny) for T in truth]
    worst = max(pose_error(o, t)[1] for o, t in zip(out, truth))
    assert worst < 0.01  # mm


def test_tracker_hold_lost_recover(truth):
    tracker = PoseTracker(hold_s=0.2)
    t = 0.0
    for T in truth[:10]:
        out = tracker.update(_estimate(T), t)
        t += 1 / 30
    assert out.state == TRACKING and out.confidence == pytest.approx(0.9)
    last_pose = out.T_cam_from_board
    held = tracker.update(None, t)
    assert held.state == HOLDING and np.allclose(held.T_cam_from_board, last_pose)
    assert 0 < held.confidence < 0.9
    lost = tracker.update(None, t + 0.5)
    assert lost.state == LOST and lost.T_cam_from_board is None and lost.confidence == 0.0
    # recovers on the next good frame, starting fresh from that measurement (no stale smoothing)
    back = tracker.update(_estimate(truth[60]), t + 0.55)
    assert back.state == TRACKING
    assert np.allclose(back.T_cam_from_board, truth[60])


def test_low_confidence_frames_do_not_count(truth):
    tracker = PoseTracker(min_confidence=0.5)
    assert tracker.update(_estimate(truth[0], confidence=0.1), 0.0).state == LOST
    assert tracker.update(_estimate(truth[1], confidence=0.9), 0.033).state == TRACKING
    assert tracker.update(_estimate(truth[2], confidence=0.1), 0.066).state == HOLDING


def test_jump_restarts_filter(truth):
    tracker = PoseTracker()
    tracker.update(_estimate(truth[0]), 0.0)
    far = make_transform(truth[0][:3, :3], truth[0][:3, 3] + [0.2, 0, 0])
    out = tracker.update(_estimate(far), 1 / 30)
    assert np.allclose(out.T_cam_from_board, far)
