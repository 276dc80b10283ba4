"""Board specs, printing at true size, detection (incl. the checkerboard's orientation)."""
from __future__ import annotations

import re

import cv2
import numpy as np
import pytest

from ar.boards import DEFAULT_BOARD_SPEC, Board, BoardSpec, write_board
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
