"""Map any skeleton's joints onto StoryBeam's canonical body by name patterns.

Features, retargeting and characters speak of a small canonical body (below) rather than
of a file's joint names, so a new skeleton usually works without code changes: CMU's
Acclaim names (``lfemur``, ``ltibia``), Character Creator's (``CC_Base_L_Thigh``),
Mixamo's (``mixamorig:LeftUpLeg``) and the usual BVH names (``LeftUpLeg``, ``LeftLeg``)
all resolve, and so do Bandai's (``UpperLeg_L``, ``Chest``), SMPL-like names (``L_Hip``,
``L_Ankle``, ``L_Foot`` as the toe, ``L_Collar`` skipped for ``L_Shoulder``) and
Biovision's (``LeftUpArm``, ``LeftLowArm``, ``LeftLowLeg``; a foot with no toe joint uses
its end site as the toe). Each name is split into a side (left/right/none) and a base
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
    "shoulder": ("upperarm", "uparm", "humerus", "arm", "shoulder"),
    "elbow": ("forearm", "lowerarm", "lowarm", "radius", "elbow"),
    "hand": ("wrist", "hand"),
    "hip": ("thigh", "upleg", "upperleg", "femur", "hip"),
    "knee": ("calf", "leg", "lowerleg", "lowleg", "shin", "tibia", "knee"),
    "ankle": ("ankle", "foot"),
    # SMPL's ``L_Foot`` is the ball of the foot (its ankle is ``L_Ankle``): "foot" is a
    # toe only when another joint already took the ankle.
    "toe": ("toebase", "toes?", "ball", "foot"),
}
_CENTRE_PARTS: dict[str, tuple[str, ...]] = {
    "spine": ("thorax", "chest", "upperchest", "spine0*[2-9]", "upperback", "spine0*1", "spine"),
    "neck": ("neck", "lowerneck", "necktwist0*1", "neck0*1", "upperneck"),
    "head": ("head",),
}
# The pelvis joint, when the root is something else (Character Creator's ``RL_BoneRoot``
# sits on the floor with ``CC_Base_Hip`` below it); Acclaim's ``root`` is the pelvis.
_HIPS_PATTERNS: tuple[str, ...] = ("hips?", "pelvis")
# Acclaim-style names glue the side letter to a known body word: "lfemur", "rtoes".
_GLUED_SIDE = re.compile(
    r"^([lr])(hipjoint|femur|tibia|foot|toes|clavicle|humerus|radius|wrist|hand|fingers|thumb)$"
)
_PREFIXES = re.compile(r"^(cc_base_|mixamorig\d*[:_]|bip0?1[ _]?|b_|def[-_]|j_)")


class JointMapError(StoryBeamError):
    """A skeleton lacks a joint the canonical body needs."""


def split_side(name: str) -> tuple[str | None, str]:
    """(side, base word) of a joint name: side is "left", "right" or None."""
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
