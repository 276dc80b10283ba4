"""The canonical body map: name conventions, the topology/rest-pose fallback, refusals."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from retrieval.features import motion_features
from retrieval.motion import Joint, Motion, Skeleton, canonical_joint_map, load_motion, save_bvh
from retrieval.motion.body import JointMapError, split_side
from retrieval.motion.topology import TopologyError, topology_joint_map
from tests.support.synthetic_motion import make_motion, make_skeleton

ROT = ["Zrotation", "Yrotation", "Xrotation"]
# world (Y up) -> native Z up: the inverse of kinematics' Z-up-to-Y-up matrix.
_Z_UP_FROM_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]).T


def _chain_skeleton(rows: list[tuple[str, str | None]]) -> Skeleton:
    """A skeleton from (name, parent name) rows; offsets are irrelevant for name maps."""
    idx: dict[str, int] = {}
    joints = []
    for name, parent in rows:
        idx[name] = len(joints)
        joints.append(Joint(name, -1 if parent is None else idx[parent], np.array([0.0, 1.0, 0.0]), ROT))
    return Skeleton(joints)


def _sided(template: list[tuple[str, str | None]], left: str, right: str) -> list[tuple[str, str | None]]:
    out = []
    for side in (left, right):
        for n, p in template:
            out.append((n.format(s=side), None if p is None else p.format(s=side)))
    return out


def _named(sk: Skeleton) -> dict[str, str]:
    return {k: sk.names[v] for k, v in canonical_joint_map(sk).items()}


CONVENTIONS = {
    "mixamo": (
        [("mixamorig:Hips", None), ("mixamorig:Spine", "mixamorig:Hips"), ("mixamorig:Spine1", "mixamorig:Spine"),
         ("mixamorig:Spine2", "mixamorig:Spine1"), ("mixamorig:Neck", "mixamorig:Spine2"),
         ("mixamorig:Head", "mixamorig:Neck")]
        + _sided([("mixamorig:{s}Shoulder", "mixamorig:Spine2"), ("mixamorig:{s}Arm", "mixamorig:{s}Shoulder"),
                  ("mixamorig:{s}ForeArm", "mixamorig:{s}Arm"), ("mixamorig:{s}Hand", "mixamorig:{s}ForeArm"),
                  ("mixamorig:{s}UpLeg", "mixamorig:Hips"), ("mixamorig:{s}Leg", "mixamorig:{s}UpLeg"),
                  ("mixamorig:{s}Foot", "mixamorig:{s}Leg"), ("mixamorig:{s}ToeBase", "mixamorig:{s}Foot")],
                 "Left", "Right"),
        {"hips": "mixamorig:Hips", "spine": "mixamorig:Spine2", "neck": "mixamorig:Neck",
         "left_shoulder": "mixamorig:LeftArm", "left_elbow": "mixamorig:LeftForeArm", "left_hand": "mixamorig:LeftHand",
         "right_knee": "mixamorig:RightLeg", "right_ankle": "mixamorig:RightFoot", "right_toe": "mixamorig:RightToeBase"},
    ),
    "smpl": (
        [("Pelvis", None), ("Spine1", "Pelvis"), ("Spine2", "Spine1"), ("Spine3", "Spine2"), ("Neck", "Spine3"),
         ("Head", "Neck")]
        + _sided([("{s}_Hip", "Pelvis"), ("{s}_Knee", "{s}_Hip"), ("{s}_Ankle", "{s}_Knee"), ("{s}_Foot", "{s}_Ankle"),
                  ("{s}_Collar", "Spine3"), ("{s}_Shoulder", "{s}_Collar"), ("{s}_Elbow", "{s}_Shoulder"),
                  ("{s}_Wrist", "{s}_Elbow"), ("{s}_Hand", "{s}_Wrist")], "L", "R"),
        {"hips": "Pelvis", "neck": "Neck", "head": "Head", "left_hip": "L_Hip", "left_knee": "L_Knee",
         "left_ankle": "L_Ankle", "left_toe": "L_Foot", "right_shoulder": "R_Shoulder", "right_elbow": "R_Elbow",
         "right_hand": "R_Wrist"},
    ),
    "biovision": (
        [("Hips", None), ("Chest", "Hips"), ("Neck", "Chest"), ("Head", "Neck")]
        + _sided([("{s}Collar", "Chest"), ("{s}UpArm", "{s}Collar"), ("{s}LowArm", "{s}UpArm"),
                  ("{s}Hand", "{s}LowArm"), ("{s}UpLeg", "Hips"), ("{s}LowLeg", "{s}UpLeg"),
                  ("{s}Foot", "{s}LowLeg"), ("{s}Toe", "{s}Foot")], "Left", "Right"),
        {"hips": "Hips", "spine": "Chest", "left_shoulder": "LeftUpArm", "left_elbow": "LeftLowArm",
         "right_knee": "RightLowLeg", "right_ankle": "RightFoot", "right_toe": "RightToe"},
    ),
    "character_creator": (
        [("RL_BoneRoot", None), ("CC_Base_Hip", "RL_BoneRoot"), ("CC_Base_Pelvis", "CC_Base_Hip"),
         ("CC_Base_Waist", "CC_Base_Hip"), ("CC_Base_Spine01", "CC_Base_Waist"), ("CC_Base_Spine02", "CC_Base_Spine01"),
         ("CC_Base_NeckTwist01", "CC_Base_Spine02"), ("CC_Base_Head", "CC_Base_NeckTwist01")]
        + _sided([("CC_Base_{s}_Thigh", "CC_Base_Pelvis"), ("CC_Base_{s}_Calf", "CC_Base_{s}_Thigh"),
                  ("CC_Base_{s}_Foot", "CC_Base_{s}_Calf"), ("CC_Base_{s}_ToeBase", "CC_Base_{s}_Foot"),
                  ("CC_Base_{s}_Clavicle", "CC_Base_Spine02"), ("CC_Base_{s}_Upperarm", "CC_Base_{s}_Clavicle"),
                  ("CC_Base_{s}_Forearm", "CC_Base_{s}_Upperarm"), ("CC_Base_{s}_Hand", "CC_Base_{s}_Forearm")],
                 "L", "R"),
        {"hips": "CC_Base_Hip", "spine": "CC_Base_Spine02", "left_shoulder": "CC_Base_L_Upperarm",
         "right_knee": "CC_Base_R_Calf", "left_toe": "CC_Base_L_ToeBase"},
    ),
    # MocapNET's MakeHuman hybrid (the CMU conversion in AmmarkoV/RGBDAcquisition): side
    # letters glued to lower-case words, a collar and a buttock before the limbs, face
    # joints with ".l" suffixes and "__" helpers, five toes per foot.
    "makehuman": (
        [("hip", None), ("abdomen", "hip"), ("chest", "abdomen"), ("neck", "chest"), ("neck1", "neck"),
         ("head", "neck1"), ("__jaw", "head"), ("jaw", "__jaw"), ("eye.l", "head"), ("eye.r", "head"),
         ("orbicularis03.l", "head")]
        + _sided([("{s}collar", "chest"), ("{s}shoulder", "{s}collar"), ("{s}elbow", "{s}shoulder"),
                  ("{s}hand", "{s}elbow"), ("__{s}thumb", "{s}hand"), ("{s}thumb", "__{s}thumb"),
                  ("{s}buttock", "hip"), ("{s}hip", "{s}buttock"), ("{s}knee", "{s}hip"), ("{s}foot", "{s}knee")],
                 "l", "r")
        + [(f"toe{t}-{k}.{s}", "lfoot" if s == "l" else "rfoot") for s in "lr" for t in (1, 2) for k in (1, 2)],
        {"hips": "hip", "spine": "chest", "neck": "neck", "head": "head", "left_shoulder": "lshoulder",
         "left_elbow": "lelbow", "right_hand": "rhand", "left_hip": "lhip", "right_knee": "rknee",
         "left_ankle": "lfoot", "left_toe": "toe1-1.l", "right_toe": "toe1-1.r"},
    ),
}


@pytest.mark.parametrize("convention", sorted(CONVENTIONS))
def test_named_conventions_resolve(convention):
    rows, expected = CONVENTIONS[convention][0], CONVENTIONS[convention][1]
    got = _named(_chain_skeleton(rows))
    assert len(got) == 18
    assert {k: got[k] for k in expected} == expected


def test_biovision_foot_without_toe_joint_uses_its_end_site():
    rows = [r for r in CONVENTIONS["biovision"][0] if not r[0].endswith("Toe")]
    sk = _chain_skeleton(rows)
    joints = list(sk.joints)
    for side in ("Left", "Right"):
        joints.append(Joint(f"{side}Foot_end", sk.index(f"{side}Foot"), np.array([0.0, -3.0, 10.0]), []))
    got = _named(Skeleton(joints))
    assert (got["left_toe"], got["right_toe"]) == ("LeftFoot_end", "RightFoot_end")


def test_poser_daz_camel_case_sides_resolve():
    # cgspeed's Daz-friendly CMU release: "lShldr", "rForeArm", "lThigh", "rShin"; the feet
    # end in end sites; "lCollar" and "lButtock" are not the shoulder or the hip.
    rows = [("hip", None), ("abdomen", "hip"), ("chest", "abdomen"), ("neck", "chest"), ("head", "neck"),
            ("leftEye", "head"), ("rightEye", "head")]
    rows += _sided([("{s}Collar", "chest"), ("{s}Shldr", "{s}Collar"), ("{s}ForeArm", "{s}Shldr"),
                    ("{s}Hand", "{s}ForeArm"), ("{s}Thumb1", "{s}Hand"), ("{s}Buttock", "hip"),
                    ("{s}Thigh", "{s}Buttock"), ("{s}Shin", "{s}Thigh"), ("{s}Foot", "{s}Shin")], "l", "r")
    sk = _chain_skeleton(rows)
    joints = list(sk.joints)
    for side in "lr":
        joints.append(Joint(f"{side}Foot_end", sk.index(f"{side}Foot"), np.array([0.0, -3.0, 10.0]), []))
    got = _named(Skeleton(joints))
    assert got == {"hips": "hip", "spine": "chest", "neck": "neck", "head": "head",
                   "left_shoulder": "lShldr", "left_elbow": "lForeArm", "left_hand": "lHand",
                   "right_shoulder": "rShldr", "right_elbow": "rForeArm", "right_hand": "rHand",
                   "left_hip": "lThigh", "left_knee": "lShin", "left_ankle": "lFoot", "left_toe": "lFoot_end",
                   "right_hip": "rThigh", "right_knee": "rShin", "right_ankle": "rFoot", "right_toe": "rFoot_end"}


@pytest.mark.parametrize("name,side_base", [
    ("lShldr", ("left", "shldr")), ("rForeArm", ("right", "forearm")), ("lelbow", ("left", "elbow")),
    ("rbuttock", ("right", "buttock")), ("toe1-1.l", ("left", "toe11")), ("lowerback", (None, "lowerback")),
    ("LowerBack", (None, "lowerback")), ("leftEye", ("left", "eye")), ("rootTransform", (None, "roottransform")),
    ("lfemur", ("left", "femur")), ("LHipJoint", ("left", "hipjoint")),
])
def test_side_letters_glued_to_a_word_are_sides_only_before_body_words(name, side_base):
    assert split_side(name) == side_base


def test_real_skeletons_resolve_by_name(cmu_dir):
    assert _named(load_motion(cmu_dir / "amc" / "02_01.amc").skeleton)["left_shoulder"] == "lhumerus"
    bandai = Path(cmu_dir).parent / "bandai2" / "bvh"
    if not bandai.is_dir():
        pytest.skip("bandai2 not found")
    got = _named(load_motion(sorted(bandai.glob("*.bvh"))[0]).skeleton)
    assert (got["hips"], got["spine"], got["left_shoulder"], got["right_toe"]) == (
        "Hips", "Chest", "UpperArm_L", "Toes_R")


# ------------------------------------------------------------------ topology fallback
def _transformed(sk: Skeleton, names: list[str] | None = None, scale: float = 1.0, z_up: bool = False,
                 keep: list[int] | None = None) -> Skeleton:
    """``sk`` renamed / rescaled / turned Z-up, optionally keeping only joints ``keep``."""
    b = _Z_UP_FROM_WORLD if z_up else np.eye(3)
    keep = list(range(sk.n_joints)) if keep is None else keep
    new = {old: i for i, old in enumerate(keep)}
    joints = []
    for old in keep:
        j = sk.joints[old]
        joints.append(Joint(names[old] if names else j.name, -1 if j.parent < 0 else new[j.parent],
                            scale * (b @ j.offset), list(j.channels), j.rotation_order))
    return Skeleton(joints, sk.metres_per_unit / scale, "z" if z_up else sk.up_axis, sk.name)


def _retransform(m: Motion, sk: Skeleton, z_up: bool, scale: float) -> Motion:
    b = _Z_UP_FROM_WORLD if z_up else np.eye(3)
    rot = b @ m.rotations @ b.T
    return Motion(sk, rot, scale * m.root_translation @ b.T, m.fps, m.name)


def _renamed(sk: Skeleton) -> list[str]:
    return [f"j{i}" for i in range(sk.n_joints)]


def _subtree(sk: Skeleton, root: int) -> set[int]:
    out = {root}
    for k in range(root + 1, sk.n_joints):
        if sk.joints[k].parent in out:
            out.add(k)
    return out


@pytest.mark.parametrize("z_up,scale", [(False, 1.0), (True, 1.0), (True, 2.54), (False, 0.01)])
def test_renamed_cmu_maps_like_names_and_features_agree(cmu_dir, z_up, scale):
    m = load_motion(cmu_dir / "amc" / "02_01.amc")
    by_names = canonical_joint_map(m.skeleton)
    sk = _transformed(m.skeleton, _renamed(m.skeleton), scale, z_up)
    assert topology_joint_map(sk) == by_names  # the shape alone gives the same joints
    assert canonical_joint_map(sk) == by_names
    m2 = _retransform(m.slice(0, 240), sk, z_up, scale)
    a = motion_features(m.slice(0, 240), "storybeam")
    b = motion_features(m2, "storybeam")
    np.testing.assert_allclose(b, a, atol=1e-9)


def test_renamed_synthetic_body_maps_like_names():
    sk = make_skeleton()
    by_names = canonical_joint_map(sk)
    assert topology_joint_map(_transformed(sk, _renamed(sk), 3.0, True)) == by_names
    m = make_motion(sk, frames=120)
    sk2 = _transformed(sk, _renamed(sk))
    np.testing.assert_allclose(
        motion_features(Motion(sk2, m.rotations, m.root_translation, m.fps), "storybeam"),
        motion_features(m, "storybeam"), atol=1e-12)


def test_mirrored_names_do_not_fool_the_shape():
    # A body whose "Left" joints are on its right: by shape, sides follow the geometry.
    sk = make_skeleton()
    names = [n.replace("Left", "@").replace("Right", "Left").replace("@", "Right") for n in sk.names]
    swapped = topology_joint_map(_transformed(sk, names))
    assert swapped == canonical_joint_map(sk)


# ------------------------------------------------------------------ refusals
def test_cmu_without_arms_is_refused_naming_the_missing_joints(cmu_dir):
    sk = load_motion(cmu_dir / "amc" / "02_01.amc").skeleton
    arms = _subtree(sk, sk.index("lclavicle")) | _subtree(sk, sk.index("rclavicle"))
    keep = [i for i in range(sk.n_joints) if i not in arms]
    for names in (None, _renamed(sk)):
        with pytest.raises(JointMapError) as err:
            canonical_joint_map(_transformed(sk, names, keep=keep))
        msg = str(err.value)
        for part in ("left_shoulder", "left_elbow", "left_hand", "right_shoulder", "right_elbow", "right_hand"):
            assert part in msg
        assert "limbs" in msg  # and says why the shape did not help


def test_degenerate_and_ambiguous_skeletons_are_refused():
    sk = make_skeleton()
    flat = Skeleton([Joint(f"j{i}", j.parent, np.zeros(3), ROT) for i, j in enumerate(sk.joints)])
    with pytest.raises(TopologyError, match="degenerate"):
        topology_joint_map(flat)
    with pytest.raises(JointMapError, match="degenerate"):
        canonical_joint_map(flat)
    # Toes pointing straight down: no forward direction, so left and right are unknowable.
    joints = [Joint(f"j{i}", j.parent, j.offset.copy(), ROT) for i, j in enumerate(sk.joints)]
    for k in (sk.index("LeftToeBase"), sk.index("RightToeBase")):
        joints[k].offset = np.array([0.0, -12.0, 0.0])
    with pytest.raises(JointMapError, match="left from right"):
        canonical_joint_map(Skeleton(joints))
    # Head as long as the arms: which limb is the head is ambiguous.
    joints = [Joint(f"j{i}", j.parent, j.offset.copy(), ROT) for i, j in enumerate(sk.joints)]
    joints[sk.index("Head")].offset = np.array([0.0, 60.0, 0.0])
    with pytest.raises(JointMapError, match="head from the arms"):
        canonical_joint_map(Skeleton(joints))


def test_renamed_z_up_cmu_survives_a_bvh_round_trip(cmu_dir, tmp_path):
    # Written by StoryBeam's BVH writer with joints j0..jN, Z up, another unit, and read
    # back with up axis and units detected: same joints, same features.
    from retrieval.motion import save_bvh

    m = load_motion(cmu_dir / "amc" / "02_01.amc").slice(0, 240)
    sk = _transformed(m.skeleton, _renamed(m.skeleton), 2.54, True)
    back = load_motion(save_bvh(_retransform(m, sk, True, 2.54), tmp_path / "renamed.bvh"))
    assert back.skeleton.up_axis == "z"
    assert canonical_joint_map(back.skeleton) == canonical_joint_map(m.skeleton)
    np.testing.assert_allclose(motion_features(back, "storybeam"), motion_features(m, "storybeam"), atol=1e-6)


@pytest.mark.parametrize("style", ["daz", "makehuman"])
def test_poser_and_makehuman_named_bvh_loads_with_the_same_features(tmp_path, style):
    # The synthetic body written as a BVH under Poser/Daz names (lShldr, rShin, lToe) or
    # MakeHuman/MocapNET names (lshoulder, rknee, toe1-1.l) and read back: same canonical
    # joints, same features as the original.
    sk = make_skeleton()
    m = make_motion(sk, frames=90)
    words = {"daz": {"Hips": "hip", "Spine": "chest", "Neck": "neck", "Head": "head", "Arm": "{s}Shldr",
                     "ForeArm": "{s}ForeArm", "Hand": "{s}Hand", "UpLeg": "{s}Thigh", "Leg": "{s}Shin",
                     "Foot": "{s}Foot", "ToeBase": "{s}Toe"},
             "makehuman": {"Hips": "hip", "Spine": "chest", "Neck": "neck", "Head": "head", "Arm": "{s}shoulder",
                           "ForeArm": "{s}elbow", "Hand": "{s}hand", "UpLeg": "{s}hip", "Leg": "{s}knee",
                           "Foot": "{s}foot", "ToeBase": "toe1-1.{s}"}}[style]
    names = []
    for n in sk.names:
        side = "l" if n.startswith("Left") else "r" if n.startswith("Right") else ""
        names.append(words[n[len("Left"):] if side == "l" else n[len("Right"):] if side == "r" else n].format(s=side))
    # Toes straight down in the rest pose (as the Daz file's end sites give no forward
    # direction): the shape alone cannot tell left from right, so the names must map it.
    toes = (sk.index("LeftToeBase"), sk.index("RightToeBase"))
    offsets = [np.array([0.0, -6.0, 0.0]) if k in toes else j.offset.copy() for k, j in enumerate(sk.joints)]
    original = Motion(Skeleton([Joint(j.name, j.parent, o, list(j.channels), j.rotation_order)
                                for j, o in zip(sk.joints, offsets)], sk.metres_per_unit, sk.up_axis),
                      m.rotations, m.root_translation, m.fps)
    renamed = Skeleton([Joint(name, j.parent, o, list(j.channels), j.rotation_order)
                        for name, j, o in zip(names, sk.joints, offsets)], sk.metres_per_unit, sk.up_axis, style)
    with pytest.raises(TopologyError, match="left from right"):
        topology_joint_map(renamed)
    back = load_motion(save_bvh(Motion(renamed, m.rotations, m.root_translation, m.fps), tmp_path / f"{style}.bvh"))
    assert canonical_joint_map(back.skeleton) == canonical_joint_map(sk)
    np.testing.assert_allclose(motion_features(back, "storybeam"), motion_features(original, "storybeam"), atol=1e-6)
