"""Board specs, printing at true size, detection (incl. the checkerboard's orientation)."""
from __future__ import annotations

import re

import cv2
import numpy as np
import pytest

from ar.boards import DEFAULT_BOARD_SPEC, Board, BoardSpec, board_dictionary, write_board
from ar.errors import BoardSpecError
from retrieval.errors import StoryBeamError


@pytest.mark.parametrize("text", [DEFAULT_BOARD_SPEC, "grid:4x5:0.04:0.01:DICT_4X4_50", "checker:9x6:0.025"])
def test_spec_round_trip(text):
    spec = BoardSpec.parse(text)
    assert str(spec) == text
    assert BoardSpec.parse(str(spec)) == spec


def test_spec_fields():
    spec = BoardSpec.parse("charuco:5x7:0.04:0.02:DICT_6X6_250")
    assert (spec.kind, spec.cols, spec.rows, spec.square_m, spec.marker_m, spec.dictionary) == (
        "charuco", 5, 7, 0.04, 0.02, "DICT_6X6_250")


@pytest.mark.parametrize("text, fragment", [
    ("hexagon:5x7:0.04", "unknown kind"),
    ("charuco:5x7:0.04:0.02", "expected 5"),
    ("charuco:5by7:0.04:0.02:DICT_6X6_250", "must look like"),
    ("charuco:5x7:0.04:0.05:DICT_6X6_250", "must be smaller"),
    ("charuco:5x7:0.04:0.02:DICT_NOPE", "unknown ArUco dictionary"),
    ("checker:9x6:40", "metres"),
    ("checker:1x6:0.02", "at least 2x2"),
])
def test_bad_specs_raise_clear_errors(text, fragment):
    with pytest.raises(BoardSpecError, match=fragment) as info:
        BoardSpec.parse(text)
    assert isinstance(info.value, StoryBeamError)
    assert text in str(info.value)


def test_too_many_markers_for_dictionary():
    with pytest.raises(BoardSpecError, match="needs 60 markers"):
        Board("grid:6x10:0.02:0.005:DICT_4X4_50")


def test_pdf_and_png_have_true_physical_size(tmp_path):
    board = Board(DEFAULT_BOARD_SPEC)
    pdf = write_board(board, tmp_path / "b.pdf")
    box = re.search(rb"MediaBox\s*\[\s*0\s+0\s+([\d.]+)\s+([\d.]+)", pdf.read_bytes())
    w_mm, h_mm = (float(v) / 72 * 25.4 for v in box.groups())
    assert w_mm == pytest.approx(board.sheet_size_m[0] * 1000, abs=0.2)
    assert h_mm == pytest.approx(board.sheet_size_m[1] * 1000, abs=0.2)
    assert w_mm <= 210.0 + 0.2 and h_mm <= 297.0  # the default board fits an A4 page

    from PIL import Image

    png = write_board(board, tmp_path / "b.png", dpi=200)
    with Image.open(png) as im:
        dpi = im.info["dpi"][0]
        assert im.size[0] / dpi * 25.4 == pytest.approx(board.sheet_size_m[0] * 1000, abs=0.2)
    det = board.detect(cv2.imread(str(png)))
    assert det is not None and det.n == det.total_points == 24


def test_write_rejects_unknown_suffix(tmp_path):
    with pytest.raises(BoardSpecError, match="must be .png or .pdf"):
        write_board(Board(DEFAULT_BOARD_SPEC), tmp_path / "b.svg")


@pytest.mark.parametrize("spec", [DEFAULT_BOARD_SPEC, "grid:4x5:0.04:0.01:DICT_4X4_50", "checker:9x6:0.025"])
def test_texture_pixels_match_object_points(spec):
    """Corners found in the drawn sheet sit where the documented board frame says."""
    board = Board(spec)
    sheet, ppm = board.texture(3000)
    det = board.detect(sheet)
    assert det is not None and det.n == det.total_points
    expected = (det.object_points[:, :2] + board.texture_origin_m(ppm)) * ppm - 0.5
    assert np.abs(expected - det.image_points).max() < 0.2


def test_checkerboard_orientation_survives_half_turn():
    """Seen upside down, corner 0 must still be the printed top-left corner (no mis-pose)."""
    board = Board("checker:9x6:0.025")
    sheet, ppm = board.texture(3000)
    turned = np.ascontiguousarray(sheet[::-1, ::-1])
    det = board.detect(turned)
    assert det is not None
    h, w = sheet.shape
    upright = (det.object_points[:, :2] + board.texture_origin_m(ppm)) * ppm - 0.5
    expected = np.stack([w - 1 - upright[:, 0], h - 1 - upright[:, 1]], 1)
    assert np.abs(expected - det.image_points).max() < 0.2


# ---------------------------------------------------------------- fast detection (issue 13)
def _frame_with_foreign_markers(distance_m=0.5, seed=4):
    """A camera frame of the default board with two markers of the same dictionary that
    the board does not print (ids 100 and 200) pasted on the table beside it."""
    from ar.synthetic import Degradation, SyntheticCamera, TrajectoryConfig, handheld_trajectory

    board = Board(DEFAULT_BOARD_SPEC)
    cam = SyntheticCamera(board, supersample=1)
    T = handheld_trajectory(board, 1, TrajectoryConfig(distance_m=distance_m, seed=seed))[0]
    frame = cam.render(T, degradation=Degradation(noise_sigma=2.0), rng=np.random.default_rng(seed))
    full = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    for k, marker_id in enumerate((100, 200)):
        tile = cv2.aruco.generateImageMarker(full, marker_id, 48)
        tile = cv2.copyMakeBorder(tile, 8, 8, 8, 8, cv2.BORDER_CONSTANT, value=255)
        y, x = 10 + 70 * k, 10
        frame[y:y + tile.shape[0], x:x + tile.shape[1]] = tile[..., None]
    return board, frame, full, T, cam.camera


