"""The one table -> scene mapping (app.player.placement) and its two placements."""
from __future__ import annotations

import numpy as np
import pytest

from app.player import PREVIEW_PLACEMENT, STAGE_PLACEMENT, STAGE_SCALE, scene_to_table, table_to_scene
from app.story import TABLE_DEPTH_M, TABLE_WIDTH_M

CORNERS = np.array([[0.0, 0.0], [TABLE_WIDTH_M, 0.0], [TABLE_WIDTH_M, TABLE_DEPTH_M], [0.0, TABLE_DEPTH_M]])


@pytest.mark.parametrize("placement", [PREVIEW_PLACEMENT, STAGE_PLACEMENT], ids=lambda p: p.name)
def test_the_table_centre_is_the_scene_origin_and_the_mapping_inverts(placement):
    centre = np.array([[TABLE_WIDTH_M / 2, TABLE_DEPTH_M / 2, 4.0]])  # a time column is ignored
    np.testing.assert_allclose(table_to_scene(centre, placement), [[0.0, 0.0]], atol=1e-15)
    rng = np.random.default_rng(0)
    pts = rng.uniform([0, 0], [TABLE_WIDTH_M, TABLE_DEPTH_M], size=(50, 2))
    np.testing.assert_allclose(scene_to_table(table_to_scene(pts, placement), placement), pts, atol=1e-12)
    # lengths scale by the placement's scale, angles are kept
    d_table = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    d_scene = np.linalg.norm(np.diff(table_to_scene(pts, placement), axis=0), axis=1)
    np.testing.assert_allclose(d_scene, placement.scale * d_table, rtol=1e-12)


def test_the_preview_sees_the_table_from_the_childs_side():
    scene = table_to_scene(CORNERS, PREVIEW_PLACEMENT)
    # front-left corner: on the viewer's right (scene -X is table +x ... so table x=0 is +X)
    np.testing.assert_allclose(scene[0], [TABLE_WIDTH_M / 2, -TABLE_DEPTH_M / 2])
    # moving right on the table (+x) is scene -X; moving away (+y) is scene +Z
    assert scene[1, 0] < scene[0, 0] and scene[1, 1] == scene[0, 1]
    assert scene[3, 1] > scene[0, 1] and scene[3, 0] == scene[0, 0]


def test_the_stage_is_a_miniature_on_the_board_with_the_childs_edge_nearest_the_rig():
    scene = table_to_scene(CORNERS, STAGE_PLACEMENT)
    np.testing.assert_allclose(np.ptp(scene, axis=0), [STAGE_SCALE * TABLE_DEPTH_M, STAGE_SCALE * TABLE_WIDTH_M])
    # table +x runs along scene -Z, table +y along scene -X
    np.testing.assert_allclose(scene[1] - scene[0], [0.0, -STAGE_SCALE * TABLE_WIDTH_M])
    np.testing.assert_allclose(scene[3] - scene[0], [-STAGE_SCALE * TABLE_DEPTH_M, 0.0])


@pytest.mark.parametrize("placement", [PREVIEW_PLACEMENT, STAGE_PLACEMENT], ids=lambda p: p.name)
def test_the_animator_walks_the_path_where_the_mapping_puts_it(placement):
    """The preview and the stage both animate through app.player.animator, which lays the
    child's table path into the scene with this mapping: the walking root follows it."""
    pytest.importorskip("pyrender")
    from app.player.animator import SceneAnimator  # needs ar.render (pyrender) at load
    from app.story import Character, MotionChoice
    from retrieval.animation import path_error_cm

    path = [(0.3, 0.2, 0.0), (0.9, 0.5, 12.0)]  # slow enough for a 16 cm walker to arrive
    animator = SceneAnimator.from_library(placement=placement)
    _, motion = animator.animate(Character(kind="robot", path=path, motion=MotionChoice("walk")))
    want = table_to_scene(np.array(path), placement)
    mpu = motion.skeleton.metres_per_unit
    start = motion.root_translation[0, [0, 2]] * mpu
    end = motion.root_translation[-1, [0, 2]] * mpu
    length = np.linalg.norm(want[1] - want[0])
    assert np.linalg.norm(start - want[0]) < 0.1 * length
    assert np.linalg.norm(end - want[1]) < 0.1 * length
    assert path_error_cm(motion, want) < 0.02 * length * 100  # within 2 % of the path's length
