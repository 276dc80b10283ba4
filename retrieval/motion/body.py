"""Map any skeleton's joints onto StoryBeam's canonical body by name patterns.

Features, retargeting and characters speak of a small canonical body (below) rather than
of a file's joint names, so a new skeleton usually works without code changes: CMU's
Acclaim names (``lfemur``, ``ltibia``), Character Creator's (``CC_Base_L_Thigh``),
Mixamo's (``mixamorig:LeftUpLeg``) and the usual BVH names (``LeftUpLeg``, ``LeftLeg``)
all resolve, and so do Bandai's (``UpperLeg_L``, ``Chest``), SMPL-like names (``L_Hip``,
``L_Ankle``, ``L_Foot`` as the toe, ``L_Collar`` skipped for ``L_Shoulder``) and
Biovision's (``LeftUpArm``, ``LeftLowArm``, ``LeftLowLeg``; a foot with no toe joint uses
its end site as the toe), Poser/Daz's (``lShldr``, ``rForeArm``, ``lThigh``, ``rShin``: a
lower-case side letter before a capital) and MakeHuman's "CMU+face" armature as MocapNET
writes it (``lshoulder``, ``relbow``, ``rhip``, ``lknee``, toes ``toe1-1.l``). Each name is split into a side (left/right/none) and a base
word; each canonical part lists base words in order of preference and takes the first
joint not already taken (so SMPL's ``L_Foot`` becomes the toe once ``L_Ankle`` is the
ankle).

Failing names, the map comes from the hierarchy and rest pose
(:mod:`retrieval.motion.topology`); a skeleton neither can map raises
:class:`JointMapError` naming the canonical joints the names missed and why the shape
did not settle them.
"""
from __future__ import annotations

import re

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.motion.model import Skeleton
from retrieval.motion.topology import TopologyError, topology_joint_map

#: The canonical body, in a fixed order (used for retargeting and characters).
CANONICAL_JOINTS: tuple[str, ...] = (
    "hips", "spine", "neck", "head",
    "left_shoulder", "left_elbow", "left_hand",
    "right_shoulder", "right_elbow", "right_hand",
    "left_hip", "left_knee", "left_ankle", "left_toe",
    "right_hip", "right_knee", "right_ankle", "right_toe",
)

#: Canonical parent of each canonical joint (the simplified hierarchy).
CANONICAL_PARENTS: dict[str, str | None] = {
    "hips": None, "spine": "hips", "neck": "spine", "head": "neck",
    "left_shoulder": "neck", "left_elbow": "left_shoulder", "left_hand": "left_elbow",
    "right_shoulder": "neck", "right_elbow": "right_shoulder", "right_hand": "right_elbow",
    "left_hip": "hips", "left_knee": "left_hip", "left_ankle": "left_knee", "left_toe": "left_ankle",
    "right_hip": "hips", "right_knee": "right_hip", "right_ankle": "right_knee", "right_toe": "right_ankle",
}

# Base words per part, most preferred first. A pattern is a full-match regex on the
# base word (lower case, separators removed).
_SIDED_PARTS: dict[str, tuple[str, ...]] = {
    # Poser/Daz's upper-arm joint is ``lShldr`` (its clavicle ``lCollar``, skipped).
    "shoulder": ("upperarm", "uparm", "humerus", "arm", "shldr", "shoulder"),
    "elbow": ("forearm", "lowerarm", "lowarm", "radius", "elbow"),
    "hand": ("wrist", "hand"),
    "hip": ("thigh", "upleg", "upperleg", "femur", "hip"),
    "knee": ("calf", "leg", "lowerleg", "lowleg", "shin", "tibia", "knee"),
    "ankle": ("ankle", "foot"),
    # SMPL's ``L_Foot`` is the ball of the foot (its ankle is ``L_Ankle``): "foot" is a
    # toe only when another joint already took the ankle.
    # MakeHuman's feet end in five toes (``toe1-1.l`` ... ``toe5-3.l``): the first one,
    # the big toe's root, stands for the toe.
    "toe": ("toebase", "toes?", "toe0*1\\d*", "ball", "foot"),
}
_CENTRE_PARTS: dict[str, tuple[str, ...]] = {
    "spine": ("thorax", "chest", "upperchest", "spine0*[2-9]", "upperback", "spine0*1", "spine"),
    "neck": ("neck", "lowerneck", "necktwist0*1", "neck0*1", "upperneck"),
    "head": ("head",),
}
# The pelvis joint, when the root is something else (Character Creator's ``RL_BoneRoot``
# sits on the floor with ``CC_Base_Hip`` below it); Acclaim's ``root`` is the pelvis.
_HIPS_PATTERNS: tuple[str, ...] = ("hips?", "pelvis")
# Acclaim-style names glue the side letter to a known body word: "lfemur", "rtoes"; so do
# MakeHuman's and MocapNET's ("lshoulder", "relbow", "lbuttock", "rknee").
_GLUED_SIDE = re.compile(
    r"^([lr])(hipjoint|femur|tibia|foot|toes?|clavicle|humerus|radius|wrist|hand|fingers|thumb"
    r"|collar|shoulder|shldr|elbow|forearm|buttock|hip|thigh|knee|shin|ankle)$"
)
# Poser/Daz-style names glue a lower-case side letter to a capitalised word: "lShldr",
# "rForeArm", "lThigh" (checked on the name as written, before lower-casing).
_CAMEL_SIDE = re.compile(r"^([lr])(?=[A-Z])")
_PREFIXES = re.compile(r"^(cc_base_|mixamorig\d*[:_]|bip0?1[ _]?|b_|def[-_]|j_)")


