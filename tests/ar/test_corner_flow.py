"""Tracking between detections (:mod:`ar.corner_flow`) and the rescue pass for dim, small and
blurred boards (:meth:`ar.boards.Board.detect_enhanced`), on synthetic frames with known truth.

The rig's loop must keep the board's pose through frames its detector misses -- blurred,
covered by a hand, dimmed -- within a tolerance of the truth, say so (``found_by``), and
refuse a followed pose when the points drift or the pose jumps; the rescue pass must find
boards the product's detector misses, with an accurate pose."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from ar.boards import DEFAULT_BOARD_SPEC, MARKER_CORNER_ID_BASE, Board, BoardDetection
from ar.corner_flow import CornerFlow, FlowParams, pose_change
from ar.geometry import make_transform, pose_error
from ar.pose import solve_board_pose
from ar.rig import RESCUE_EVERY, RIG_SIZE, RigTracker
from ar.synthetic import Degradation, SyntheticCamera, TrajectoryConfig, default_camera, handheld_trajectory

MISSED = range(10, 20)  # the frames the detector is made to miss


@pytest.fixture(scope="module")
def board():
    return Board(DEFAULT_BOARD_SPEC)


@pytest.fixture(scope="module")
def scene(board):
    camera = default_camera().scaled(*RIG_SIZE)
    return camera, SyntheticCamera(board, camera=camera, supersample=1)


@pytest.fixture(scope="module")
def truth(board):
    return handheld_trajectory(board, 30, TrajectoryConfig(seed=4))


def _clip(scene, truth, missed: Degradation) -> list[np.ndarray]:
    """30 frames; those in MISSED rendered with ``missed`` (the rest clean)."""
    _, cam = scene
    rng = np.random.default_rng(4)
    return [cam.render(T, degradation=missed if i in MISSED else None, rng=rng) for i, T in enumerate(truth)]


def _run(board, camera, frames, **kw):
    rig = RigTracker(board, camera.K, camera.dist, **kw)
    return rig, [rig.step(f, i / 30) for i, f in enumerate(frames)]


@pytest.mark.parametrize("missed", [Degradation(blur_sigma=3.0), Degradation(blur_sigma=3.0, occlusion=0.3)],
                         ids=["blurred", "blurred-and-covered"])
def test_the_pose_is_followed_through_frames_the_detector_misses(board, scene, truth, missed):
    camera, _ = scene
    frames = _clip(scene, truth, missed)
    grey = [cv2.cvtColor(frames[i], cv2.COLOR_BGR2GRAY) for i in MISSED]
    assert all(board.detect(g) is None and board.detect_enhanced(g) is None for g in grey)  # truly missed
    _, states = _run(board, camera, frames)
    found = [s.found_by for s in states]
    assert found[:10] == ["detected"] * 10 and found[20:] == ["detected"] * 10
    assert [found[i] for i in MISSED] == ["followed"] * len(MISSED)
    errors = np.array([pose_error(states[i].estimate.T_cam_from_board, truth[i]) for i in MISSED])
    print(f"\nfollowed pose error, median {np.median(errors, 0)}, max {errors.max(0)} (deg, mm)")
    assert np.median(errors[:, 0]) < 0.5 and np.median(errors[:, 1]) < 1.5
    assert errors[:, 0].max() < 1.5 and errors[:, 1].max() < 4.0
    assert all(states[i].state == "tracking" for i in MISSED)  # the filter takes the followed poses
    assert all(states[i].estimate.rms_px < 1.0 for i in MISSED)


def test_without_following_the_same_frames_are_lost(board, scene, truth):
    camera, _ = scene
    _, states = _run(board, camera, _clip(scene, truth, Degradation(blur_sigma=3.0)), flow=False)
    assert [states[i].found_by for i in MISSED] == ["lost"] * len(MISSED)
    assert all(states[i].estimate is None for i in MISSED)


def test_the_region_search_follows_the_followed_pose(board, scene, truth):
    """After the followed frames, the detector searches around the followed pose (region), not the whole frame."""
    camera, _ = scene
    _, states = _run(board, camera, _clip(scene, truth, Degradation(blur_sigma=3.0)))
    assert states[20].search == "region"


def _anchored(board, scene, truth, params=None) -> CornerFlow:
    camera, cam = scene
    flow = CornerFlow(board, camera.K, camera.dist, params)
    clean = cv2.cvtColor(cam.render(truth[9]), cv2.COLOR_BGR2GRAY)
    estimate = solve_board_pose(board.detect(clean), camera.K, camera.dist)
    flow.anchor(clean, estimate)
    assert flow.active
    return flow


def _blurred(scene, T) -> np.ndarray:
    return cv2.cvtColor(scene[1].render(T, degradation=Degradation(blur_sigma=3.0)), cv2.COLOR_BGR2GRAY)


def test_a_frame_of_something_else_is_refused(board, scene, truth):
    flow = _anchored(board, scene, truth)
    rng = np.random.default_rng(0)
    noise = cv2.GaussianBlur(rng.integers(0, 255, (480, 640), dtype=np.uint8), (0, 0), 2.0)
    assert flow.follow(noise) is None
    assert "points" in flow.last_refusal and not flow.active  # reset: nothing followed until the next detection
    assert flow.follow(_blurred(scene, truth[10])) is None


def test_a_leap_of_the_board_is_refused(board, scene, truth):
    """The board 25 cm away from where it was a frame ago: its corners cannot be followed."""
    flow = _anchored(board, scene, truth)
    leap = truth[10].copy()
    leap[0, 3] += 0.25
    assert flow.follow(_blurred(scene, leap)) is None and flow.last_refusal


def test_a_pose_jump_over_the_limit_is_refused(board, scene, truth):
    """The same small, real motion is followed with the default limits and refused when the
    limit on the rotation between two frames is set under it."""
    assert _anchored(board, scene, truth).follow(_blurred(scene, truth[10])) is not None
    deg, _ = pose_change(truth[9], truth[10])
    strict = _anchored(board, scene, truth, FlowParams(max_jump_deg=deg / 4))
    assert strict.follow(_blurred(scene, truth[10])) is None
    assert "jumped" in strict.last_refusal


def test_following_stops_after_max_frames(board, scene, truth):
    flow = _anchored(board, scene, truth, FlowParams(max_frames=2))
    assert flow.follow(_blurred(scene, truth[10])) is not None
    assert flow.follow(_blurred(scene, truth[11])) is not None
    assert flow.follow(_blurred(scene, truth[12])) is None and "without a detection" in flow.last_refusal


def test_pose_change_measures_the_camera_centre_over_the_board():
    T = make_transform(np.eye(3), np.array([0.0, 0.0, 0.5]))
    turned = make_transform(cv2.Rodrigues(np.array([0.0, np.radians(5.0), 0.0]))[0], np.zeros(3)) @ T
    deg, metres = pose_change(T, turned)  # a turn about the camera: no travel of its centre
    assert abs(deg - 5.0) < 1e-6 and metres < 1e-9
    moved = T.copy()
    moved[0, 3] += 0.02
    assert pose_change(T, moved) == pytest.approx((0.0, 0.02))


# ---------------------------------------------------------------------------- the rescue pass
@pytest.fixture(scope="module")
def dim_small(board):
    """A board 35 cm away at 320x240, exposure 0.08 (a dim corner), a little blur: the
    product's detector finds nothing."""
    camera = default_camera().scaled(320, 240)
    cam = SyntheticCamera(board, camera=camera, supersample=2)
    truth = handheld_trajectory(board, 8, TrajectoryConfig(seed=5, distance_m=0.35))
    rng = np.random.default_rng(1)
    deg = Degradation(exposure=0.08, noise_sigma=2.0, blur_sigma=0.7, shot_noise=0.5)
    frames = [cv2.cvtColor(cam.render(T, degradation=deg, rng=rng), cv2.COLOR_BGR2GRAY) for T in truth]
    return camera, frames, truth


