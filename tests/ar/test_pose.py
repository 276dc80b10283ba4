"""Pose accuracy on synthetic frames, and refusal of partial checkerboard views."""
from __future__ import annotations

import numpy as np
import pytest

from ar.boards import DEFAULT_BOARD_SPEC, Board
from ar.geometry import invert, look_at, pose_error, project_points
from ar.pose import RegionPoseEstimator, estimate_board_pose
from ar.synthetic import Degradation, SyntheticCamera, TrajectoryConfig, default_camera, handheld_trajectory


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


# ---------------------------------------------------------------- region search (issue 13)
def test_region_search_gives_the_full_frame_poses_and_uses_the_region():
    """Frame after frame, the region predicted from the last pose yields the same pose as a
    search of the whole frame (same detector on a crop), and the region path is really taken."""
    board = Board(DEFAULT_BOARD_SPEC)
    camera = default_camera().scaled(640, 480)
    cam = SyntheticCamera(board, camera=camera, supersample=1)
    poses = handheld_trajectory(board, 12, TrajectoryConfig(distance_m=0.5, seed=8))
    region = RegionPoseEstimator(board, camera.K, camera.dist)
    rng = np.random.default_rng(1)
    for T in poses:
        frame = cam.render(T, rng=rng)
        full = estimate_board_pose(frame, board, camera.K, camera.dist)
        fast = region.estimate(frame)
        assert full is not None and fast is not None
        np.testing.assert_allclose(fast.T_cam_from_board, full.T_cam_from_board, atol=1e-6)
    assert region.counts == {"region": 11, "full": 1, "fallback": 0, "rescued": 0, "lost": 0}


def test_region_search_falls_back_to_the_whole_frame():
    """A board that jumps out of the predicted region is still found (the whole frame is
    searched in the same call); after frames without it, the search starts whole."""
    board = Board(DEFAULT_BOARD_SPEC)
    camera = default_camera().scaled(640, 480)
    cam = SyntheticCamera(board, camera=camera, supersample=1)
    T = handheld_trajectory(board, 1, TrajectoryConfig(distance_m=0.9, seed=2))[0]
    moved = T.copy()
    moved[0, 3] += 0.25  # 25 cm sideways between two frames: beyond the region
    region = RegionPoseEstimator(board, camera.K, camera.dist)
    assert region.estimate(cam.render(T)) is not None
    box, scale = region.predicted_region((640, 480))
    assert scale == 1 and (box[2] - box[0]) * (box[3] - box[1]) < 0.6 * 640 * 480
    est = region.estimate(cam.render(moved))
    assert est is not None and pose_error(est.T_cam_from_board, moved)[1] < 2.0
    assert region.counts["fallback"] == 1
    blank = np.zeros((480, 640, 3), np.uint8)
    for _ in range(3):
        assert region.estimate(blank) is None
    assert region.predicted_region((640, 480)) is None  # too long without the board: search whole
    assert region.estimate(cam.render(T)) is not None
    assert region.counts == {"region": 0, "full": 2, "fallback": 1, "rescued": 0, "lost": 3}


def test_region_scale_grows_with_marker_size():
    board = Board(DEFAULT_BOARD_SPEC)
    camera = default_camera()
    cam = SyntheticCamera(board, camera=camera, supersample=1)
    scales = []
    for d in (0.6, 0.2):
        region = RegionPoseEstimator(board, camera.K, camera.dist)
        region.estimate(cam.render(handheld_trajectory(board, 1, TrajectoryConfig(distance_m=d, seed=2))[0]))
        scales.append(region.predicted_region(camera.size)[1])
    assert scales == [1, 2]