class JointMapError(StoryBeamError):
    """A skeleton lacks a joint the canonical body needs."""


def split_side(name: str) -> tuple[str | None, str]:
    """(side, base word) of a joint name: side is "left", "right" or None."""
    camel = _CAMEL_SIDE.match(name.strip())
    if camel:
        return ("left" if camel.group(1) == "l" else "right"), re.sub(r"[^a-z0-9]", "", name.strip()[1:].lower())
    n = _PREFIXES.sub("", name.strip().lower())
    m = _GLUED_SIDE.match(n)
    if m:
        return ("left" if m.group(1) == "l" else "right"), m.group(2)
    side = None
    for word, s in (("left", "left"), ("right", "right")):
        if word in n:
            side, n = s, n.replace(word, "")
            break
    else:
        tokens = re.split(r"[_\.\s:-]+", n)
        for k, tok in enumerate(tokens):
            if tok in ("l", "r"):
                side = "left" if tok == "l" else "right"
                tokens = tokens[:k] + tokens[k + 1 :]
                break
        n = "".join(tokens)
    return side, re.sub(r"[^a-z0-9]", "", n)


def _names_joint_map(skeleton: Skeleton) -> dict[str, int]:
    """The canonical joints that name patterns find (possibly not all)."""
    parsed = [split_side(j.name) for j in skeleton.joints]
    found: dict[str, int] = {}
    used: set[int] = set()

    def first(side: str | None, patterns: tuple[str, ...]) -> int | None:
        for pat in patterns:
            rx = re.compile(pat)
            for i, (s, base) in enumerate(parsed):
                if (
                    s == side
                    and i not in used
                    and rx.fullmatch(base)
                    and not skeleton.joints[i].is_end_site
                ):
                    used.add(i)
                    return i
        return None

    hips = first(None, _HIPS_PATTERNS)
    found["hips"] = 0 if hips is None else hips
    used.add(found["hips"])
    for part, pats in _CENTRE_PARTS.items():
        i = first(None, pats)
        if i is not None:
            found[part] = i
    for side in ("left", "right"):
        for part, pats in _SIDED_PARTS.items():
            i = first(side, pats)
            if i is not None:
                found[f"{side}_{part}"] = i
        ankle = found.get(f"{side}_ankle")
        if f"{side}_toe" not in found and ankle is not None:
            # Biovision-style feet end in an end site at the toes: use it as the toe.
            tips = [k for k in skeleton.children(ankle) if skeleton.joints[k].is_end_site]
            if len(tips) == 1 and float(np.linalg.norm(skeleton.joints[tips[0]].offset)) > 0:
                found[f"{side}_toe"] = tips[0]
    return found


def canonical_joint_map(skeleton: Skeleton, required: bool = True) -> dict[str, int]:
    """Canonical joint name -> joint index in ``skeleton``.

    First by names: ``hips`` is the first centre joint named like a hip/pelvis (``Hips``,
    ``CC_Base_Hip``), else the root; every other part takes the first unused joint whose
    base word matches its patterns, in order of preference. When names leave any canonical
    joint unmatched, the map comes from the hierarchy and rest pose instead
    (:func:`retrieval.motion.topology.topology_joint_map`). When both fail and
    ``required``, raises :class:`JointMapError` naming the joints names could not match and
    why the shape did not settle them; with ``required=False`` the partial name map is
    returned.
    """
    found = _names_joint_map(skeleton)
    missing = [c for c in CANONICAL_JOINTS if c not in found]
    if not missing:
        return {c: found[c] for c in CANONICAL_JOINTS}
    try:
        return topology_joint_map(skeleton)
    except TopologyError as exc:
        reason = str(exc)
    if required:
        raise JointMapError(
            f"skeleton {skeleton.name or '(unnamed)'} has no joint for: {', '.join(missing)} "
            f"(by names; by shape: {reason}) (joint names: {', '.join(skeleton.names[:40])})"
        )
    return {c: found[c] for c in CANONICAL_JOINTS if c in found}


