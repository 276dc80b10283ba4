"""ar.height_map: rasterising scanned points into a height map over the board plane,
sampling it, and its file (durable write, every malformed file refused by name)."""
from __future__ import annotations

import io

import numpy as np
import pytest

from ar.height_map import MAX_SIDE_CELLS, HeightMap, HeightMapError, fill_bounded_holes
from tests.support.table_scan import scan_points

BOX = (0.10, 0.16, 0.05, 0.09, 0.045)  # x0, x1, y0, y1, height (m): a pencil case


def _table_points(extent=(0.0, 0.25, 0.0, 0.15), outliers=0.01):
    return scan_points([BOX], extent, outliers=outliers)


def test_from_points_recovers_a_box_top_and_the_table_despite_outliers():
    pts = _table_points()
    hm = HeightMap.from_points(pts, cell_m=0.002, extent=(0.0, 0.25, 0.0, 0.15))
    assert hm.shape == (75, 125)
    assert hm.known.all()
    cx, cy = hm.cell_centres()
    inner_top = (cx > BOX[0] + 0.004) & (cx < BOX[1] - 0.004) & (cy > BOX[2] + 0.004) & (cy < BOX[3] - 0.004)
    floor = (cx < BOX[0] - 0.004) | (cx > BOX[1] + 0.004) | (cy < BOX[2] - 0.004) | (cy > BOX[3] + 0.004)
    top_err = np.abs(hm.heights[inner_top] - BOX[4])
    assert np.median(top_err) < 0.0003 and top_err.max() < 0.002  # medians shrug off the 1 % of wild points
    assert np.abs(hm.heights[floor]).max() < 0.002
    assert np.abs(hm.height_at(0.13, 0.07) - BOX[4]) < 0.001


def test_bounded_small_holes_are_filled_open_and_large_ones_stay_unknown():
    pts = _table_points(outliers=0.0)
    x, y = pts[:, 0], pts[:, 1]
    small = (np.abs(x - 0.05) < 0.003) & (np.abs(y - 0.05) < 0.003)  # 3x3 cells inside the table
    large = (np.abs(x - 0.20) < 0.012) & (np.abs(y - 0.07) < 0.012)  # 12x12 cells: a shadow
    edge = x < 0.006  # open to the grid border
    on_top = (np.abs(x - 0.13) < 0.003) & (np.abs(y - 0.07) < 0.003)  # a specular spot on the box
    keep = ~(small | large | edge | on_top)
    hm = HeightMap.from_points(pts[keep], extent=(0.0, 0.25, 0.0, 0.15))
    assert hm.height_at(0.05, 0.05, return_known=True)[1]
    assert abs(hm.height_at(0.13, 0.07) - BOX[4]) < 0.001  # filled from the box top, not the floor
    assert not hm.height_at(0.20, 0.07, return_known=True)[1]
    assert not hm.height_at(0.002, 0.07, return_known=True)[1]
    h, known = hm.height_at(0.20, 0.07, default=-1.0, return_known=True)
    assert h == -1.0 and not known
    # with filling off, the small holes stay holes
    raw = HeightMap.from_points(pts[keep], extent=(0.0, 0.25, 0.0, 0.15), max_hole_cells=0)
    assert not raw.height_at(0.05, 0.05, return_known=True)[1]


def test_hole_filling_takes_the_nearest_cell_and_keeps_an_edge_sharp():
    heights = np.zeros((7, 8), np.float32)
    heights[:, 4:] = 0.05
    known = np.ones_like(heights, bool)
    known[2:5, 3:5] = False  # a hole across the edge
    filled, k = fill_bounded_holes(heights, known, max_hole_cells=6)
    assert k.all()
    np.testing.assert_array_equal(filled[2:5, 3], 0.0)
    np.testing.assert_array_equal(filled[2:5, 4], np.float32(0.05))
    untouched, k2 = fill_bounded_holes(heights, known, max_hole_cells=5)
    assert not k2[2:5, 3:5].any() and np.array_equal(untouched[k2], heights[k2])


def test_height_at_is_bilinear_between_known_centres_and_flags_off_grid():
    heights = np.array([[0.0, 0.01], [0.02, 0.03]], np.float32)
    hm = HeightMap(0.0, 0.0, 0.01, heights, np.ones((2, 2), bool))
    assert hm.height_at(0.005, 0.005) == pytest.approx(0.0)
    assert hm.height_at(0.01, 0.01) == pytest.approx(0.015)
    assert hm.height_at(0.0075, 0.005) == pytest.approx(0.0025)  # a quarter of the way to 0.01
    vals, known = hm.height_at(np.array([0.01, 0.5, -0.001]), np.array([0.01, 0.01, 0.01]), return_known=True)
    np.testing.assert_allclose(vals, [0.015, 0.0, 0.0], atol=1e-7)
    assert known.tolist() == [True, False, False]
    # an unknown corner drops out of the weights instead of pulling towards 0
    hm2 = HeightMap(0.0, 0.0, 0.01, np.full((2, 2), 0.04, np.float32), np.array([[True, True], [True, False]]))
    assert hm2.height_at(0.01, 0.01) == pytest.approx(0.04)


