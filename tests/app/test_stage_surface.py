"""The projector stage on a scanned table (issue 28): a character whose path crosses a box
is drawn on the box's top, so its projected feet land on it.

Landing error, per planted sole point on the box top: the stage draws the foot from the
*tracked* projector pose; the ray of the true projector through that pixel meets the true
box top at the landing point; its distance from where the foot stands (board x, y) is how
far the light of the foot lands from the foot. The synthetic rig gives the truth (the
hand's pose, the rig's extrinsics); the box is the synthetic table's 4.5 cm pencil case,
scanned as the teacher's *Scan the table* step scans it (Gray-code frames rendered on the
synthetic rig, decoded, triangulated, rasterised).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.player.stage import StageRenderer
from app.story.model import Character, MotionChoice, Scene
from app.services.table_scan import SYNTHETIC_BOXES, scan_captures, synthetic_scan
from ar import DEFAULT_BOARD_SPEC, HEIGHT_MAP_FILE, Board, HeightMap
from ar.rig import SyntheticRig
from ar.scene import scene_to_board_points
from lab.bench.surface import PATHS, landing_errors

LIBRARY = Path(__file__).resolve().parents[2] / "assets" / "motions"
_X0, _Y0, _X1, _Y1, _H = SYNTHETIC_BOXES[0]
BOX = (_X0, _X1, _Y0, _Y1, _H)  # board frame: x0, x1, y0, y1, height (m)
PATH = PATHS["pencil case 45 mm"]  # the stage's miniature lays it along board x = 0.185, over the box

pytestmark = pytest.mark.skipif(not (LIBRARY / "labels.csv").is_file(), reason="bundled motion library absent")


@pytest.fixture(scope="module")
def scan() -> HeightMap:
    board = Board(DEFAULT_BOARD_SPEC)
    return scan_captures(*synthetic_scan(board), board)


def _landing_errors(stage: StageRenderer, rig: SyntheticRig, character: Character) -> tuple[np.ndarray, np.ndarray]:
    """(landing errors, foot heights) in metres of the planted feet on the box top
    (:func:`lab.bench.surface.landing_errors`, what ``storybeam bench surface`` reports)."""
    got = landing_errors(stage, rig, character, SYNTHETIC_BOXES[0])
    return got["errors"], got["heights"]


@pytest.mark.slow
def test_feet_land_on_the_scanned_box_top_within_3_mm(tmp_path, scan):
    scan.save(tmp_path / HEIGHT_MAP_FILE)
    character = Character(kind="robot", path=PATH, motion=MotionChoice("walk"))
    rig = SyntheticRig()
    stage = StageRenderer(rig=rig, profile_dir=tmp_path, draw=None)  # finds table.npz in the profile
    try:
        assert stage.height_map is not None
        errors, heights = _landing_errors(stage, rig, character)
    finally:
        stage.close()
    print(f"\nfeet on the box top: landing error median {np.median(errors) * 1000:.2f} mm, "
          f"max {errors.max() * 1000:.2f} mm over {len(errors)} planted sole points; "
          f"height median {np.median(heights) * 1000:.2f} mm (box {BOX[4] * 1000:.0f} mm)")
    assert len(errors) >= 10
    assert np.median(errors) < 0.003 and np.percentile(errors, 90) < 0.003
    assert np.all(np.abs(heights - BOX[4]) < 0.003)

    # the same story on the bare table: the feet are drawn on the table under the box, and
    # their light lands centimetres off on its top
    bare_rig = SyntheticRig()
    bare = StageRenderer(rig=bare_rig, draw=None)
    try:
        assert bare.height_map is None
        bare_errors, _ = _landing_errors(bare, bare_rig, character)
    finally:
        bare.close()
    assert np.median(bare_errors) > 0.01


@pytest.mark.slow
def test_the_path_over_the_box_jumps_at_its_edges(scan):
    stage = StageRenderer(rig=SyntheticRig(), draw=None, height_map=scan)
    try:
        _design, motion = stage.animator.animate(Character(kind="robot", path=PATH, motion=MotionChoice("walk")))
    finally:
        stage.close()
    root = scene_to_board_points(motion.root_translation * motion.skeleton.metres_per_unit, stage.board)
    lift = -root[:, 2] - np.median(-root[root[:, 1] < BOX[2] - 0.03, 2])  # root height over its height on the table
    y = root[:, 1]
    top = (y > BOX[2] + 0.02) & (y < BOX[3] - 0.02)
    assert np.abs(np.median(lift[top]) - BOX[4]) < 0.002  # on the box, one box higher
    # around each edge the root flies over the top: the jump starts when the leading foot
    # reaches the edge (the root ~2 cm before it) and ends when the trailing foot has left
    for edge in (BOX[2], BOX[3]):
        near = np.abs(y - edge) < 0.03
        assert lift[near].max() > BOX[4] + 0.01


def test_the_stage_follows_the_profile_scan_as_the_teacher_rescans(tmp_path, caplog):
    """A scan written while the stage runs is used from the next frame; a deleted one is
    dropped; an unreadable one is reported and the stage plays on the bare table."""
    stage = StageRenderer(rig=SyntheticRig(), profile_dir=tmp_path, draw=None)
    empty = Scene()
    try:
        assert stage.height_map is None and stage.animator.ground is None
        HeightMap.flat((0.0, 0.2, 0.0, 0.28), height=0.03).save(tmp_path / HEIGHT_MAP_FILE)
        stage.prepare(empty)
        assert stage.height_map is not None
        assert stage.animator.ground(np.array([0.0]), np.array([0.0]))[0] == pytest.approx(0.03)  # board centre
        (tmp_path / HEIGHT_MAP_FILE).write_bytes(b"not a scan at all")
        stage.prepare(empty)
        assert stage.height_map is None and stage.animator.ground is None
        assert "table.npz" in caplog.text and "scanned table not used" in caplog.text
        HeightMap.flat((0.0, 0.2, 0.0, 0.28), height=0.01).save(tmp_path / HEIGHT_MAP_FILE)
        stage.prepare(empty)
        assert stage.animator.ground(np.array([0.0]), np.array([0.0]))[0] == pytest.approx(0.01)
        (tmp_path / HEIGHT_MAP_FILE).unlink()
        stage.prepare(empty)
        assert stage.height_map is None
    finally:
        stage.close()