#: The canonical body's bone lengths in leg lengths (hip->knee->ankle = 1):
#: :func:`canonical_pose` re-poses every skeleton onto them. ``hip_half_width`` and
#: ``shoulder_half_width`` run along the pelvis's and the chest's lateral axis,
#: ``shoulder_drop`` down the chest's. The values are the mean proportions of the CMU
#: library's 205 skeletons (:func:`body_proportions` on each rest pose, rounded to 0.01;
#: checked by ``tests/retrieval/test_canonical_pose.py``), so re-posing changes the
#: library's own features least: a body with longer forearms (0.31 rather than CMU's
#: 0.23), a longer head and a wider pelvis, tried first, weighted the hands' columns
#: differently from the library's own and cost CMU its kick poses
#: (docs/notebook/results.md, "Why the canonical body lost CMU's jumps").
CANONICAL_BONES: dict[str, float] = {
    "thigh": 0.48, "shin": 0.52, "foot": 0.15, "hip_half_width": 0.10, "lower_spine": 0.34,
    "upper_spine": 0.35, "head": 0.09, "shoulder_half_width": 0.2, "shoulder_drop": 0.06,
    "upper_arm": 0.35, "forearm": 0.23,
}
#: (canonical joint, the joint its bone starts from, the bone's length key) for the limb
#: joints :func:`canonical_pose` places along the source's bone direction.
_LIMBS: tuple[tuple[str, str, str], ...] = (
    ("left_elbow", "left_shoulder", "upper_arm"), ("left_hand", "left_elbow", "forearm"),
    ("right_elbow", "right_shoulder", "upper_arm"), ("right_hand", "right_elbow", "forearm"),
    ("left_knee", "left_hip", "thigh"), ("left_ankle", "left_knee", "shin"), ("left_toe", "left_ankle", "foot"),
    ("right_knee", "right_hip", "thigh"), ("right_ankle", "right_knee", "shin"),
    ("right_toe", "right_ankle", "foot"),
)
#: Bumped whenever :func:`canonical_pose` changes what it computes: cached features of a
#: canonical-body set are keyed by it.
CANONICAL_POSE_VERSION = 3

#: The canonical joint map of :func:`canonical_pose`'s output.
CANONICAL_INDEX: dict[str, int] = {c: i for i, c in enumerate(CANONICAL_JOINTS)}


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 1e-12)


def canonical_pose(pos: np.ndarray, joint_map: dict[str, int], leg: float) -> np.ndarray:
    """(T, J, 3) positions of any skeleton (metres, Y up; ``joint_map`` its canonical map,
    ``leg`` its rest leg length in metres) -> (T, 18, 3) positions of the canonical body
    (:data:`CANONICAL_JOINTS` order, :data:`CANONICAL_INDEX`) in leg lengths, doing the
    same posture with the canonical bone lengths (:data:`CANONICAL_BONES`).

    Method: the source gives directions only, never lengths or joint placements, and
    only between joints every rig places alike — the hip joints, the shoulder joints
    (the upper arms' starts), the limbs and the head's direction from the shoulders; a
    rig's spine and neck joints are left out (CMU's own BVH conversion starts its neck
    at the thorax, 12 cm below the Acclaim original's). The pelvis centre is the
    midpoint of the two hip joints (not the file's root or ``Hips`` joint, which rigs
    place anywhere between the hips and the waist), at the source's position divided by
    ``leg`` (a jump rises by the same number of leg lengths); the hip joints sit
    ``hip_half_width`` either side along the source's hip-to-hip axis; spine and neck
    lie on the straight trunk from the pelvis centre towards the source's shoulder
    centre; the shoulders sit ``shoulder_half_width`` either side of the neck along the
    source's shoulder-to-shoulder axis and ``shoulder_drop`` down the trunk; the head is
    ``head`` from the neck along the source's shoulder-centre->head direction (a head
    joint at the eyes or at the top of the neck points the same way); every limb joint
    is its parent plus the canonical length along the source's bone direction.
    What stays rig-dependent is the direction itself where rigs disagree (a toe joint at
    the ball or at the tip of the foot): see :attr:`FeatureSet.floor_joints`."""
    pos = np.asarray(pos, dtype=np.float64) / leg
    b = CANONICAL_BONES
    out = np.empty((pos.shape[0], len(CANONICAL_JOINTS), 3))

    def src(name: str) -> np.ndarray:
        return pos[:, joint_map[name]]

    def put(name: str, value: np.ndarray) -> None:
        out[:, CANONICAL_INDEX[name]] = value

    def got(name: str) -> np.ndarray:
        return out[:, CANONICAL_INDEX[name]]

    mid = 0.5 * (src("left_hip") + src("right_hip"))
    lateral = _unit(src("left_hip") - src("right_hip"))
    put("hips", mid)
    put("left_hip", mid + b["hip_half_width"] * lateral)
    put("right_hip", mid - b["hip_half_width"] * lateral)
    shoulder_centre = 0.5 * (src("left_shoulder") + src("right_shoulder"))
    trunk = _unit(shoulder_centre - mid)
    put("spine", mid + b["lower_spine"] * trunk)
    put("neck", got("spine") + b["upper_spine"] * trunk)
    put("head", got("neck") + b["head"] * _unit(src("head") - shoulder_centre))
    across = src("left_shoulder") - src("right_shoulder")
    across = _unit(across - np.sum(across * trunk, axis=-1, keepdims=True) * trunk)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        put(f"{side}_shoulder", got("neck") + sign * b["shoulder_half_width"] * across - b["shoulder_drop"] * trunk)
    for joint, start, bone in _LIMBS:
        put(joint, got(start) + b[bone] * _unit(src(joint) - src(start)))
    return out


