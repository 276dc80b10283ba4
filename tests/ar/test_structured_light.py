"""Gray-code structured light (issue 28): the sequence, decoding (against OpenCV's own
per-pixel decoder), local homographies, sub-pixel codes, triangulation, files and errors.
The end-to-end checks against the synthetic rig's truth, through the commands, are in
tests/ar/test_structured_light_e2e.py."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from ar import Board, CalibrationError, DEFAULT_BOARD_SPEC, ProjectorCalibration, SyntheticCamera
from ar.calibration import CameraCalibration
from ar.structured_light.calibrate import GrayCodeCalibration, local_homography_corners
from ar.structured_light.decode import DecodedPose, decode_images, decode_pose_folder, pose_folders
from ar.structured_light.patterns import GrayCodeLayout, graycode_sequence, parse_projector_size
from ar.structured_light.scan import fit_plane, subpixel_codes, triangulate, write_ply
from ar.structured_light.synthetic import Box, GrayCodeScene, graycode_poses
from ar.synthetic import default_camera, default_projector

SMALL_PROJECTOR = (100, 60)  # 7 + 6 bits: a fast sequence of 28 images


def test_sequence_is_opencv_patterns_then_white_then_black():
    seq = graycode_sequence((800, 600))
    layout = GrayCodeLayout(800, 600)
    assert (layout.col_bits, layout.row_bits, layout.n_images) == (10, 10, 42)
    assert len(seq) == 42 and seq[0].shape == (600, 800)
    ok, ref = cv2.structured_light.GrayCodePattern.create(800, 600).generate()
    assert ok and all(np.array_equal(a, b) for a, b in zip(seq, ref))
    assert seq[layout.white_index].min() == 255 and seq[layout.black_index].max() == 0
    assert parse_projector_size("1024X768") == (1024, 768)
    for bad in ("1024", "ax768", "1x768"):
        with pytest.raises(CalibrationError, match="projector size"):
            parse_projector_size(bad)


@pytest.mark.parametrize("size", [(1024, 768), (100, 60)])
def test_decoding_the_patterns_themselves_is_the_identity(size):
    """A camera that *is* the projector decodes every pixel to itself (odd sizes too)."""
    seq = graycode_sequence(size)
    seq[-1] = np.full_like(seq[-1], 10)  # a black level below the white, as a camera sees it
    d = decode_images(seq, size)
    ys, xs = np.mgrid[0:size[1], 0:size[0]]
    assert d.mask.all() and np.array_equal(d.col, xs) and np.array_equal(d.row, ys)


@pytest.fixture(scope="module")
def small_capture():
    """A small synthetic rig (200x150 camera, 100x60 projector, a box) and one pose's captures."""
    board = Board(DEFAULT_BOARD_SPEC)
    camera = default_camera().scaled(320, 240)
    projector = default_projector().scaled(*SMALL_PROJECTOR)
    cam = SyntheticCamera(board, camera=camera, projector=projector, supersample=1)
    box = Box(0.05, 0.05, 0.12, 0.12, 0.04)
    scene = GrayCodeScene(cam, [box])
    T = graycode_poses(board, cam.proj_from_cam, 1)[0]
    return cam, scene, T, scene.capture_graycode(T)


def test_vectorised_decoding_matches_opencv_get_proj_pixel(small_capture):
    _cam, _scene, _T, frames = small_capture
    grey = [cv2.cvtColor(f, cv2.COLOR_BGR2GRAY) for f in frames]
    d = decode_images(grey, SMALL_PROJECTOR)
    assert 0.1 < d.mask.mean() < 0.9  # light and shadow, decoded and not
    gc = cv2.structured_light.GrayCodePattern.create(*SMALL_PROJECTOR)
    gc.setWhiteThreshold(5)
    patterns = grey[:-2]
    rng = np.random.default_rng(0)
    lit = np.argwhere(d.lit)
    checked = 0
    for y, x in lit[rng.choice(len(lit), 400, replace=False)]:
        err, (px, py) = gc.getProjPixel(patterns, int(x), int(y))
        assert (not err) == bool(d.mask[y, x]), (x, y)
        if not err:
            assert (px, py) == (d.col[y, x], d.row[y, x])
            checked += 1
    assert checked > 100