def test_normal_is_up_on_flat_ground_and_tilts_on_a_ramp():
    flat = HeightMap.flat((0, 0.1, 0, 0.1), height=0.02)
    np.testing.assert_allclose(flat.normal_at(0.05, 0.05), [0, 0, 1], atol=1e-9)
    assert flat.height_at(0.05, 0.05) == pytest.approx(0.02)
    hm = HeightMap.flat((0, 0.1, 0, 0.1))
    cx, _ = hm.cell_centres()
    ramp = HeightMap(hm.x0, hm.y0, hm.cell_m, (0.5 * cx).astype(np.float32), hm.known)
    n = ramp.normal_at(0.05, 0.05)
    np.testing.assert_allclose(n, np.array([-0.5, 0.0, 1.0]) / np.sqrt(1.25), atol=1e-5)


def test_save_and_load_round_trip(tmp_path):
    hm = HeightMap.from_points(_table_points(), extent=(0.0, 0.25, 0.0, 0.15))
    path = hm.save(tmp_path / "sub" / "table.npz")
    back = HeightMap.load(path)
    assert (back.x0, back.y0, back.cell_m) == (hm.x0, hm.y0, hm.cell_m)
    np.testing.assert_array_equal(back.heights, hm.heights)
    np.testing.assert_array_equal(back.known, hm.known)
    assert path.stat().st_size < 200_000
    assert not list(path.parent.glob(".*.tmp"))  # the durable write's temporary is gone


def _npz(**arrays) -> bytes:
    base = dict(heights=np.zeros((3, 4), np.float32), known=np.ones((3, 4), bool),
                origin=np.array([0.0, 0.0, 0.002]), version=np.array(1))
    base.update(arrays)
    base = {k: v for k, v in base.items() if v is not None}
    buf = io.BytesIO()
    np.savez(buf, **base)
    return buf.getvalue()


@pytest.mark.parametrize("data, problem", [
    (b"", "not a height map file"),
    (b"{\"heights\": []}", "not a height map file"),
    (_npz(known=None), "missing known"),
    (_npz(version=np.array(7)), "unsupported height map version"),
    (_npz(known=np.ones((3, 4), np.float32)), "wrong array types"),
    (_npz(origin=np.array([0.0, 0.0])), "wrong array types"),
    (_npz(known=np.ones((2, 4), bool)), "must be the same non-empty 2-D shape"),
    (_npz(origin=np.array([0.0, 0.0, -1.0])), "cell size"),
    (_npz(heights=np.full((3, 4), np.nan, np.float32)), "known heights must be finite"),
    (_npz(heights=np.zeros((1, MAX_SIDE_CELLS + 1), np.float32), known=np.zeros((1, MAX_SIDE_CELLS + 1), bool)),
     "larger than"),
])
def test_malformed_files_are_refused_naming_the_file(tmp_path, data, problem):
    path = tmp_path / "table.npz"
    path.write_bytes(data)
    with pytest.raises(HeightMapError) as err:
        HeightMap.load(path)
    assert str(err.value).startswith(f"{path}: ")
    assert problem in str(err.value)


def test_pickled_object_arrays_are_never_loaded(tmp_path):
    path = tmp_path / "evil.npz"
    buf = io.BytesIO()
    np.savez(buf, heights=np.array([object()], dtype=object), known=np.ones(1, bool), origin=np.zeros(3),
             version=np.array(1))
    path.write_bytes(buf.getvalue())
    with pytest.raises(HeightMapError, match="not a height map file"):
        HeightMap.load(path)


def test_missing_and_folder_paths(tmp_path):
    with pytest.raises(HeightMapError, match="file not found"):
        HeightMap.load(tmp_path / "nope.npz")
    with pytest.raises(HeightMapError, match="is a folder"):
        HeightMap.load(tmp_path)


def test_bad_points_are_refused():
    with pytest.raises(HeightMapError, match=r"\(N, 3\)"):
        HeightMap.from_points(np.zeros((5, 2)))
    with pytest.raises(HeightMapError, match="no finite points"):
        HeightMap.from_points(np.full((4, 3), np.nan))
    with pytest.raises(HeightMapError, match="larger than"):
        HeightMap.from_points(np.array([[0, 0, 0], [100.0, 0, 0]]), cell_m=0.002)
    with pytest.raises(HeightMapError, match="extent"):
        HeightMap.flat((0.1, 0.0, 0.0, 0.1))


def test_scene_ground_reads_the_map_at_the_board_point_under_the_scene_point():
    from ar import DEFAULT_BOARD_SPEC, Board
    from ar.scene import board_to_scene_points, scene_ground

    board = Board(DEFAULT_BOARD_SPEC)
    hm = HeightMap.from_points(scan_points([BOX], (0.0, 0.25, 0.0, 0.15), outliers=0.0))
    ground = scene_ground(hm, board)
    on_box, beside = board_to_scene_points(np.array([[0.13, 0.07, 0.0], [0.05, 0.07, 0.0]]), board)
    # scene (X, Z) = board (x, y) minus the board centre; the scene's Y is the height
    assert ground(on_box[0], on_box[2]) == pytest.approx(BOX[4], abs=0.001)
    assert ground(beside[0], beside[2]) == pytest.approx(0.0, abs=0.001)
    far = ground(np.array([5.0]), np.array([5.0]))
    assert far.tolist() == [0.0]  # off the scan: the table
