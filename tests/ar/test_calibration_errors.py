"""Every rejection of a calibration file, through the public loaders: the exact message the
teacher sees (the file, then the problem). A rig with a wrong calibration would project
characters off the table, so an implausible file is refused rather than used."""
from __future__ import annotations

import json

import numpy as np
import pytest

from ar.calibration import MAX_CALIBRATION_BYTES, CameraCalibration, ProjectorCalibration, validate_intrinsics
from ar.errors import CalibrationError

K = [[700.0, 0.0, 400.0], [0.0, 700.0, 300.0], [0.0, 0.0, 1.0]]


def _camera(**changes) -> dict:
    data = {"camera_matrix": K, "dist_coeffs": [0.01, -0.02, 0.0, 0.0, 0.0], "image_size": [800, 600], "rms": 0.3}
    data.update(changes)
    return data


def _projector(**changes) -> dict:
    data = {"projector": {"camera_matrix": [[1300.0, 0, 512], [0, 1300.0, 384], [0, 0, 1]],
                          "dist_coeffs": [0.0, 0, 0, 0, 0], "image_size": [1024, 768]},
            "proj_from_cam": {"R": np.eye(3).tolist(), "t": [0.06, 0.0, 0.0]}, "rms": 0.1, "stereo_rms": 0.2}
    data.update(changes)
    return data


def _load_error(tmp_path, loader, data, name="camera.json") -> str:
    path = tmp_path / name
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    with pytest.raises(CalibrationError) as err:
        loader(path)
    assert err.value.path == str(path)
    return str(err.value).removeprefix(f"{path}: ")


def test_the_valid_files_load(tmp_path):
    (tmp_path / "c.json").write_text(json.dumps(_camera()))
    (tmp_path / "p.json").write_text(json.dumps(_projector()))
    assert CameraCalibration.load(tmp_path / "c.json").image_size == (800, 600)
    proj = ProjectorCalibration.load(tmp_path / "p.json")
    assert proj.stereo_rms == 0.2 and proj.image_size == (1024, 768)


@pytest.mark.parametrize(("changes", "problem"), [
    ({"camera_matrix": [[float("inf"), 0, 400], [0, 700, 300], [0, 0, 1]]}, "camera_matrix contains non-finite values"),
    ({"image_size": [0, 600]}, "camera image_size must be positive, got 0x600"),
    ({"image_size": [800, -1]}, "camera image_size must be positive, got 800x-1"),
    ({"camera_matrix": [[5.0, 0, 400], [0, 5.0, 300], [0, 0, 1]]},
     "camera focal lengths fx=5, fy=5 are implausible for a 800x600 image"),
    ({"camera_matrix": [[700.0, 0, 400], [0, 20000.0, 300], [0, 0, 1]]},
     "camera focal lengths fx=700, fy=20000 are implausible for a 800x600 image"),
    ({"camera_matrix": [[700.0, 0, 400], [0, 1500.0, 300], [0, 0, 1]]}, "camera aspect fx/fy=0.466667 is implausible"),
    ({"camera_matrix": [[700.0, 0, 400], [0, 700.0, 9000], [0, 0, 1]]},
     "camera principal point (400, 9000) is far outside the 800x600 image"),
    ({"camera_matrix": [[700.0, 3.0, 400], [0, 700.0, 300], [0, 0, 1]]},
     "camera camera_matrix must look like [[fx,0,cx],[0,fy,cy],[0,0,1]]"),
    ({"camera_matrix": [[700.0, 0, 400], [0, 700.0, 300], [0, 0, 2]]},
     "camera camera_matrix must look like [[fx,0,cx],[0,fy,cy],[0,0,1]]"),
    ({"dist_coeffs": [0.1, 0.2, 0.3]}, "camera dist_coeffs must be 4, 5, 8, 12 or 14 finite numbers, got 3"),
    ({"dist_coeffs": [0.0, 0.0, 0.0, 0.0, 1000.0]},
     "camera dist_coeffs [0.0, 0.0, 0.0, 0.0, 1000.0] are implausibly large"),
    ({"rms": -1.0}, "rms must be >= 0, got -1.0"),
    ({"rms": [1, 2]}, "rms must have shape (), got (2,)"),
    ({"per_view_errors": [1, 2]}, "per_view_errors must be an object, got list"),
    ({"rejected_views": "none"}, "rejected_views must be an object, got str"),
    ({"camera_matrix": [["a", 0, 0], [0, 0, 0], [0, 0, 1]]}, "camera_matrix must be numbers"),
])
def test_camera_file_rejections(tmp_path, changes, problem):
    assert _load_error(tmp_path, CameraCalibration.load, _camera(**changes)) == problem


@pytest.mark.parametrize(("mutate", "problem"), [
    (lambda d: d.pop("proj_from_cam"), "missing object 'proj_from_cam'"),
    (lambda d: d["projector"].update(image_size=[1024, 0]), "projector image_size must be positive, got 1024x0"),
    (lambda d: d["projector"].update(camera_matrix=[[50000.0, 0, 512], [0, 50000.0, 384], [0, 0, 1]]),
     "projector focal lengths fx=50000, fy=50000 are implausible for a 1024x768 image"),
    (lambda d: d["proj_from_cam"].update(R=[[1.0, 0, 0], [0, 1, 0], [0, 0, -1]]), "proj_from_cam.R is not a rotation matrix"),
    (lambda d: d["proj_from_cam"].update(t=[0.0, 3.0, 0.0]),
     "proj_from_cam.t = [0.0, 3.0, 0.0] m puts the projector over 2 m from the camera"),
    (lambda d: d.update(stereo_rms=float("nan")), "stereo_rms contains non-finite values"),
])
def test_projector_file_rejections(tmp_path, mutate, problem):
    data = _projector()
    mutate(data)
    assert _load_error(tmp_path, ProjectorCalibration.load, data, "projector.json") == problem


def test_unusable_files(tmp_path):
    assert _load_error(tmp_path, CameraCalibration.load, "[1, 2, 3]") == "expected a JSON object at top level"
    assert _load_error(tmp_path, CameraCalibration.load, "[" * 100_000) == "not valid JSON (nested too deeply)"
    assert _load_error(tmp_path, CameraCalibration.load, '{"rms": 1,}') == \
        "not valid JSON (line 1: Expecting property name enclosed in double quotes)"
    big = " " * (MAX_CALIBRATION_BYTES + MAX_CALIBRATION_BYTES // 2) + json.dumps(_camera())
    assert _load_error(tmp_path, CameraCalibration.load, big) == \
        "file is 1.5 MB, more than the 1 MB a calibration file can be"
    path = tmp_path / "latin1.json"
    path.write_bytes(b'{"board": "\xe9"}')
    with pytest.raises(CalibrationError) as err:
        CameraCalibration.load(path)
    assert str(err.value).startswith(f"{path}: cannot read: 'utf-8' codec can't decode byte 0xe9")
    folder = tmp_path / "camera_dir.json"
    folder.mkdir()
    with pytest.raises(CalibrationError) as err:
        CameraCalibration.load(folder)
    assert str(err.value) == f"{folder}: cannot read: [Errno 21] Is a directory: '{folder}'"


def test_validate_intrinsics_refuses_a_non_finite_or_misshapen_matrix():
    for bad in (np.full((3, 3), np.nan), np.eye(2)):
        with pytest.raises(CalibrationError) as err:
            validate_intrinsics(bad, np.zeros(5), (800, 600), what="projector")
        assert str(err.value) == "projector camera_matrix must be a finite 3x3 matrix"
        assert err.value.path is None