def test_shadows_of_a_box_are_not_decoded(small_capture):
    cam, scene, T, frames = small_capture
    surf = scene.surface(T)
    assert (~surf["lit"] & surf["valid"]).sum() > 10  # the box casts a shadow the camera sees
    d = decode_images(frames, SMALL_PROJECTOR)
    unlit = ~surf["lit"]  # supersample 1: one surface sample per camera pixel
    assert not (d.mask & unlit).any()
    truth = scene.height_truth(T)
    assert np.nanmax(truth) == pytest.approx(0.04)


def _homography_decoded(H: np.ndarray, shape=(120, 160)) -> DecodedPose:
    ys, xs = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    p = H @ np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    col = np.floor(p[0] / p[2] + 0.5).reshape(shape).astype(np.int32)  # whole projector pixels, as decoded
    row = np.floor(p[1] / p[2] + 0.5).reshape(shape).astype(np.int32)
    mask = np.ones(shape, bool)
    mask[:, ::5] = False  # holes, as the finest stripes leave
    grey = np.zeros(shape, np.uint8)
    return DecodedPose("h", col, row, mask, grey, grey, np.ones(shape, bool))


def test_local_homography_recovers_a_corner_to_a_fraction_of_a_pixel():
    H = np.array([[1.8, 0.12, 20.0], [-0.05, 1.7, 15.0], [1e-4, 2e-4, 1.0]])
    d = _homography_decoded(H)
    corners = np.array([[40.3, 50.7], [100.5, 60.25], [80.0, 90.9]])
    proj, ok = local_homography_corners(d, corners, window=20)
    truth = cv2.perspectiveTransform(corners.reshape(-1, 1, 2), H).reshape(-1, 2)
    assert ok.all()
    assert np.abs(proj - truth).max() < 0.05  # each code is only a whole pixel; the fit is 20x finer
    proj, ok = local_homography_corners(d, np.array([[2.0, 2.0], [500.0, 500.0]]), window=3)
    assert not ok.any()  # too few decoded pixels around / outside the image


def test_subpixel_codes_are_finer_than_whole_pixels_and_drop_depth_edges():
    H = np.array([[1.8, 0.1, 20.0], [0.0, 1.7, 15.0], [0.0, 0.0, 1.0]])
    d = _homography_decoded(H)
    d.col[:, 80:] += 9  # a depth edge: codes jump between columns 79 and 80
    col, row, mask = subpixel_codes(d, 7)
    ys, xs = np.mgrid[0:120, 0:160].astype(np.float64)
    true_col = 1.8 * xs + 0.1 * ys + 20.0 + 9 * (xs >= 80)
    inner = mask.copy()
    inner[:4], inner[-4:], inner[:, :4], inner[:, -4:] = False, False, False, False
    err = np.abs(col - true_col)[inner]
    raw = np.abs(d.col - true_col)[d.mask]
    assert np.sqrt(np.mean(err ** 2)) < 0.5 * np.sqrt(np.mean(raw ** 2))
    assert not mask[:, 78:82].any()  # windows across the edge are left out
    assert mask[:, 60:70].all()


def _truth_calibration(cam: SyntheticCamera) -> GrayCodeCalibration:
    T = cam.proj_from_cam
    camera = CameraCalibration(cam.camera.K, cam.camera.dist, cam.camera.size, 0.1)
    projector = ProjectorCalibration(cam.projector.K, cam.projector.dist, cam.projector.size, T[:3, :3], T[:3, 3], 0.1)
    return GrayCodeCalibration(camera, projector, {"p": {"camera_px": 0.1, "projector_px": 0.1, "corners": 9}},
                               board=DEFAULT_BOARD_SPEC)