def test_the_rescue_pass_finds_dim_small_boards_the_detector_misses(board, dim_small):
    camera, frames, truth = dim_small
    assert all(board.detect(g) is None for g in frames)
    found = [board.detect_enhanced(g) for g in frames]
    assert sum(f is not None for f in found) >= 6
    errors = []
    for f, T in zip(found, truth):
        if f is not None:
            est = solve_board_pose(f, camera.K, camera.dist)
            assert est is not None and est.rms_px < 2.0
            errors.append(pose_error(est.T_cam_from_board, T))
    errors = np.array(errors)
    print(f"\nrescued pose error, median {np.median(errors, 0)} (deg, mm)")
    assert np.median(errors[:, 0]) < 1.0 and np.median(errors[:, 1]) < 3.0


def test_the_rig_poses_dim_small_boards_through_the_rescue_pass(board, dim_small):
    camera, frames, _ = dim_small
    rig = RigTracker(board, camera.K, camera.dist)
    states = [rig.step(g, i / 30) for i, g in enumerate(frames)]
    assert sum(s.found_by != "lost" for s in states) >= 7
    # found by the rescue pass first, then followed, the rescue pass re-anchoring every RESCUE_EVERY-th frame
    assert states[0].found_by == "detected" and states[0].search == "rescued"
    assert rig.counts["rescued"] >= len(frames) // RESCUE_EVERY


