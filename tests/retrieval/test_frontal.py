"""The frontal feature set (:mod:`retrieval.features.frontal`): registered, the clip's
mean heading is what a body facing +Z calls 0, the features do not change when the
performer turns or walks elsewhere, and depth does not enter them while it does enter
the 3-D set; the measured rest pose keeps the clip's bone lengths."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.features import (
    FRONTAL,
    MR17,
    FeatureError,
    available_feature_sets,
    face_camera,
    get_feature_set,
    leg_length,
    mean_heading,
    motion_features,
)
from retrieval.features.frontal import measured_rest
from retrieval.motion import CANONICAL_PARENTS, canonical_joint_map, positions, rest_positions
from tests.support.synthetic_motion import make_motion, make_skeleton


def _clip(heading_deg: float = 0.0, **kw) -> tuple[np.ndarray, dict[str, int], float, np.ndarray]:
    sk = make_skeleton()
    m = make_motion(sk, heading_deg=heading_deg, **kw)
    jm = canonical_joint_map(sk)
    return positions(m), jm, leg_length(sk, jm), rest_positions(sk)


def test_registered_with_mr17_columns():
    assert "frontal" in available_feature_sets()
    fs = get_feature_set("frontal")
    assert fs is FRONTAL and fs.names == MR17.names and fs.dim == 17
    assert fs.normalise == "arms"


def test_mean_heading_of_a_body_facing_the_camera_is_zero_and_follows_turns():
    pos, jm, _, _ = _clip(0.0)
    base = mean_heading(pos, jm)
    for turn in (30.0, -75.0, 160.0):
        pos_t, _, _, _ = _clip(turn)
        got = np.degrees(mean_heading(pos_t, jm) - base)
        assert abs((got - turn + 180) % 360 - 180) < 1.0, (turn, got)
    # the synthetic body faces +Z with its left on +X: heading 0
    left, right = pos[0, jm["left_hip"]], pos[0, jm["right_hip"]]
    assert left[0] > right[0]
    assert abs(np.degrees(base)) < 5.0


def test_face_camera_drops_depth_and_turns_to_heading_zero():
    pos, jm, _, _ = _clip(50.0)
    out = face_camera(pos, jm)
    assert np.all(out[..., 2] == 0.0)
    kept = face_camera(pos, jm, keep_depth=True)
    assert abs(mean_heading(kept, jm)) < 1e-9
    np.testing.assert_allclose(kept[..., 1], pos[..., 1])  # a turn about the vertical keeps heights


def test_features_invariant_to_heading_and_place():
    pos, jm, leg, rest = _clip(0.0)
    base = FRONTAL.from_positions(pos, jm, leg, 30.0, rest)
    for turn in (35.0, -120.0):
        pos_t, _, _, _ = _clip(turn)
        shifted = pos_t + np.array([1.5, 0.0, -2.0])
        np.testing.assert_allclose(FRONTAL.from_positions(shifted, jm, leg, 30.0, rest), base, atol=1e-9)


def test_depth_does_not_enter_but_does_in_3d():
    pos, jm, leg, rest = _clip(0.0, arm_swing=50.0)
    moved = pos.copy()
    moved[:, jm["left_hand"], 2] += 0.3  # the hand 30 cm nearer the camera
    np.testing.assert_allclose(FRONTAL.from_positions(moved, jm, leg, 30.0, rest),
                               FRONTAL.from_positions(pos, jm, leg, 30.0, rest))
    assert not np.allclose(MR17.from_positions(moved, jm, leg, 30.0, rest), MR17.from_positions(pos, jm, leg, 30.0, rest))


def test_motion_features_through_the_registry_and_errors():
    sk = make_skeleton()
    f = motion_features(make_motion(sk), "frontal")
    assert f.shape == (60, 17) and np.all(np.isfinite(f))
    with pytest.raises(FeatureError, match="positions must be"):
        FRONTAL.from_positions(np.zeros((4, 3)), canonical_joint_map(sk), 1.0)
    with pytest.raises(FeatureError, match="needs joints"):
        FRONTAL.from_positions(np.zeros((4, 3, 3)), {"hips": 0}, 1.0)


def test_measured_rest_keeps_bone_lengths():
    pos, jm, _, rest = _clip(20.0)
    got = measured_rest(pos, jm)
    for joint, parent in CANONICAL_PARENTS.items():
        if parent is None:
            continue
        want = np.linalg.norm(rest[jm[joint]] - rest[jm[parent]])
        assert abs(np.linalg.norm(got[jm[joint]] - got[jm[parent]]) - want) < 1e-6, joint
