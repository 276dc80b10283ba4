"""*Scan the table* (issue 28): the calibration wizard's last step captures the Gray-code
sequence, scans it into a height map and stores it beside the calibration through the
durable write, where the projector stage finds it."""
from __future__ import annotations

import re

import numpy as np
import pytest

from app.services.calibration_wizard import CalibrationWizard
from app.services.table_scan import (SYNTHETIC_BOXES, capture_sequence, describe_scan, scan_captures,
                                     synthetic_scan)
from ar import DEFAULT_BOARD_SPEC, HEIGHT_MAP_FILE, Board, HeightMap, HeightMapError
from tests.support.table_scan import scan_points

BOARD_EXTENT = (-0.05, 0.25, -0.05, 0.33)


def _to_scan_step(wizard: CalibrationWizard) -> CalibrationWizard:
    """Run the wizard's calibration steps (synthetic views) up to the scan."""
    while wizard.steps[wizard.current].key != "scan":
        step = wizard.run_next()
        assert step.error is None, f"{step.key}: {step.error}"
    return wizard


def test_capture_shows_every_pattern_and_keeps_a_fresh_frame_after_each():
    patterns = [np.full((4, 6), k, np.uint8) for k in range(5)]
    shown, reads = [], []

    def read():
        reads.append(len(shown))
        return np.full((3, 3, 3), 10 * len(shown) + len(reads), np.uint8)

    frames = capture_sequence(patterns, lambda rgb: shown.append(rgb.copy()), read, settle_s=0.0, flush_frames=2,
                              sleep=lambda s: None)
    assert [int(s[0, 0, 0]) for s in shown] == [0, 1, 2, 3, 4]
    assert all(s.shape == (4, 6, 3) for s in shown)  # grey patterns go to the projector as RGB
    assert len(reads) == 15 and len(frames) == 5
    assert [int(f[0, 0, 0]) for f in frames] == [10 * (k + 1) + 3 * (k + 1) for k in range(5)]  # the third read after each

    shown.clear()

    def stops():
        return None if len(shown) == 3 else np.zeros((2, 2, 3), np.uint8)
    with pytest.raises(HeightMapError, match="camera stopped during the scan.*pattern 3 of 5"):
        capture_sequence(patterns, lambda rgb: shown.append(rgb), stops, settle_s=0.0, sleep=lambda s: None)


def test_the_scan_step_stores_the_height_map_with_the_calibration(tmp_path):
    hm = HeightMap.from_points(scan_points([(0.15, 0.22, 0.17, 0.24, 0.045)], BOARD_EXTENT))
    got = {}

    def scan(captures, calibration):
        got["captures"], got["calibration"] = captures, calibration
        return hm
    (tmp_path / "projector.json").write_text("{}")  # a real rig's Gray-code calibration is read by the step ...
    wizard = _to_scan_step(CalibrationWizard(tmp_path, n_views=5, scan_capture=lambda: ["frame"] * 3, scan=scan))
    step = wizard.run_next()
    # ... and a malformed one is refused by name, nothing is written, the step can be retried
    assert step.error is not None and "projector.json" in step.error and not wizard.done
    assert not (tmp_path / HEIGHT_MAP_FILE).exists()

    wizard.scan_capture = lambda: ["frame"] * 3
    from ar.structured_light.calibrate import GrayCodeCalibration
    from app.services.table_scan import synthetic_rig_calibration
    from ar.synthetic import SyntheticCamera
    synthetic_rig_calibration(SyntheticCamera(Board(DEFAULT_BOARD_SPEC), supersample=1)).save(tmp_path / "projector.json")
    step = wizard.run_next()
    assert step.error is None and wizard.done
    assert got["captures"] == ["frame"] * 3 and isinstance(got["calibration"], GrayCodeCalibration)
    assert step.result == describe_scan(hm) and re.search(r"99 % seen, tallest 4[56] mm", step.result)
    back = HeightMap.load(tmp_path / HEIGHT_MAP_FILE)
    np.testing.assert_array_equal(back.heights, hm.heights)
    assert (tmp_path / "camera.json").is_file()  # beside the calibration
    assert not list(tmp_path.glob(".*.tmp"))


def test_a_failed_scan_keeps_the_previous_one(tmp_path):
    old = HeightMap.flat((0, 0.1, 0, 0.1), height=0.01)
    old.save(tmp_path / HEIGHT_MAP_FILE)

    def scan(captures, calibration):
        raise HeightMapError("the board was not found: keep the whole printed board in the camera's view")
    wizard = _to_scan_step(CalibrationWizard(tmp_path, n_views=5, scan=scan))
    wizard.scan_capture = None  # synthetic captures, the injected scan fails
    step = wizard.run_next()
    assert "board was not found" in step.error and not wizard.done
    assert HeightMap.load(tmp_path / HEIGHT_MAP_FILE).heights.max() == pytest.approx(0.01)


def test_a_real_camera_without_a_projector_is_refused(tmp_path):
    wizard = CalibrationWizard(tmp_path, camera_index=0)
    wizard._board = Board(DEFAULT_BOARD_SPEC)
    wizard.current = [s.key for s in wizard.steps].index("scan")
    step = wizard.run_next()
    assert "connect it as a second display" in step.error


@pytest.mark.slow
def test_synthetic_wizard_scans_the_boxes_within_2_mm(tmp_path):
    """The whole step on the synthetic rig: Gray-code frames rendered over the table with
    two boxes, decoded, triangulated with the rig's true calibration, rasterised."""
    wizard = _to_scan_step(CalibrationWizard(tmp_path, n_views=5))
    step = wizard.run_next()
    assert step.error is None, step.error
    hm = HeightMap.load(tmp_path / HEIGHT_MAP_FILE)
    cx, cy = hm.cell_centres()
    for x0, y0, x1, y1, height in SYNTHETIC_BOXES:
        top = (cx > x0 + 0.005) & (cx < x1 - 0.005) & (cy > y0 + 0.005) & (cy < y1 - 0.005)
        assert hm.known[top].mean() > 0.9
        err = np.abs(hm.heights[top & hm.known] - height)
        print(f"\nbox {height * 1000:.0f} mm: median height error {np.median(err) * 1000:.2f} mm")
        assert np.median(err) < 0.002
    table = (cy < 0.12) & (cx > 0.02) & (cx < 0.18) & hm.known
    assert np.median(np.abs(hm.heights[table])) < 0.001


@pytest.mark.slow
def test_scan_without_the_board_in_view_is_refused():
    board = Board(DEFAULT_BOARD_SPEC)
    captures, calibration = synthetic_scan(board)
    dark = [np.zeros_like(c) for c in captures]
    with pytest.raises(HeightMapError, match="no projected pattern was seen"):
        scan_captures(dark, calibration, board)
