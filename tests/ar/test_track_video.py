"""``storybeam track`` (:mod:`ar.track_video`): the rig's loop on a recording, per frame the pose
and how it was found, the summary, the assumed camera, and the errors a user meets."""
from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from app.cli import main
from ar.boards import DEFAULT_BOARD_SPEC, Board
from ar.calibration import CameraCalibration
from ar.camera_sources import CameraSourceError, FrameListSource
from ar.geometry import pose_error
from ar.synthetic import Degradation, SyntheticCamera, TrajectoryConfig, default_camera, handheld_trajectory
from ar.track_video import DEFAULT_HFOV_DEG, default_camera_for, plain_detector, summarise, track_recording

BLURRED = (4, 5, 6)


@pytest.fixture(scope="module")
def clip():
    """12 frames at 320x240, frames 4-6 blurred past detection; the camera and the true poses."""
    board = Board(DEFAULT_BOARD_SPEC)
    camera = default_camera().scaled(320, 240)
    cam = SyntheticCamera(board, camera=camera, supersample=2)
    truth = handheld_trajectory(board, 12, TrajectoryConfig(seed=6, distance_m=0.45))
    rng = np.random.default_rng(6)
    frames = [cam.render(T, degradation=Degradation(blur_sigma=2.5) if i in BLURRED else None, rng=rng)
              for i, T in enumerate(truth)]
    return board, camera, frames, truth


def test_the_default_camera_assumes_a_phone_lens():
    cam = default_camera_for(320, 180)
    hfov = math.degrees(2 * math.atan(160 / cam.K[0, 0]))
    assert hfov == pytest.approx(DEFAULT_HFOV_DEG)
    assert cam.K[0, 0] == cam.K[1, 1] and (cam.K[0, 2], cam.K[1, 2]) == (159.5, 89.5)
    assert not cam.dist.any()
    upright = default_camera_for(180, 320)  # a phone held upright: the lens's field spans the long side
    assert upright.K[0, 0] == pytest.approx(cam.K[0, 0])


def test_track_recording_reports_every_frame_and_the_summary(clip):
    board, camera, frames, truth = clip
    calibration = CameraCalibration(camera.K, camera.dist, camera.size, 0.0)
    report = track_recording(FrameListSource(frames), board, calibration, plain=True)
    rows = report["frames"]
    assert [r["index"] for r in rows] == list(range(12))
    assert [rows[i]["found_by"] for i in BLURRED] == ["followed"] * 3
    # this small board is found by the rescue pass, which waits while the corners can be followed
    assert all(r["found_by"] in ("detected", "followed") for r in rows) and rows[0]["found_by"] == "detected"
    assert all(rows[i]["plain_points"] == 0 for i in BLURRED)  # the plain detector misses them too
    s = report["summary"]
    assert s["frames"] == 12 and s["pose_rate"] == 1.0 and s["lost_rate"] == 0.0
    assert s["detected_rate"] + s["followed_rate"] == pytest.approx(1.0) and s["detected_rate"] >= 3 / 12
    assert 3 <= s["longest_followed_run"] <= 3 + 2
    assert s["plain_rate"] <= s["detected_rate"]  # OpenCV's defaults find fewer small boards than the rig
    assert 0 < s["reproj_px_median"] < 0.5 and s["ms_median"] > 0
    assert report["camera"]["assumed"] is False
    for r, T in zip(rows, truth):  # the reported pose is the board's
        R = cv2.Rodrigues(np.array(r["rvec"]))[0]
        est = np.eye(4)
        est[:3, :3], est[:3, 3] = R, r["tvec_m"]
        rot_deg, trans_mm = pose_error(est, T)
        assert rot_deg < 1.0 and trans_mm < 5.0  # 320x240 at 45 cm, blurred frames among them


def test_summary_counts_held_frames_as_without_a_pose():
    rows = [{"found_by": k, "reproj_px": None if k == "lost" else 0.3, "ms": 2.0}
            for k in ("detected", "followed", "lost", "lost")]
    s = summarise(rows)
    assert s["pose_rate"] == 0.5 and s["lost_rate"] == 0.5 and s["reproj_px_median"] == pytest.approx(0.3)


def test_an_uncalibrated_recording_uses_the_assumed_camera(clip):
    board, _, frames, _ = clip
    report = track_recording(FrameListSource(frames[:3]), board)
    assert report["camera"]["assumed"] and report["camera"]["size"] == [320, 240]
    assert report["summary"]["detected_rate"] == 1.0


def test_an_empty_recording_is_an_error_naming_it():
    with pytest.raises(CameraSourceError, match="<frames>"):
        track_recording(FrameListSource([]), Board(DEFAULT_BOARD_SPEC))


def test_the_plain_detector_counts_points():
    board = Board("checker:9x6:0.025")
    cam = SyntheticCamera(board, camera=default_camera().scaled(640, 480), supersample=1)
    T = handheld_trajectory(board, 1, TrajectoryConfig(seed=1, distance_m=0.5))[0]
    gray = cv2.cvtColor(cam.render(T), cv2.COLOR_BGR2GRAY)
    assert plain_detector(board)(gray) == 54 and plain_detector(board)(np.zeros_like(gray)) == 0


def test_the_track_command(clip, tmp_path, capsys):
    board, camera, frames, _ = clip
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / f"f{i:03d}.png"), f)
    CameraCalibration(camera.K, camera.dist, camera.size, 0.0).save(tmp_path / "camera.json")
    out = tmp_path / "track.json"
    assert main(["track", "--video", str(folder), "--board", DEFAULT_BOARD_SPEC, "--camera",
                 str(tmp_path / "camera.json"), "--json", str(out), "--compare-plain"]) == 0
    printed = capsys.readouterr().out
    assert "pose (detected + followed)" in printed and "100.0 %" in printed and "plain OpenCV detector" in printed
    report = json.loads(out.read_text())
    assert len(report["frames"]) == 12 and report["summary"]["pose_rate"] == 1.0
    assert main(["track", "--video", str(folder), "--board", DEFAULT_BOARD_SPEC, "--limit", "2"]) == 0
    assert "camera assumed" in capsys.readouterr().out
    assert main(["track", "--video", str(folder), "--board", DEFAULT_BOARD_SPEC, "--camera", str(tmp_path / "camera.json"),
                 "--no-follow", "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert not report["follow"] and report["summary"]["lost_rate"] == pytest.approx(0.25)


def test_the_track_command_names_what_is_wrong(tmp_path, capsys):
    missing = tmp_path / "nope.mp4"
    assert main(["track", "--video", str(missing), "--board", DEFAULT_BOARD_SPEC]) == 1
    assert str(missing) in capsys.readouterr().err
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(b"not a video at all")
    assert main(["track", "--video", str(broken), "--board", DEFAULT_BOARD_SPEC]) == 1
    err = capsys.readouterr().err
    assert str(broken) in err and "not a video" in err
    assert main(["track", "--video", str(broken), "--board", "charuco:5x7"]) == 1
    assert "expected 5" in capsys.readouterr().err
