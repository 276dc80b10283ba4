"""Forbes–Fiume pose vectors (retrieval/features/pose_vectors.py): hips-relative,
heading-aligned, size-normalised, joint-weighted."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.features import JOINT_WEIGHTS, leg_length, pose_frames
from retrieval.motion import CANONICAL_JOINTS, canonical_joint_map, positions
from tests.support.synthetic_motion import make_motion, make_skeleton


@pytest.fixture(scope="module")
def walk():
    sk = make_skeleton()
    motion = make_motion(sk, frames=40, arm_swing=35, knee_bend=25, bounce=0.03)
    jm = canonical_joint_map(sk)
    return positions(motion), jm, leg_length(sk, jm)


def _turn(pos: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Rotate (T, J, 3) positions about the vertical (Y) by a per-frame angle."""
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    x, z = pos[..., 0], pos[..., 2]
    return np.stack([c * x + s * z, pos[..., 1], -s * x + c * z], axis=-1)


def test_shape_and_hips_at_the_origin(walk):
    pos, jm, size = walk
    v = pose_frames(pos, jm, size)
    assert v.shape == (len(pos), 3 * len(CANONICAL_JOINTS))
    hips = CANONICAL_JOINTS.index("hips")
    assert np.all(v.reshape(len(pos), -1, 3)[:, hips] == 0.0)


def test_heading_invariance(walk):
    pos, jm, size = walk
    rng = np.random.default_rng(0)
    yaw = rng.uniform(-np.pi, np.pi, size=len(pos))  # a different heading every frame
    moved = _turn(pos, yaw) + np.array([3.0, 0.0, -2.0])  # and somewhere else on the floor
    np.testing.assert_allclose(pose_frames(moved, jm, size), pose_frames(pos, jm, size), atol=1e-9)


def test_scale_invariance_when_body_size_scales_too(walk):
    pos, jm, size = walk
    np.testing.assert_allclose(pose_frames(pos * 0.07, jm, size * 0.07), pose_frames(pos, jm, size), atol=1e-9)
    np.testing.assert_allclose(pose_frames(pos, jm, 2 * size), pose_frames(pos, jm, size) / 2, atol=1e-12)


def test_not_invariant_to_tilting(walk):
    """Only turns about the vertical are factored out: a body lying down is another pose."""
    pos, jm, size = walk
    tilt = pos.copy()
    tilt[..., 1], tilt[..., 2] = pos[..., 2], -pos[..., 1]
    assert np.abs(pose_frames(tilt, jm, size) - pose_frames(pos, jm, size)).max() > 0.1


def test_joints_are_weighted_by_the_square_root_of_their_importance(walk):
    pos, jm, size = walk
    v = pose_frames(pos, jm, size).reshape(len(pos), -1, 3)
    unweighted = v / np.sqrt([JOINT_WEIGHTS[n] for n in CANONICAL_JOINTS])[None, :, None]
    # unweighted, each joint's distance from the hips is the body's, in body-size units
    hips = jm["hips"]
    for k, name in enumerate(CANONICAL_JOINTS):
        want = np.linalg.norm(pos[:, jm[name]] - pos[:, hips], axis=1) / size
        np.testing.assert_allclose(np.linalg.norm(unweighted[:, k], axis=1), want, atol=1e-9)
    assert set(JOINT_WEIGHTS) == set(CANONICAL_JOINTS)
    assert all(0 < w <= 1 for w in JOINT_WEIGHTS.values())


def test_the_hips_face_plus_z_after_alignment(walk):
    pos, jm, size = walk
    v = pose_frames(_turn(pos, np.full(len(pos), 1.1)), jm, size).reshape(len(pos), -1, 3)
    left, right = CANONICAL_JOINTS.index("left_hip"), CANONICAL_JOINTS.index("right_hip")
    across = v[:, left] - v[:, right]
    assert np.all(across[:, 0] > 0) and np.allclose(across[:, 2], 0.0, atol=1e-9)  # left hip on +X
