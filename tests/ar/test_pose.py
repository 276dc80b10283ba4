"""Pose accuracy on synthetic frames, and refusal of partial checkerboard views."""
from __future__ import annotations

import numpy as np
import pytest

from ar.boards import DEFAULT_BOARD_SPEC, Board
from ar.geometry import invert, look_at, pose_error, project_points
from ar.pose import estimate_board_pose
from ar.synthetic import Degradation, SyntheticCamera, TrajectoryConfig, handheld_trajectory


@pytest.fixture(scope="module")
def charuco_cam():
    return SyntheticCamera(Board(DEFAULT_BOARD_SPEC))


@pytest.fixture(scope="module")
def checker_cam():
    return SyntheticCamera(Board("checker:9x6:0.025"))


def _errors(cam, poses, degradation=None):
    rng = np.random.default_rng(3)
    errs, found = [], 0
    for T in poses:
        est = estimate_board_pose(cam.render(T, degradation=degradation, rng=rng), cam.board, cam.camera.K, cam.camera.dist)
        if est is not None:
            found += 1
            errs.append(pose_error(est.T_cam_from_board, T))
    return found, np.array(errs).reshape(-1, 2)


def test_clean_frames_at_half_a_metre_meet_accuracy_targets(charuco_cam):
    poses = handheld_trajectory(charuco_cam.board, 12, TrajectoryConfig(distance_m=0.5, seed=5))
    found, errs = _errors(charuco_cam, poses)
    assert found == len(poses)
    rot_med, trans_med = np.median(errs, 0)
    assert rot_med <= 0.2
    assert trans_med <= 1.0


def test_pose_is_not_trivially_the_truth(charuco_cam):
    """Sanity for the test bench itself: a wrong intrinsic must show up as pose error."""
    T = handheld_trajectory(charuco_cam.board, 1)[0]
    img = charuco_cam.render(T)
    K_wrong = charuco_cam.camera.K.copy()
    K_wrong[0, 0] *= 1.05
    K_wrong[1, 1] *= 1.05
    est = estimate_board_pose(img, charuco_cam.board, K_wrong, charuco_cam.camera.dist)
    assert pose_error(est.T_cam_from_board, T)[1] > 5.0


def test_confidence_drops_under_occlusion(charuco_cam):
    T = handheld_trajectory(charuco_cam.board, 1)[0]
    clean = estimate_board_pose(charuco_cam.render(T), charuco_cam.board, charuco_cam.camera.K, charuco_cam.camera.dist)
    occluded = estimate_board_pose(charuco_cam.render(T, degradation=Degradation(occlusion=0.45),
                                                       rng=np.random.default_rng(1)),
                                   charuco_cam.board, charuco_cam.camera.K, charuco_cam.camera.dist)
    assert occluded is None or occluded.confidence < clean.confidence
    assert clean.covariance.shape == (6, 6) and np.all(np.linalg.eigvalsh(clean.covariance) > 0)


def test_checkerboard_full_view_is_posed(checker_cam):
    poses = handheld_trajectory(checker_cam.board, 4, TrajectoryConfig(seed=2))
    found, errs = _errors(checker_cam, poses)
    assert found == 4
    assert np.median(errs[:, 0]) < 0.2 and np.median(errs[:, 1]) < 1.0


def test_checkerboard_partial_view_is_rejected_not_misposed(checker_cam):
    """Part of the checkerboard outside the frame: no IDs, so no pose at all."""
    board = checker_cam.board
    c = board.centre
    # look at the board's right edge from 0.35 m: the left part is out of the frame
    target = c + np.array([board.pattern_size_m[0] * 0.5, 0.0, 0.0])
    T = look_at(target + np.array([0.0, 0.05, -0.35]), target, np.array([0.0, -1.0, 0.0]))
    px = project_points(board.all_object_points, T, checker_cam.camera.K, checker_cam.camera.dist)
    inside = np.mean((px[:, 0] >= 0) & (px[:, 0] < 800) & (px[:, 1] >= 0) & (px[:, 1] < 600))
    assert 0.3 < inside < 0.9  # really a partial view
    img = checker_cam.render(T)
    assert estimate_board_pose(img, board, checker_cam.camera.K, checker_cam.camera.dist) is None
    # occluded by a hand: also rejected
    T_full = handheld_trajectory(board, 1)[0]
    occluded = checker_cam.render(T_full, degradation=Degradation(occlusion=0.3), rng=np.random.default_rng(0))
    assert estimate_board_pose(occluded, board, checker_cam.camera.K, checker_cam.camera.dist) is None


def test_grid_board_pose():
    cam = SyntheticCamera(Board("grid:4x5:0.04:0.01:DICT_4X4_50"), supersample=1)
    poses = handheld_trajectory(cam.board, 3, TrajectoryConfig(seed=4))
    found, errs = _errors(cam, poses)
    assert found == 3 and np.median(errs[:, 0]) < 0.3 and np.median(errs[:, 1]) < 1.5


def test_trajectory_is_smooth_with_tremor():
    board = Board(DEFAULT_BOARD_SPEC)
    poses = handheld_trajectory(board, 60, TrajectoryConfig(distance_m=0.5))
    centres = np.array([invert(T)[:3, 3] for T in poses])
    dist = np.linalg.norm(centres - board.centre, axis=1)
    assert np.all(np.abs(dist - 0.5) < 0.05)  # hovers at the requested distance
    steps = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    assert steps.max() < 0.01 and steps.min() > 0  # moves, but never jumps
