"""Foot locking (retrieval.animation.foot_lock): the analytic two-bone leg solve and
pinning the sole points of a sliding walk to the table."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ar.render.characters import build_character
from retrieval.animation import contacts, lock_feet, retarget, sole_points, two_bone_knee
from retrieval.animation.metrics import foot_skate_cm_per_m
from retrieval.motion import global_transforms
from retrieval.motion.formats import load_motion

BVH = Path(__file__).resolve().parents[2] / "assets" / "motions" / "bvh"


def test_two_bone_knee_keeps_both_bone_lengths_and_bends_towards_the_hint():
    rng = np.random.default_rng(0)
    t = 50
    hip = rng.normal(size=(t, 3))
    l1, l2 = 0.45, 0.42
    direction = rng.normal(size=(t, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    target = hip + direction * rng.uniform(0.2, 0.8, size=(t, 1))  # all within reach
    hint = hip + rng.normal(size=(t, 3))
    knee = two_bone_knee(hip, target, hint, l1, l2)
    np.testing.assert_allclose(np.linalg.norm(knee - hip, axis=1), l1, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(target - knee, axis=1), l2, atol=1e-9)
    # the knee lies on the hint's side of the hip-target line
    u = (target - hip) / np.linalg.norm(target - hip, axis=1, keepdims=True)
    side_knee = (knee - hip) - np.sum((knee - hip) * u, axis=1, keepdims=True) * u
    side_hint = (hint - hip) - np.sum((hint - hip) * u, axis=1, keepdims=True) * u
    assert np.all(np.sum(side_knee * side_hint, axis=1) > 0)


def test_two_bone_knee_stretches_the_leg_towards_an_unreachable_target():
    hip = np.zeros((1, 3))
    target = np.array([[0.0, -3.0, 0.0]])  # much further than l1 + l2
    knee = two_bone_knee(hip, target, np.array([[0.0, -0.5, 1.0]]), 0.5, 0.5)
    assert np.linalg.norm(knee - hip) == pytest.approx(0.5)
    assert knee[0, 1] == pytest.approx(-0.5, abs=1e-3)  # straight down, along the target


@pytest.fixture(scope="module")
def sliding_walk():
    """A bundled walk on the robot, with the root dragged sideways so the feet slide."""
    robot = build_character("robot")
    walk = retarget(load_motion(BVH / "02_01.bvh"), robot.skeleton)
    slid = walk.copy()
    drift = np.linspace(0.0, 3.0, walk.n_frames)  # 3 cm (a quarter of its height) of sideways slide
    slid.root_translation[:, 0] += drift
    return slid


def _stance_spreads(motion, contact) -> np.ndarray:
    """The horizontal wander of a sole point over each of its contacts (native units, cm
    for the robot), away from the contact's fade-in and fade-out frames."""
    soles = sole_points(motion) / motion.skeleton.metres_per_unit
    spreads = []
    for j in range(4):
        c = contact[:, j]
        edges = np.flatnonzero(np.diff(np.concatenate([[0], c.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a >= 6:
                inner = soles[a + 2:b - 2, j][:, [0, 2]]  # away from the fades
                spreads.append(float(np.ptp(inner, axis=0).max()))
    return np.array(spreads)


def test_lock_feet_pins_the_stance_soles_of_a_sliding_walk(sliding_walk):
    contact = contacts(sliding_walk)
    assert contact.any(), "the walk should have ground contacts"
    before = _stance_spreads(sliding_walk, contact)
    locked = lock_feet(sliding_walk, contact)
    after = _stance_spreads(locked, contact)
    # measured: median 0.35 cm -> 0.004 cm; worst 0.50 cm -> 0.11 cm (the right heel, rolling)
    assert np.median(after) < 0.05 * np.median(before)
    assert after.max() < 0.3 * before.max()
    assert foot_skate_cm_per_m(locked) < foot_skate_cm_per_m(sliding_walk)


def test_lock_feet_moves_only_the_legs_and_keeps_the_root(sliding_walk):
    contact = contacts(sliding_walk)
    locked = lock_feet(sliding_walk, contact)
    sk = sliding_walk.skeleton
    np.testing.assert_array_equal(locked.root_translation, sliding_walk.root_translation)
    legs = {sk.index(f"{s}_{n}") for s in ("left", "right") for n in ("hip", "knee", "ankle")}
    others = [j for j in range(len(sk.joints)) if j not in legs]
    np.testing.assert_array_equal(locked.rotations[:, others], sliding_walk.rotations[:, others])
    # rotations stay rotations (orthonormal, det +1)
    r = locked.rotations[:, sorted(legs)]
    eye = np.broadcast_to(np.eye(3), r.shape)
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), eye, atol=1e-9)
    # bone lengths are the skeleton's, so the hip still sits where it did
    _, pos0 = global_transforms(sliding_walk)
    _, pos1 = global_transforms(locked)
    hips = [sk.index("left_hip"), sk.index("right_hip")]
    np.testing.assert_allclose(pos1[:, hips], pos0[:, hips], atol=1e-9)


def test_no_contact_leaves_the_motion_unchanged(sliding_walk):
    none = np.zeros((sliding_walk.n_frames, 4), dtype=bool)
    out = lock_feet(sliding_walk, none)
    np.testing.assert_array_equal(out.rotations, sliding_walk.rotations)