def _true_px(board, det, T, camera):
    from ar.geometry import project_points

    return project_points(det.object_points, T, camera.K, camera.dist)


def test_board_dictionary_finds_exactly_the_board_markers_of_the_full_dictionary():
    """The restricted dictionary (the board's own codes) finds every board marker at the very
    same corners as the full 250-code dictionary, and only drops the foreign ids."""
    board, frame, full, _T, _cam = _frame_with_foreign_markers()
    gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    n = (board.spec.cols * board.spec.rows) // 2
    params = cv2.aruco.DetectorParameters()
    c_full, ids_full, _ = cv2.aruco.ArucoDetector(full, params).detectMarkers(gray)
    c_sub, ids_sub, _ = cv2.aruco.ArucoDetector(board_dictionary(full, n), params).detectMarkers(gray)
    ids_full, ids_sub = ids_full.ravel(), ids_sub.ravel()
    assert {100, 200} <= set(ids_full.tolist())  # the foreign markers are really there and readable
    assert not {100, 200} & set(ids_sub.tolist())
    on_board = {int(i): c for i, c in zip(ids_full, c_full) if i < n}
    assert sorted(on_board) == sorted(ids_sub.tolist()) and len(on_board) >= n - 2
    for i, c in zip(ids_sub, c_sub):
        np.testing.assert_array_equal(c, on_board[int(i)])
    assert board_dictionary(full, n).maxCorrectionBits == full.maxCorrectionBits


def test_region_detection_equals_full_frame_detection():
    from ar.geometry import project_points

    board, frame, _, T, camera = _frame_with_foreign_markers()
    whole = board.detect(frame)
    w, h = board.pattern_size_m
    quad = project_points(np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]]), T, camera.K, camera.dist)
    box = (*(np.floor(quad.min(0)) - 10).astype(int), *(np.ceil(quad.max(0)) + 10).astype(int))
    part = board.detect(frame, region=box)
    np.testing.assert_array_equal(part.ids, whole.ids)
    np.testing.assert_allclose(part.image_points, whole.image_points, atol=1e-3)
    # a region without the board finds nothing (and a degenerate one is refused)
    assert board.detect(frame, region=(0, 0, 60, 60)) is None
    assert board.detect(frame, region=(10, 10, 12, 500)) is None


def test_downscaled_search_refined_at_full_resolution_is_as_accurate_as_full_search():
    """Near the board (markers ~45 px) markers found at half size and corners refined at full
    size are within 0.1 px as close to the true corners as a full-resolution search's (median
    and 95th percentile); the unrefined half-size corners are not."""
    board, frame, _, T, camera = _frame_with_foreign_markers(distance_m=0.3, seed=2)
    whole = board.detect(frame)
    half = board.detect(frame, scale=2)
    assert half is not None and half.n >= whole.n - 2
    err_whole = np.linalg.norm(whole.image_points - _true_px(board, whole, T, camera), axis=1)
    err_half = np.linalg.norm(half.image_points - _true_px(board, half, T, camera), axis=1)
    tol = 0.1  # px: the two searches refine with different windows
    assert np.median(err_half) <= np.median(err_whole) + tol, (np.median(err_half), np.median(err_whole))
    assert np.percentile(err_half, 95) <= np.percentile(err_whole, 95) + tol
    gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    coarse = board.detect(cv2.resize(gray, (gray.shape[1] // 2, gray.shape[0] // 2), interpolation=cv2.INTER_AREA))
    coarse.image_points = (coarse.image_points + 0.5) * 2 - 0.5
    err_coarse = np.linalg.norm(coarse.image_points - _true_px(board, coarse, T, camera), axis=1)
    assert np.percentile(err_coarse, 95) > np.percentile(err_whole, 95) + tol  # what the refinement removes


@pytest.mark.parametrize("name", ["DICT_6X6_250", "DICT_4X4_50", "DICT_5X5_100"])
def test_dictionary_codes_are_far_enough_apart_for_the_restriction_proof(name):
    """The premise of :func:`board_dictionary`'s proof: any two codes (in any of the four
    rotations) differ in at least 2 maxCorrectionBits + 1 bits."""
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
    n, m = d.bytesList.shape[0], d.markerSize
    bits = np.array([cv2.aruco.Dictionary.getBitsFromByteList(d.bytesList[i:i + 1], m) for i in range(n)]).reshape(n, m, m)
    rotations = np.stack([np.rot90(bits, k, axes=(1, 2)) for k in range(4)], 1).reshape(n, 4, -1)
    dist = (rotations[:, None] != bits.reshape(n, -1)[None, :, None]).sum(-1).min(-1)
    np.fill_diagonal(dist, m * m)
    assert dist.min() >= 2 * d.maxCorrectionBits + 1