def test_marker_corners_stand_in_where_few_charuco_corners_are_found(board, scene, truth):
    """The markers' corners carry the ChArUco board's own frame: a pose from them alone is the truth's."""
    camera, cam = scene
    gray = cv2.cvtColor(cam.render(truth[0]), cv2.COLOR_BGR2GRAY)
    corners, ids, _ = cv2.aruco.ArucoDetector(board._cv_board.getDictionary()).detectMarkers(gray)
    none = BoardDetection(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, np.int64), len(board.all_object_points))
    found = board._with_marker_corners(none, corners, ids)
    assert found.n == 4 * len(ids) and (found.ids >= MARKER_CORNER_ID_BASE).all()
    est = solve_board_pose(found, camera.K, camera.dist)
    rot_deg, trans_mm = pose_error(est.T_cam_from_board, truth[0])
    assert rot_deg < 0.5 and trans_mm < 3.0


def _shifted(T: np.ndarray, metres: float) -> np.ndarray:
    out = T.copy()
    out[0, 3] += metres
    return out


def test_a_steady_fast_motion_is_followed_from_the_motion_guess(board, scene, truth):
    """The board sliding 3 cm a frame (about a square): the last two detections give the motion,
    and the points are followed from where it puts them."""
    camera, cam = scene
    flow = CornerFlow(board, camera.K, camera.dist)
    for k in (0, 1):
        gray = cv2.cvtColor(cam.render(_shifted(truth[9], 0.03 * k)), cv2.COLOR_BGR2GRAY)
        flow.anchor(gray, solve_board_pose(board.detect(gray), camera.K, camera.dist))
    target = _shifted(truth[9], 0.06)
    est = flow.follow(_blurred(scene, target))
    assert est is not None, flow.last_refusal
    rot_deg, trans_mm = pose_error(est.T_cam_from_board, target)
    assert rot_deg < 0.5 and trans_mm < 2.0


def test_points_far_from_the_motion_guess_are_refused(board, scene, truth):
    """The same 3 cm jump without a motion to expect it: the corners repeat every square, so
    points found that far from the guess may have slipped onto their neighbours -- refused."""
    flow = _anchored(board, scene, truth)
    assert flow.follow(_blurred(scene, _shifted(truth[9], 0.03))) is None
    assert "guess" in flow.last_refusal