def canonical_rest() -> np.ndarray:
    """(18, 3) rest pose of the canonical body of :func:`canonical_pose` (T-pose, facing
    +Z, Y up, leg lengths; the pelvis centre at the origin)."""
    b = CANONICAL_BONES
    rest = np.zeros((len(CANONICAL_JOINTS), 3))
    down = np.array([0.0, -1.0, 0.0])
    offsets = {
        "left_hip": (b["hip_half_width"], 0, 0), "right_hip": (-b["hip_half_width"], 0, 0),
        "spine": (0, b["lower_spine"], 0), "neck": (0, b["upper_spine"], 0), "head": (0, b["head"], 0),
        "left_shoulder": (b["shoulder_half_width"], -b["shoulder_drop"], 0),
        "right_shoulder": (-b["shoulder_half_width"], -b["shoulder_drop"], 0),
        "left_elbow": (b["upper_arm"], 0, 0), "left_hand": (b["forearm"], 0, 0),
        "right_elbow": (-b["upper_arm"], 0, 0), "right_hand": (-b["forearm"], 0, 0),
        "left_knee": down * b["thigh"], "left_ankle": down * b["shin"], "left_toe": (0, 0, b["foot"]),
        "right_knee": down * b["thigh"], "right_ankle": down * b["shin"], "right_toe": (0, 0, b["foot"]),
    }
    for c in CANONICAL_JOINTS[1:]:
        rest[CANONICAL_INDEX[c]] = rest[CANONICAL_INDEX[CANONICAL_PARENTS[c]]] + np.asarray(offsets[c], float)
    return rest


def body_proportions(rest: np.ndarray, joint_map: dict[str, int], leg: float) -> dict[str, float]:
    """The :data:`CANONICAL_BONES` quantities of one skeleton's (J, 3) rest pose (metres,
    ``leg`` its leg length), in leg lengths: both sides averaged; ``lower_spine`` +
    ``upper_spine`` as one ``trunk`` (pelvis centre to shoulder centre, plus the shoulder
    drop, as :func:`canonical_pose` stacks them) and ``head`` from the neck (the head
    joint's distance from the shoulder centre less the drop)."""
    r = np.asarray(rest, dtype=np.float64) / leg

    def p(name: str) -> np.ndarray:
        return r[joint_map[name]]

    def both(a: str, b: str) -> float:
        return float(np.mean([np.linalg.norm(p(f"{s}_{a}") - p(f"{s}_{b}")) for s in ("left", "right")]))

    mid = 0.5 * (p("left_hip") + p("right_hip"))
    shoulders = 0.5 * (p("left_shoulder") + p("right_shoulder"))
    drop = CANONICAL_BONES["shoulder_drop"]
    return {
        "thigh": both("knee", "hip"), "shin": both("ankle", "knee"), "foot": both("toe", "ankle"),
        "hip_half_width": float(np.linalg.norm(p("left_hip") - p("right_hip"))) / 2,
        "trunk": float(np.linalg.norm(shoulders - mid)) + drop,
        "head": float(np.linalg.norm(p("head") - shoulders)) - drop,
        "shoulder_half_width": float(np.linalg.norm(p("left_shoulder") - p("right_shoulder"))) / 2,
        "upper_arm": both("elbow", "shoulder"), "forearm": both("hand", "elbow"),
    }
