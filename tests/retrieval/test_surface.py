"""retrieval.animation.surface: a character laid on a path follows the table's surface --
its feet on a box top, a jump at an edge higher than a step, lower edges walked, and no
sole ever inside a box. Bundled motions only; the ground is an exact box function here
(tests/app/test_stage_surface.py runs it on a scanned height map through the stage)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ar.scene import build_character
from retrieval.animation import (STEP_MAX_M, character_height, contacts, find_edges, follow_path, follow_surface,
                                 retarget, sole_points, straight_path)
from retrieval.motion.formats import load_motion

BVH = Path(__file__).resolve().parents[2] / "assets" / "motions" / "bvh"
TALL = (-0.05, 0.08, 0.045)  # x from, x to, height: higher than a step
LOW = (0.12, 0.15, 0.02)  # lower than a step


def _ground(x, z):
    """Two boxes 8 cm deep across the path (scene frame, metres)."""
    x, z = np.asarray(x), np.asarray(z)
    h = np.zeros(np.broadcast(x, z).shape)
    for x0, x1, top in (TALL, LOW):
        h = np.where((x >= x0) & (x < x1) & (np.abs(z) < 0.04), top, h)
    return h


@pytest.fixture(scope="module")
def walked():
    robot = build_character("robot", 0.10)
    walk = retarget(load_motion(BVH / "02_01.bvh"), robot.skeleton)
    return follow_path(walk, straight_path(0.4, start=(-0.2, 0.0))).motion


def test_feet_stand_on_the_box_top_and_on_the_table(walked):
    res = follow_surface(walked, _ground)
    soles = sole_points(res.motion)
    touch = contacts(res.motion)
    x, y, z = soles[..., 0], soles[..., 1], soles[..., 2]
    on_top = touch & (x > TALL[0] + 0.01) & (x < TALL[1] - 0.01)
    on_table = touch & (x < TALL[0] - 0.03)
    assert on_top.sum() > 20 and on_table.sum() > 20
    # the clip's own soles touch within ~2 mm of its ground; the box top is the new ground
    assert np.median(np.abs(y[on_top] - TALL[2])) < 0.0015
    assert np.abs(y[on_top] - TALL[2]).max() < 0.003
    assert np.median(np.abs(y[on_table])) < 0.0015
    # and without the surface the same feet would be 4.5 cm inside the box
    assert np.median(sole_points(walked)[..., 1][on_top]) < 0.003
    # no sole goes into a box's side or top, in any frame (swing feet included)
    assert (y - _ground(x, z)).min() > -0.003


def test_a_high_edge_is_jumped_and_a_low_one_walked(walked):
    res = follow_surface(walked, _ground)
    # up onto the tall box, off it straight onto the low one (whose near edge lies inside
    # the jump), and down the low box's far edge on foot
    kinds = [(e.jump, round(e.rise, 3)) for e in res.edges]
    assert kinds == [(True, 0.045), (True, -0.045), (False, -0.02)]
    jumps = res.edges[:2]
    assert res.offset[jumps[1].window[1]] == pytest.approx(LOW[2])
    assert all(abs(e.rise) <= STEP_MAX_M for e in res.edges if not e.jump)
    # the jump's arc clears the box top by the clearance (20 % of the character's height)
    a, b = jumps[0].window
    peak = res.offset[a:b + 1].max()
    assert peak >= TALL[2] + 0.2 * character_height(walked) - 1e-6
    # the root rises only around the edge: before the window on the table, after it on the box
    root_y = res.motion.root_translation[:, 1] * res.motion.skeleton.metres_per_unit
    base_y = walked.root_translation[:, 1] * walked.skeleton.metres_per_unit
    np.testing.assert_allclose(root_y[:a] - base_y[:a], 0.0, atol=1e-9)
    after = slice(b + 1, jumps[1].window[0])
    np.testing.assert_allclose(root_y[after] - base_y[after], TALL[2], atol=1e-9)


def test_a_step_lower_than_the_threshold_is_walked_when_alone(walked):
    only_low = lambda x, z: np.where((np.asarray(x) >= LOW[0]) & (np.asarray(x) < LOW[1]), LOW[2], 0.0)  # noqa: E731
    res = follow_surface(walked, only_low)
    assert [e.jump for e in res.edges] == [False, False]
    assert [round(e.rise, 3) for e in res.edges] == [0.02, -0.02]
    # the ramp never lifts the character more than the step (no hop)
    assert res.offset.max() <= LOW[2] + 1e-9
    # a lower threshold turns the same step into jumps
    strict = follow_surface(walked, only_low, step_max_m=0.01)
    assert [e.jump for e in strict.edges] == [True, True]


def test_flat_ground_changes_nothing(walked):
    res = follow_surface(walked, lambda x, z: np.zeros(np.shape(x)))
    assert res.edges == []
    np.testing.assert_array_equal(res.motion.root_translation, walked.root_translation)


def test_find_edges_merges_a_ragged_edge_and_ignores_standing_still():
    h = np.array([0, 0, 0.01, 0.03, 0.05, 0.05, 0.05, 0.0, 0.0])
    travel = np.full(8, 0.005)
    assert find_edges(h, travel) == [(1, 3, pytest.approx(0.05)), (6, 6, pytest.approx(-0.05))]
    # 1 mm of scan noise while the character stands still is not an edge
    assert find_edges(np.array([0.0, 0.001, 0.0, 0.001]), np.zeros(3)) == []
