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


def test_canonical_bones_are_the_cmu_librarys_mean_proportions(cmu_dir):
    """CANONICAL_BONES are the mean rest proportions of the library's skeletons (so the
    re-posing changes the library's own features least), rounded to 0.01."""
    from retrieval.library import read_labels

    rows = read_labels(cmu_dir)
    measured = []
    for r in rows:
        sk = (rm.load_motion(r.file, r.skeleton) if r.skeleton else rm.load_motion(r.file)).skeleton
        jm = rm.canonical_joint_map(sk)
        measured.append(rm.body_proportions(rm.rest_positions(sk), jm, leg_length(sk, jm)))
    mean = {k: float(np.mean([m[k] for m in measured])) for k in measured[0]}
    bones = dict(rm.CANONICAL_BONES, trunk=rm.CANONICAL_BONES["lower_spine"] + rm.CANONICAL_BONES["upper_spine"])
    for key, value in mean.items():
        assert bones[key] == pytest.approx(value, abs=0.006), key


@pytest.mark.parametrize("character", ["kid", "robot", "cat"])
def test_cmu_poses_on_the_apps_characters_find_their_trial(cmu_dir, character):
    """CMU trials retargeted onto the app's characters (a child's pose comes from one):
    poses at 1/4, 1/2, 3/4 of jumps, kicks, runs, walks and a dance -- the jumps and
    kicks the canonical body once lost among them -- find their class and mostly their
    own trial in the default pose search over the CMU library."""
    from ar.scene.characters import build_character
    from retrieval.animation import retarget
    from retrieval.library import PoseSearch, read_labels

    search = PoseSearch.build(cmu_dir)
    rows = {r.trial: r for r in read_labels(cmu_dir)}
    target = build_character(character).skeleton
    same_class = same_trial = 0
    trials = ("02_04", "16_01", "49_03", "118_11", "118_25", "10_05", "11_01", "02_03", "127_06", "03_03",
              "07_01", "05_06")
    for trial in trials:
        row = rows[trial]
        moved = retarget(rm.load_motion(row.file, row.skeleton) if row.skeleton else rm.load_motion(row.file), target)
        for frac in (0.25, 0.5, 0.75):
            hit = search.search(search.motion_pose(moved, int(round(frac * (moved.n_frames - 1)))), k=1)[0]
            same_class += hit.label == row.label
            same_trial += hit.trial == trial
    assert same_class >= 0.9 * 3 * len(trials) and same_trial >= 0.6 * 3 * len(trials)


def test_the_pose_sets_floor_is_local_a_step_up_is_not_flight():
    """MR17_CANONICAL takes its floor within a second of each frame: a body standing on a
    box for two seconds stands on the box's floor there (the whole clip's floor would
    make it a jump's apex), while a jump of 0.4 s keeps its height above the ground."""
    from retrieval.library import POSE_FEATURE_SET

    sk = make_skeleton()
    motion = make_motion(sk, frames=180, fps=30.0, arm_swing=0.0, knee_bend=0.0)
    pos = rm.positions(motion)
    jm = rm.canonical_joint_map(sk)
    leg = leg_length(sk, jm)
    lift = np.zeros(len(pos))
    lift[60:120] = 0.4 * leg  # on a box, frames 60-119
    lift[150:162] = 0.4 * leg * np.sin(np.linspace(0, np.pi, 12))  # a jump, 0.4 s in the air
    lifted = pos + lift[:, None, None] * np.array([0.0, 1.0, 0.0])
    fs = get_feature_set("mr17-canonical")
    assert fs.floor_window == 1.0 and fs is get_feature_set(POSE_FEATURE_SET)
    hips = fs.names.index("hips_height")
    local = fs.from_positions(lifted, jm, leg, 30.0)[:, hips]
    whole = replace(fs, floor_window=0.0).from_positions(lifted, jm, leg, 30.0)[:, hips]
    assert local[90] == pytest.approx(local[30], abs=1e-6)  # on the box: standing
    assert whole[90] - whole[30] == pytest.approx(0.4, abs=1e-6)  # the whole clip's floor: "flying"
    apex = 150 + int(np.argmax(lift[150:162]))
    assert local[apex] - local[30] == pytest.approx(lift[apex] / leg, abs=1e-6)  # the jump keeps its height
    with pytest.raises(FeatureError, match="needs the frame rate"):
        fs.from_positions(lifted, jm, leg)
