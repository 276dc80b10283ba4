"""The canonical body re-posing (retrieval.motion.canonical_pose) and the feature sets
that use it (FeatureSet.body = "canonical"): a skeleton's proportions, joint placement
along its bones and toe pitch drop out; the posture stays."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import retrieval.motion as rm
from retrieval.features import MR17, FeatureError, get_feature_set
from retrieval.features.relational import leg_length
from tests.support.synthetic_motion import make_motion, make_skeleton

CANONICAL_MR17 = replace(MR17, name="mr17-canonical-test", body="canonical")


def _reproportioned(sk: rm.Skeleton, factors: dict[str, float]) -> rm.Skeleton:
    """The same joints and rest directions, some bones longer or shorter (factor per joint:
    its offset from the parent is scaled)."""
    joints = [rm.Joint(j.name, j.parent, j.offset * factors.get(j.name, 1.0), list(j.channels), j.rotation_order)
              for j in sk.joints]
    return rm.Skeleton(joints, sk.metres_per_unit, sk.up_axis, "other")


def _features(motion: rm.Motion, fs) -> np.ndarray:
    jm = rm.canonical_joint_map(motion.skeleton)
    return fs.from_positions(rm.positions(motion), jm, leg_length(motion.skeleton, jm), motion.fps,
                             rm.rest_positions(motion.skeleton))


def test_canonical_rest_has_the_canonical_bone_lengths():
    rest = rm.canonical_rest()
    bone = {c: float(np.linalg.norm(rest[rm.CANONICAL_INDEX[c]] - rest[rm.CANONICAL_INDEX[rm.CANONICAL_PARENTS[c]]]))
            for c in rm.CANONICAL_JOINTS[1:]}
    assert bone["left_knee"] == pytest.approx(rm.CANONICAL_BONES["thigh"])
    assert bone["left_ankle"] + bone["left_knee"] == pytest.approx(1.0)  # lengths are in leg lengths
    assert bone["right_elbow"] == pytest.approx(rm.CANONICAL_BONES["upper_arm"])
    assert bone["head"] == pytest.approx(rm.CANONICAL_BONES["head"])


def test_other_proportions_give_the_same_canonical_pose_and_features():
    """Arms 1.4x, spine 0.7x, a head joint twice as far up the neck, wider hips, a
    longer foot: the file's own features change, the canonical ones do not."""
    sk = make_skeleton()
    other = _reproportioned(sk, {"LeftForeArm": 1.4, "RightForeArm": 1.4, "LeftHand": 1.4, "RightHand": 1.4,
                                 "Neck": 0.7, "Head": 2.0, "LeftUpLeg": 1.5, "RightUpLeg": 1.5,
                                 "LeftToeBase": 1.6, "RightToeBase": 1.6})
    kw = dict(frames=50, arm_swing=50.0, knee_bend=30.0, bounce=0.05, heading_deg=30.0)
    a, b = make_motion(sk, **kw), make_motion(other, **kw)
    pa = rm.canonical_pose(rm.positions(a), rm.canonical_joint_map(sk), leg_length(sk))
    pb = rm.canonical_pose(rm.positions(b), rm.canonical_joint_map(other), leg_length(other))
    assert pa.shape == (50, len(rm.CANONICAL_JOINTS), 3)
    hips = rm.CANONICAL_INDEX["hips"]
    # the body about its pelvis centre (where the pelvis is depends on the rig's root; heights use the floor)
    np.testing.assert_allclose(pa - pa[:, hips:hips + 1], pb - pb[:, hips:hips + 1], atol=1e-9)
    # the posture is kept: bone lengths are the canonical ones in every frame
    thigh = np.linalg.norm(pa[:, rm.CANONICAL_INDEX["left_knee"]] - pa[:, rm.CANONICAL_INDEX["left_hip"]], axis=1)
    np.testing.assert_allclose(thigh, rm.CANONICAL_BONES["thigh"])
    np.testing.assert_allclose(_features(a, CANONICAL_MR17), _features(b, CANONICAL_MR17), atol=1e-9)
    source_gap = np.abs(_features(a, MR17) - _features(b, MR17)).max()
    assert source_gap > 0.1  # what the re-posing removes


def test_a_different_posture_still_differs():
    sk = make_skeleton()
    walk = _features(make_motion(sk, arm_swing=20.0, knee_bend=15.0), CANONICAL_MR17)
    run = _features(make_motion(sk, arm_swing=70.0, knee_bend=50.0, bounce=0.1), CANONICAL_MR17)
    assert np.abs(walk - run).mean() > 0.05


def test_canonical_body_needs_every_canonical_joint_and_a_known_body():
    sk = make_skeleton()
    pos = rm.positions(make_motion(sk, frames=5))
    jm = rm.canonical_joint_map(sk)
    partial = {k: v for k, v in jm.items() if k != "spine"}
    with pytest.raises(FeatureError, match="re-poses the canonical body: it needs joints spine"):
        CANONICAL_MR17.from_positions(pos, partial, 1.0)
    with pytest.raises(FeatureError, match="unknown body 'giant'"):
        replace(MR17, body="giant").from_positions(pos, jm, 1.0)
    assert get_feature_set("storybeam").body in ("source", "canonical")
