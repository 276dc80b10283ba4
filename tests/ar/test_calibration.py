"""Camera and projector calibration recover the synthetic rig; calibration files are validated."""
from __future__ import annotations

import json

import numpy as np
import pytest

from ar.boards import DEFAULT_BOARD_SPEC, Board
from ar.calibration import (CameraCalibration, ProjectorCalibration, ProjectorCalibrationSequence, calibrate_camera,
                            calibrate_from_correspondences, calibrate_projector_from_folder, extrinsics_error,
                            write_capture)
from ar.errors import CalibrationError
from ar.synthetic import SyntheticCamera, calibration_poses, capture_projector_sequence
from retrieval.errors import StoryBeamError


@pytest.fixture(scope="module")
def rig():
    return SyntheticCamera(Board(DEFAULT_BOARD_SPEC))


@pytest.fixture(scope="module")
def camera_calib(rig):
    views = [(f"v{i:02d}", rig.render(T)) for i, T in enumerate(calibration_poses(rig.board, 10))]
    blank = np.full_like(views[0][1], 90)
    return calibrate_camera(views + [("blank.png", blank)], rig.board)


def test_camera_calibration_recovers_intrinsics(rig, camera_calib):
    K_true = rig.camera.K
    K = camera_calib.camera_matrix
    assert abs(K[0, 0] / K_true[0, 0] - 1) < 0.005
    assert abs(K[1, 1] / K_true[1, 1] - 1) < 0.005
    assert abs(K[0, 2] - K_true[0, 2]) < 3 and abs(K[1, 2] - K_true[1, 2]) < 3
    assert camera_calib.rms < 0.3
    assert camera_calib.rejected_views == {"blank.png": "board not detected"}
    assert len(camera_calib.per_view_errors) == 10


def test_bad_view_is_rejected(rig):
    """A view whose points were matched wrongly fits badly and is dropped."""
    board = rig.board
    rng = np.random.default_rng(0)
    names, obj, img = [], [], []
    for i, T in enumerate(calibration_poses(board, 8, seed=3)):
        det = board.detect(rig.render(T))
        names.append(f"v{i}")
        obj.append(det.object_points)
        img.append(det.image_points)
    img[2] = img[2] + rng.normal(0, 4.0, img[2].shape)
    _rms, _K, _d, errors, rejected, keep = calibrate_from_correspondences(names, obj, img, rig.camera.size)
    assert list(rejected) == ["v2"] and 2 not in keep and "v2" not in errors


def test_too_few_views_is_a_clear_error(rig):
    with pytest.raises(CalibrationError, match="at least 3 usable views"):
        calibrate_camera([("a.png", np.zeros((600, 800, 3), np.uint8))], rig.board)


def test_projector_calibration_recovers_extrinsics(rig, camera_calib, tmp_path):
    sequence = ProjectorCalibrationSequence(rig.board)
    steps = list(sequence)
    assert len(steps) == 8 and all("Step" in s.instruction for s in steps)
    captures = capture_projector_sequence(rig, sequence)
    write_capture(tmp_path, [(s, frames, pattern) for s, _T, pattern, frames in captures], rig.projector.size)
    calib = calibrate_projector_from_folder(tmp_path, rig.board, camera_calib)
    rot_deg, trans_mm = extrinsics_error(calib, rig.proj_from_cam)
    assert rot_deg <= 0.3 and trans_mm <= 2.0
    assert abs(calib.camera_matrix[0, 0] / rig.projector.K[0, 0] - 1) < 0.01
    # and it survives a save/load round trip
    path = calib.save(tmp_path / "projector.json")
    loaded = ProjectorCalibration.load(path)
    assert np.allclose(loaded.T_proj_from_cam, calib.T_proj_from_cam)


def _camera_dict():
    return {"camera_matrix": [[700.0, 0, 400], [0, 700.0, 300], [0, 0, 1]], "dist_coeffs": [0.0, 0, 0, 0, 0],
            "image_size": [800, 600], "rms": 0.1}


def test_camera_file_round_trip(tmp_path, camera_calib):
    path = camera_calib.save(tmp_path / "camera.json")
    data = json.loads(path.read_text())
    assert {"camera_matrix", "dist_coeffs", "image_size", "rms"} <= set(data)
    loaded = CameraCalibration.load(path)
    assert np.allclose(loaded.camera_matrix, camera_calib.camera_matrix)
    assert loaded.image_size == camera_calib.image_size


@pytest.mark.parametrize("mutate, fragment", [
    (lambda d: d.pop("camera_matrix"), "missing key 'camera_matrix'"),
    (lambda d: d.update(camera_matrix=[[700.0, 0, 400], [0, 700.0, 300]]), r"shape \(3, 3\)"),
    (lambda d: d.update(dist_coeffs=[float("nan"), 0, 0, 0, 0]), "non-finite"),
    (lambda d: d.update(camera_matrix=[[5.0, 0, 400], [0, 5.0, 300], [0, 0, 1]]), "implausible"),
    (lambda d: d.update(camera_matrix=[[700.0, 0, 9000], [0, 700.0, 300], [0, 0, 1]]), "principal point"),
    (lambda d: d.update(dist_coeffs=[0.1, 0.2, 0.3]), "4, 5, 8, 12 or 14"),
    (lambda d: d.update(image_size=[800]), r"shape \(2,\)"),
    (lambda d: d.update(rms="abc"), "must be numbers"),
])
def test_camera_file_validation_names_file_and_problem(tmp_path, mutate, fragment):
    data = _camera_dict()
    mutate(data)
    path = tmp_path / "cam_bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalibrationError, match=fragment) as info:
        CameraCalibration.load(path)
    assert str(path) in str(info.value)
    assert isinstance(info.value, StoryBeamError)


def test_unreadable_files(tmp_path):
    with pytest.raises(CalibrationError, match="file not found"):
        CameraCalibration.load(tmp_path / "missing.json")
    bad = tmp_path / "broken.json"
    bad.write_text("{not json")
    with pytest.raises(CalibrationError, match="not valid JSON") as info:
        CameraCalibration.load(bad)
    assert "broken.json" in str(info.value)


def test_projector_file_validation(tmp_path):
    good = {"projector": {"camera_matrix": [[1300.0, 0, 512], [0, 1300.0, 384], [0, 0, 1]],
                          "dist_coeffs": [0.0, 0, 0, 0, 0], "image_size": [1024, 768]},
            "proj_from_cam": {"R": np.eye(3).tolist(), "t": [0.06, 0.0, 0.0]}, "rms": 0.1}
    path = tmp_path / "projector.json"
    path.write_text(json.dumps(good))
    assert ProjectorCalibration.load(path).t_proj_from_cam[0] == pytest.approx(0.06)
    bad_R = json.loads(json.dumps(good))
    bad_R["proj_from_cam"]["R"] = [[2.0, 0, 0], [0, 1, 0], [0, 0, 1]]
    path.write_text(json.dumps(bad_R))
    with pytest.raises(CalibrationError, match="not a rotation") as info:
        ProjectorCalibration.load(path)
    assert "projector.json" in str(info.value)
    far = json.loads(json.dumps(good))
    far["proj_from_cam"]["t"] = [5.0, 0, 0]
    path.write_text(json.dumps(far))
    with pytest.raises(CalibrationError, match="over 2 m"):
        ProjectorCalibration.load(path)
    path.write_text(json.dumps({"rms": 0.1}))
    with pytest.raises(CalibrationError, match="missing object 'projector'"):
        ProjectorCalibration.load(path)
