"""Per-frame features: the 17 pairs, body-size and skeleton invariance, registry."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.features.relational import (
    MR17, FeatureError, FeatureSet, FeatureSpec, get_feature_set, leg_length, motion_features,
    register_feature_set,
)
from tests.support.synthetic_motion import make_motion, make_skeleton


def test_seventeen_named_features():
    assert MR17.dim == 17 and len(set(MR17.names)) == 17
    assert get_feature_set("mr17") is MR17


def test_values_on_the_rest_like_first_frame():
    sk = make_skeleton()
    f = motion_features(make_motion(sk, frames=2, arm_swing=0, knee_bend=0))
    legs = leg_length(sk)
    assert legs == pytest.approx(0.82)
    names = MR17.names
    # hands hang at x = ±18 cm: 36 cm apart; hips joints at ±9 cm
    assert f[0, names.index("hand_hand")] == pytest.approx(0.36 / legs)
    assert f[0, names.index("ankle_ankle")] == pytest.approx(0.18 / legs)
    assert f[0, names.index("lankle_lhip")] == pytest.approx(0.82 / legs)
    # hands 53 cm below the shoulder line, head 5 + 10 cm above it
    assert f[0, names.index("lhand_above_head")] == pytest.approx(-(0.53 + 0.15) / legs)
    # left hand 36 cm across and 53 cm below the right shoulder
    assert f[0, names.index("lhand_rshoulder")] == pytest.approx(np.hypot(0.36, 0.53) / legs)


def test_invariant_to_body_size_heading_and_up_axis():
    base = motion_features(make_motion(make_skeleton(1.0)))
    child = motion_features(make_motion(make_skeleton(0.6)))
    turned = motion_features(make_motion(make_skeleton(1.0), heading_deg=70))
    z_up = motion_features(make_motion(make_skeleton(1.0, up_axis="z")))
    for other in (child, turned, z_up):
        assert np.allclose(base, other, atol=1e-9)


def test_features_distinguish_different_motions():
    sk = make_skeleton()
    walk = motion_features(make_motion(sk, arm_swing=20, knee_bend=15))
    run = motion_features(make_motion(sk, arm_swing=60, knee_bend=45, bounce=0.1))
    assert np.abs(walk - run).max() > 0.2


def test_registry_accepts_a_new_set_and_rejects_bad_specs():
    small = register_feature_set(FeatureSet("test_hands", (FeatureSpec("hh", "distance", ("left_hand", "right_hand")),)))
    f = motion_features(make_motion(make_skeleton()), "test_hands")
    assert f.shape == (60, 1)
    assert np.allclose(f[:, 0], motion_features(make_motion(make_skeleton()))[:, 0])
    assert get_feature_set(small) is small
    with pytest.raises(FeatureError):
        register_feature_set(FeatureSet("bad", (FeatureSpec("x", "distance", ("head",)),)))
    with pytest.raises(FeatureError):
        get_feature_set("nope")


def test_same_trial_on_acclaim_and_cc_base_skeletons_gives_close_features(cmu_dir):
    motion_io = pytest.importorskip("retrieval.motion.formats.dispatch")
    from retrieval.motion import resample

    amc = motion_io.load_motion(cmu_dir / "extra" / "01_01.amc", cmu_dir / "asf" / "01.asf")
    bvh = motion_io.load_motion(cmu_dir / "extra" / "01_01.bvh")
    fa = motion_features(resample(amc, 30.0))
    fb = motion_features(resample(bvh, 30.0))
    # The BVH may start with a converter T-pose frame: align by the best offset of a few
    # frames, then compare every feature over the clip (the BVH drops the thorax bone,
    # which moves the upper body; the features are chosen to be blind to that).
    n = min(len(fa), len(fb)) - 10
    errs = [np.abs(fa[5:5 + n] - fb[5 + s:5 + s + n]).max(axis=0) for s in range(-5, 6)]
    best = min(errs, key=lambda e: e.max())
    spread = fa.std(axis=0)
    assert np.all(best < 0.05 * spread), dict(zip(MR17.names, (best / spread).round(3)))


def test_lowest_kind_reads_the_lower_foot_above_the_floor():
    """"lowest": one foot raised (a kick, a step) keeps it 0; both raised (a flight) lifts it."""
    fs = register_feature_set(FeatureSet("test_lowest", (
        FeatureSpec("lower_ankle_height", "lowest", ("left_ankle", "right_ankle")),
        FeatureSpec("lankle_height", "height", ("left_ankle",)))))
    joints = ["left_ankle", "right_ankle", "left_toe", "right_toe"]
    jm = {n: i for i, n in enumerate(joints)}
    # 10 frames: standing (0-3), left foot kicked 0.5 m (4-6), both feet 0.3 m up (7-9)
    left = np.array([0, 0, 0, 0, .5, .5, .5, .3, .3, .3])
    right = np.array([0, 0, 0, 0, 0, 0, 0, .3, .3, .3])
    pos = np.zeros((10, 4, 3))
    pos[:, 0, 1], pos[:, 2, 1] = left, left
    pos[:, 1, 1], pos[:, 3, 1] = right, right
    f = fs.from_positions(pos, jm, body_size=0.5)
    assert np.allclose(f[:, 0], np.minimum(left, right) / 0.5)
    assert np.allclose(f[:, 1], left / 0.5)
    assert fs.joints_used() >= set(joints)
