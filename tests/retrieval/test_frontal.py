"""The frontal feature set (:mod:`retrieval.features.frontal`): registered, the clip's
mean heading is what a body facing +Z calls 0, the features do not change when the
performer turns or walks elsewhere, and depth does not enter them while it does enter
the 3-D set; the measured rest pose keeps the clip's bone lengths; the ankle–hip
distances are relative to their median over the segment."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.features import (
    FRONTAL,
    MR17,
    FeatureError,
    FrontalFeatureSet,
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


def test_ankle_hip_distances_are_relative_to_the_segment():
    """A body whose knees are read in the wrong place has a long measured leg length:
    per that length its legs look bent. The ankle–hip distances are therefore per their
    median over the segment, so they do not depend on the length they were divided by;
    the other leg features still do."""
    pos, jm, leg, rest = _clip(0.0, knee_bend=40.0)
    assert FRONTAL.relative == ("lankle_lhip", "rankle_rhip")
    ah = [FRONTAL.names.index(n) for n in FRONTAL.relative]
    hips = FRONTAL.names.index("hips_height")
    f = FRONTAL.from_positions(pos, jm, leg, 30.0, rest)
    f_long = FRONTAL.from_positions(pos, jm, 1.3 * leg, 30.0, rest)  # the leg measured 30 % long
    np.testing.assert_allclose(f_long[:, ah], f[:, ah], rtol=1e-12)
    np.testing.assert_allclose(f_long[:, hips] * 1.3, f[:, hips], rtol=1e-12)
    assert np.median(f[:, ah].mean(axis=1)) == pytest.approx(1.0)
    assert np.ptp(f[:, ah]) > 0.05  # the knee bend is still seen, relative to the usual extension
    # idempotent: a window of a relative clip made relative again is the window made relative alone
    np.testing.assert_allclose(FRONTAL.relative_to_segment(f), f, rtol=1e-12)
    raw = get_feature_set("frontal_legs").from_positions(pos, jm, leg, 30.0, rest)
    np.testing.assert_allclose(FRONTAL.relative_to_segment(f[10:40])[:, ah],
                               FRONTAL.relative_to_segment(raw[10:40])[:, ah], rtol=1e-12)
    with pytest.raises(FeatureError, match="relative features nope"):
        FrontalFeatureSet(name="bad", specs=MR17.specs, relative=("nope",))
    with pytest.raises(FeatureError, match=r"\(T, 17\)"):
        FRONTAL.relative_to_segment(np.zeros((5, 3)))