def test_triangulation_recovers_points_and_a_plane():
    board = Board(DEFAULT_BOARD_SPEC)
    cam = SyntheticCamera(board, supersample=1)
    calib = _truth_calibration(cam)
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(-0.1, 0.1, 200), rng.uniform(-0.1, 0.1, 200), rng.uniform(0.4, 0.6, 200)])
    Tp = cam.proj_from_cam
    cam_px = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.camera.K, cam.camera.dist)[0].reshape(-1, 2)
    proj_px = cv2.projectPoints(X, cv2.Rodrigues(Tp[:3, :3])[0], Tp[:3, 3], cam.projector.K, cam.projector.dist)[0]
    got = triangulate(cam_px, proj_px.reshape(-1, 2), calib)
    assert np.abs(got - X).max() < 1e-6
    plane = np.column_stack([X[:, :2], 0.5 + 0.1 * X[:, 0]])
    plane[:10, 2] += 0.02  # an object on the board: left out of the fit
    n, d, keep = fit_plane(plane)
    assert keep.sum() == 190 and np.abs(plane[keep] @ n - d).max() < 1e-9


def test_calibration_file_round_trip_and_errors(tmp_path):
    cam = SyntheticCamera(Board(DEFAULT_BOARD_SPEC), supersample=1)
    calib = _truth_calibration(cam)
    path = calib.save(tmp_path / "projector.json")
    data = json.loads(path.read_text())
    assert {"R", "T", "rms", "camera", "projector", "per_pose"} <= set(data)
    assert np.allclose(data["T"], cam.proj_from_cam[:3, 3])
    assert np.allclose(ProjectorCalibration.load(path).T_proj_from_cam, cam.proj_from_cam)  # the rig reads it as is
    back = GrayCodeCalibration.load(path)
    assert np.allclose(back.camera.camera_matrix, cam.camera.K) and back.board == DEFAULT_BOARD_SPEC
    del data["camera"]
    (tmp_path / "old.json").write_text(json.dumps(data))
    with pytest.raises(CalibrationError, match="old.json.*no 'camera'"):
        GrayCodeCalibration.load(tmp_path / "old.json")


def test_bad_capture_folders_are_named(tmp_path):
    with pytest.raises(CalibrationError, match="nope.*not found"):
        pose_folders(tmp_path / "nope")
    with pytest.raises(CalibrationError, match="no pose folders"):
        pose_folders(tmp_path)
    pose = tmp_path / "pose_00"
    pose.mkdir()
    seq = graycode_sequence(SMALL_PROJECTOR)
    for i, im in enumerate(seq[:-1]):
        cv2.imwrite(str(pose / f"{i:02d}.png"), im)
    with pytest.raises(CalibrationError, match=r"pose_00: 27 images, but a 100x60 projector's .* has 28"):
        decode_pose_folder(pose, SMALL_PROJECTOR)
    (pose / "27.png").write_bytes(b"not a png")
    with pytest.raises(CalibrationError, match="27.png: cannot read"):
        decode_pose_folder(pose, SMALL_PROJECTOR)
    cv2.imwrite(str(pose / "27.png"), np.zeros((10, 10), np.uint8))
    with pytest.raises(CalibrationError, match="27.png: image is 10x10"):
        decode_pose_folder(pose, SMALL_PROJECTOR)


