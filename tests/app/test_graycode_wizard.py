"""The teacher's calibration wizard in Gray-code mode (issue 28), with the synthetic rig
as the camera: the wizard shows the sequence through the projector window's callback,
captures each image through the camera source and calibrates; the result is checked
against the rig's truth."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytestmark = pytest.mark.slow  # 4 poses x 42 rendered captures, then a calibration and a scan (~25 s)


def test_graycode_wizard_calibrates_the_synthetic_rig(tmp_path):
    pytest.importorskip("cv2")
    from app.services.calibration_wizard import GrayCodeWizard
    from ar import DEFAULT_BOARD_SPEC, Board, SyntheticCamera
    from ar.geometry import rotation_angle_deg
    from ar.structured_light.synthetic import GrayCodeScene, ProjectedSceneSource, graycode_poses
    from ar.synthetic import default_projector

    board = Board(DEFAULT_BOARD_SPEC)
    projector = default_projector()  # 1024 x 768: 42 images a pose
    cam = SyntheticCamera(board, projector=projector)
    source = ProjectedSceneSource(GrayCodeScene(cam), graycode_poses(board, cam.proj_from_cam, 4))
    wizard = GrayCodeWizard(tmp_path, show=source.show, camera=source, projector_size=projector.size, n_poses=4,
                            settle_frames=0, settle_s=0.0, before_pose=lambda i: setattr(source, "pose_index", i))
    assert [s.key for s in wizard.steps] == ["board", "graycode_pose_1", "graycode_pose_2", "graycode_pose_3",
                                             "graycode_pose_4", "solve", "save", "scan"]
    while not wizard.done:
        step = wizard.run_next()
        assert step.error is None, f"{step.key}: {step.error}"
    assert source.shown_count == 5 * 43  # the whole sequence per pose and for the scan, then black
    data = json.loads((tmp_path / "projector.json").read_text())
    assert (tmp_path / "camera.json").is_file()
    from ar import HEIGHT_MAP_FILE, HeightMap
    table = HeightMap.load(tmp_path / HEIGHT_MAP_FILE)  # the table scanned at the last pose: the bare board
    assert table.known_fraction > 0.2 and np.median(np.abs(table.heights[table.known])) < 0.001
    K = np.array(data["projector"]["camera_matrix"])
    assert abs(K[0, 0] / projector.K[0, 0] - 1) < 0.01
    assert np.linalg.norm(np.array(data["T"]) - cam.proj_from_cam[:3, 3]) < 0.002
    assert rotation_angle_deg(np.array(data["R"]) @ cam.proj_from_cam[:3, :3].T) < 0.1


def test_graycode_wizard_keeps_the_error_when_the_board_is_out_of_view(tmp_path):
    pytest.importorskip("cv2")
    from app.services.calibration_wizard import GrayCodeWizard
    from ar import DEFAULT_BOARD_SPEC, Board, SyntheticCamera
    from ar.geometry import look_at
    from ar.structured_light.synthetic import GrayCodeScene, ProjectedSceneSource
    from ar.synthetic import default_projector

    board = Board(DEFAULT_BOARD_SPEC)
    projector = default_projector().scaled(64, 48)
    cam = SyntheticCamera(board, camera=cam_model_small(), projector=projector, supersample=1)
    away = look_at(np.array([2.0, 2.0, -0.5]), np.array([2.0, 2.0, 0.0]), np.array([-1.0, 0.0, 0.0]))
    source = ProjectedSceneSource(GrayCodeScene(cam), [away])
    wizard = GrayCodeWizard(tmp_path, show=source.show, camera=source, projector_size=projector.size, n_poses=3,
                            settle_frames=0, settle_s=0.0)
    assert wizard.run_next().error is None
    step = wizard.run_next()
    assert "board is not in view" in step.error and wizard.current == 1  # the teacher can retry this pose
    no_rig = GrayCodeWizard(tmp_path, n_poses=3)
    no_rig.run_next()
    assert "projector window and the camera" in no_rig.run_next().error


def cam_model_small():
    from ar.synthetic import default_camera
    return default_camera().scaled(160, 120)


def test_the_teacher_screen_runs_the_gray_code_wizard_on_a_real_rig(tmp_path):
    """A rig whose camera is a device and whose projector window opens gets the Gray-code
    wizard, showing on that window and filming through that camera; any other set-up the
    camera-only wizard (there is no light to project with)."""
    from types import SimpleNamespace

    from app.services import CalibrationWizard, GrayCodeWizard
    from app.ui.teacher import calibration_wizard

    shown, opened = [], []
    window = SimpleNamespace(display=(1920, 0, 1280, 800), show=shown.append)

    def app_with(camera, window):
        return SimpleNamespace(renderer_factory=SimpleNamespace(camera=camera), profile_dir=tmp_path,
                               open_projector_window=lambda: window)

    wizard = calibration_wizard(app_with("0", window), open_source=lambda choice: opened.append(choice) or "cam")
    assert isinstance(wizard, GrayCodeWizard) and wizard.projector_size == (1280, 800)
    assert wizard.show == shown.append and wizard.camera == "cam" and opened == ["0"]
    for camera, win in (("0", None), ("kivy:1", window), ("session.mp4", window)):
        plain = calibration_wizard(app_with(camera, win), open_source=lambda c: pytest.fail("no camera to open"))
        assert type(plain) is CalibrationWizard