def test_ply_is_readable(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    pts = np.array([[0.0, 0.1, 0.5], [0.01, -0.02, 0.6], [0.3, 0.2, 0.7]])
    path = write_ply(tmp_path / "s.ply", pts, np.array([10, 128, 250]))
    cloud = trimesh.load(path)
    assert np.allclose(cloud.vertices, pts, atol=1e-6)
    assert np.array_equal(np.asarray(cloud.colors)[:, 0], [10, 128, 250])


def test_commands_name_bad_input(tmp_path, capsys):
    from app.cli import main

    out = str(tmp_path / "p.json")
    assert main(["calibrate", "projector", "--graycode", str(tmp_path), "--out", out]) == 1
    assert "--projector-size WxH is required" in capsys.readouterr().err
    assert main(["calibrate", "projector", "--graycode", str(tmp_path / "none"), "--projector-size", "100x60",
                 "--out", out]) == 1
    assert "none: Gray-code capture folder not found" in capsys.readouterr().err
    (tmp_path / "pose_00").mkdir()
    assert main(["calibrate", "projector", "--graycode", str(tmp_path), "--projector-size", "100x60", "--out", out]) == 1
    assert "pose_00: 0 images" in capsys.readouterr().err
    assert main(["calibrate", "projector", "--graycode", str(tmp_path), "--projector-size", "100", "--out", out]) == 1
    assert "must look like 1024x768" in capsys.readouterr().err
    cam = SyntheticCamera(Board(DEFAULT_BOARD_SPEC), supersample=1)
    calibration = _truth_calibration(cam).save(tmp_path / "projector.json")
    assert main(["scan", "--graycode", str(tmp_path / "pose_00"), "--calibration", str(calibration),
                 "--out", str(tmp_path / "s.ply")]) == 1
    assert "pose_00: 0 images, but a 1024x768 projector's" in capsys.readouterr().err
    assert main(["scan", "--graycode", str(tmp_path / "pose_00"), "--calibration", str(tmp_path / "nope.json"),
                 "--out", str(tmp_path / "s.ply")]) == 1
    assert "nope.json: file not found" in capsys.readouterr().err


def test_faint_light_is_explained_with_the_threshold_to_lower(small_capture):
    from ar.structured_light.calibrate import pose_corners

    _cam, _scene, _T, frames = small_capture
    faint = [(f.astype(np.float32) * 0.25).astype(np.uint8) for f in frames]  # a quarter of the light
    decoded = decode_images(faint, SMALL_PROJECTOR)
    reason = pose_corners(decoded, Board(DEFAULT_BOARD_SPEC))
    assert isinstance(reason, str) and "lower --black-threshold" in reason
    assert decode_images(faint, SMALL_PROJECTOR, black_threshold=5, white_threshold=1).mask.mean() > 0.05


def test_pose_folder_reads_unpadded_names_in_number_order(tmp_path):
    """``2.png`` comes before ``10.png``: decoding the projector's own patterns saved as
    ``0.png`` .. ``27.png`` is the identity (in plain name order it would not be)."""
    seq = graycode_sequence(SMALL_PROJECTOR)
    seq[-1] = np.full_like(seq[-1], 10)
    for i, im in enumerate(seq):
        cv2.imwrite(str(tmp_path / f"{i}.png"), im)
    d = decode_pose_folder(tmp_path, SMALL_PROJECTOR)
    ys, xs = np.mgrid[0:SMALL_PROJECTOR[1], 0:SMALL_PROJECTOR[0]]
    assert d.mask.all() and np.array_equal(d.col, xs) and np.array_equal(d.row, ys)


@pytest.mark.parametrize("spec", [DEFAULT_BOARD_SPEC, "checker:9x6:0.025", "grid:4x5:0.04:0.01:DICT_4X4_50"])
def test_scan_view_sees_and_lights_the_whole_board_and_the_box(spec):
    from ar.geometry import project_points
    from ar.structured_light.synthetic import default_scan_box, scan_view

    board = Board(spec)
    cam = SyntheticCamera(board, supersample=1)
    box = default_scan_box(board)
    T = scan_view(board, box, cam.proj_from_cam)
    w, h = board.sheet_size_m
    m = board.margin_m
    corners = np.array([[-m, -m, 0], [w - m, -m, 0], [w - m, h - m, 0], [-m, h - m, 0],
                        [box.x0, box.y0, -box.height], [box.x1, box.y1, -box.height]])
    for model, T_dev in ((cam.camera, T), (cam.projector, cam.proj_from_cam @ T)):
        px = project_points(corners, T_dev, model.K, model.dist)
        assert np.all(px >= 0) and np.all(px[:, 0] < model.width) and np.all(px[:, 1] < model.height), spec
