"""Retarget any loaded motion onto a character's canonical skeleton.

Characters are built on the small canonical body of :mod:`retrieval.motion.body` (18 joints)
with their own proportions (big heads, short legs), so a clip captured on a 31-joint
Acclaim skeleton or a 100-joint Character Creator rig has to be re-expressed on it.
Copying local rotations would not work: the rigs have different rest poses and bone
axes. Instead the retarget is *position based* and therefore rig independent:

1. forward kinematics of the source gives each canonical joint's world position;
2. the hips and the chest get a full orientation from two body axes (up = towards the
   next joint, lateral = between the two hips / the two shoulders);
3. every limb joint gets the *smallest* rotation from its parent's frame that points its
   bone at the source's bone direction (no twist: the characters' parts are round, so
   twist would be invisible anyway);
4. the root (the middle of the two hip joints) moves by the source's root path scaled by
   the leg-length ratio, so strides fit the character's legs and feet do not slide;
5. a vertical offset puts the lowest foot on the table (y = 0) whenever a foot is in
   contact; between contacts (a jump's flight) the offset is interpolated so the
   character leaves the table.

The result is a :class:`~retrieval.motion.model.Motion` on the canonical skeleton (native unit:
centimetres, Y up) that any BVH writer can save and reload.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
from scipy.ndimage import minimum_filter1d

from retrieval.errors import StoryBeamError
from retrieval.motion import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    Joint,
    Motion,
    Skeleton,
    canonical_joint_map,
    global_transforms,
    min_rotation,
    positions,
    rest_positions,
    world_from_native,
)

#: Leaf joints of the canonical body; each gets an end site so a BVH writer has a tip.
CANONICAL_LEAVES = ("head", "left_hand", "right_hand", "left_toe", "right_toe")
_END_SUFFIX = "_end"
#: tan of the rest pitch of the ankle-to-toe bone (about 15 degrees: a human foot standing
#: flat, ankle joint to ball). The toe's end site reaches down to the sole.
FOOT_PITCH_TAN = 0.27


class RetargetError(StoryBeamError):
    """A motion cannot be retargeted (missing joints, degenerate skeleton)."""


@dataclass(frozen=True)
class BodyProportions:
    """Bone lengths of a canonical body, in arbitrary units (scaled to a height later).

    The defaults are an adult's; characters override them (cartoon bodies have big heads
    and short legs). ``height`` of the scaled skeleton is measured from the soles (the
    ground under the ankles) to ``head_top``.
    """

    thigh: float = 0.245
    shin: float = 0.245
    ankle_height: float = 0.045
    foot_length: float = 0.09
    toe_length: float = 0.045
    hip_half_width: float = 0.055
    pelvis_drop: float = 0.04
    lower_spine: float = 0.12
    upper_spine: float = 0.16
    neck: float = 0.06
    head_top: float = 0.12
    shoulder_half_width: float = 0.10
    shoulder_drop: float = 0.03
    upper_arm: float = 0.17
    forearm: float = 0.15
    hand: float = 0.07

    @property
    def leg_length(self) -> float:
        """Hip joint to ankle: what root motion is scaled by."""
        return self.thigh + self.shin

    @property
    def raw_height(self) -> float:
        return (
            self.ankle_height + self.shin + self.thigh + self.pelvis_drop + self.lower_spine
            + self.upper_spine + self.neck + self.head_top
        )

    def scaled(self, factor: float) -> "BodyProportions":
        return replace(self, **{f.name: getattr(self, f.name) * factor for f in fields(self)})


def _canonical_offsets(p: BodyProportions) -> dict[str, tuple[float, float, float]]:
    """Rest offsets (T-pose, facing +Z, Y up, the character's left on +X)."""
    return {
        "hips": (0.0, 0.0, 0.0),
        "spine": (0.0, p.lower_spine, 0.0),
        "neck": (0.0, p.upper_spine, 0.0),
        "head": (0.0, p.neck, 0.0),
        "head_end": (0.0, p.head_top, 0.0),
        "left_shoulder": (p.shoulder_half_width, -p.shoulder_drop, 0.0),
        "left_elbow": (p.upper_arm, 0.0, 0.0),
        "left_hand": (p.forearm, 0.0, 0.0),
        "left_hand_end": (p.hand, 0.0, 0.0),
        "right_shoulder": (-p.shoulder_half_width, -p.shoulder_drop, 0.0),
        "right_elbow": (-p.upper_arm, 0.0, 0.0),
        "right_hand": (-p.forearm, 0.0, 0.0),
        "right_hand_end": (-p.hand, 0.0, 0.0),
        "left_hip": (p.hip_half_width, -p.pelvis_drop, 0.0),
        "left_knee": (0.0, -p.thigh, 0.0),
        "left_ankle": (0.0, -p.shin, 0.0),
        "left_toe": (0.0, -p.foot_length * FOOT_PITCH_TAN, p.foot_length),
        "left_toe_end": (0.0, p.foot_length * FOOT_PITCH_TAN - p.ankle_height, p.toe_length),
        "right_hip": (-p.hip_half_width, -p.pelvis_drop, 0.0),
        "right_knee": (0.0, -p.thigh, 0.0),
        "right_ankle": (0.0, -p.shin, 0.0),
        "right_toe": (0.0, -p.foot_length * FOOT_PITCH_TAN, p.foot_length),
        "right_toe_end": (0.0, p.foot_length * FOOT_PITCH_TAN - p.ankle_height, p.toe_length),
    }


def canonical_skeleton(
    proportions: BodyProportions | None = None, height_m: float = 1.7, name: str = "canonical"
) -> Skeleton:
    """The canonical body (18 joints + 5 end sites, depth-first order) scaled so that it
    stands ``height_m`` metres tall. Native unit: centimetres (so a BVH file of a 12 cm
    character still has readable numbers); Y up."""
    if height_m <= 0:
        raise RetargetError(f"character height must be positive, got {height_m}")
    p = (proportions or BodyProportions())
    p = p.scaled(height_m * 100.0 / p.raw_height)
    offs = _canonical_offsets(p)
    order: list[str] = []

    def visit(joint: str) -> None:
        order.append(joint)
        if joint in CANONICAL_LEAVES:
            order.append(joint + _END_SUFFIX)
        for child in CANONICAL_JOINTS:
            if CANONICAL_PARENTS[child] == joint:
                visit(child)

    visit("hips")
    index = {n: i for i, n in enumerate(order)}
    joints = []
    for n in order:
        parent_name = n[: -len(_END_SUFFIX)] if n.endswith(_END_SUFFIX) else CANONICAL_PARENTS[n]
        parent = -1 if parent_name is None else index[parent_name]
        if n == "hips":
            ch = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
        elif n.endswith(_END_SUFFIX):
            ch = []
        else:
            ch = ["Zrotation", "Yrotation", "Xrotation"]
        joints.append(Joint(n, parent, np.array(offs[n], dtype=np.float64), ch, "ZYX"))
    return Skeleton(joints, metres_per_unit=0.01, up_axis="y", name=name)


def skeleton_leg_length(skeleton: Skeleton) -> float:
    """Mean hip-to-ankle length in metres of a canonical-mappable skeleton (rest pose)."""
    cmap = canonical_joint_map(skeleton)
    lengths = []
    offsets = skeleton.offsets * skeleton.metres_per_unit
    for side in ("left", "right"):
        hip, ankle = cmap[f"{side}_hip"], cmap[f"{side}_ankle"]
        total, j = 0.0, ankle
        while j != hip and j >= 0:  # bone lengths along the chain are rotation invariant
            total += float(np.linalg.norm(offsets[j]))
            j = skeleton.joints[j].parent
        if j != hip:
            raise RetargetError(f"skeleton {skeleton.name}: {side} ankle is not below the {side} hip")
        lengths.append(total)
    return float(np.mean(lengths))


def _normalise(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-12)


def _frame(up: np.ndarray, lateral: np.ndarray) -> np.ndarray:
    """Orthonormal frames (..., 3, 3) whose columns are (lateral, up, forward)."""
    y = _normalise(up)
    x = _normalise(lateral - np.sum(lateral * y, axis=-1, keepdims=True) * y)
    z = np.cross(x, y)
    return np.stack([x, y, z], axis=-1)


def _rest_frames(target: Skeleton) -> dict[str, np.ndarray]:
    """Body frames of the target's rest pose for the joints oriented by two axes."""
    rp = rest_positions(target)
    idx = {n: i for i, n in enumerate(target.names)}
    mid_hip = 0.5 * (rp[idx["left_hip"]] + rp[idx["right_hip"]])
    shoulders = rp[idx["left_shoulder"]] - rp[idx["right_shoulder"]]
    return {
        "hips": _frame(rp[idx["spine"]] - mid_hip, rp[idx["left_hip"]] - rp[idx["right_hip"]]),
        "spine": _frame(rp[idx["neck"]] - rp[idx["spine"]], shoulders),
        "neck": _frame(rp[idx["head"]] - rp[idx["neck"]], shoulders),
    }


def retarget(
    motion: Motion,
    target: Skeleton,
    *,
    ground: bool = True,
    name: str | None = None,
) -> Motion:
    """``motion`` (any skeleton with a canonical joint map) re-expressed on ``target``
    (a :func:`canonical_skeleton`), at the target's size.

    Root motion is scaled by target leg length / source leg length; with ``ground`` the
    feet are put on y = 0 during contacts (see :func:`ground_offsets`).
    """
    try:
        cmap = canonical_joint_map(motion.skeleton)
    except StoryBeamError as exc:
        raise RetargetError(f"cannot retarget {motion.name or 'motion'}: {exc}") from None
    tidx = {n: i for i, n in enumerate(target.names)}
    missing = [c for c in CANONICAL_JOINTS if c not in tidx]
    if missing:
        raise RetargetError(f"target skeleton {target.name} lacks canonical joints {missing}")
    if motion.n_frames == 0:
        raise RetargetError(f"{motion.name or 'motion'} has no frames")

    src = positions(motion)  # (T, J, 3) metres, Y up
    q = {c: src[:, i] for c, i in cmap.items()}
    t_count = motion.n_frames
    mpu = target.metres_per_unit
    src_leg = skeleton_leg_length(motion.skeleton)
    if src_leg <= 1e-6:
        raise RetargetError(f"skeleton {motion.skeleton.name}: zero leg length")
    tgt_offsets = target.offsets
    tgt_leg = float(np.mean([
        np.linalg.norm(tgt_offsets[tidx[f"{s}_knee"]]) + np.linalg.norm(tgt_offsets[tidx[f"{s}_ankle"]])
        for s in ("left", "right")
    ])) * mpu
    ratio = tgt_leg / src_leg

    for side in ("left", "right"):  # make a flat source foot a flat character foot
        a, t = f"{side}_ankle", f"{side}_toe"
        q[t] = q[a] + _repitch_foot(q[t] - q[a], q[a], motion.fps, src_leg, _rest_pitch(tgt_offsets[tidx[t]]))
    rest = _rest_frames(target)
    shoulders = q["left_shoulder"] - q["right_shoulder"]
    mid_hip = 0.5 * (q["left_hip"] + q["right_hip"])
    frames_now = {
        "hips": _frame(q["spine"] - mid_hip, q["left_hip"] - q["right_hip"]),
        "spine": _frame(q["neck"] - q["spine"], shoulders),
        "neck": _frame(q["head"] - q["neck"], shoulders),
    }
    glob: dict[str, np.ndarray] = {}
    local = np.broadcast_to(np.eye(3), (t_count, target.n_joints, 3, 3)).copy()
    for c in CANONICAL_JOINTS:
        parent = CANONICAL_PARENTS[c]
        g_parent = np.broadcast_to(np.eye(3), (t_count, 3, 3)) if parent is None else glob[parent]
        if c in frames_now:
            g = frames_now[c] @ rest[c].T
        elif c in CANONICAL_LEAVES:
            g = g_parent
        else:
            child = next(k for k in CANONICAL_JOINTS if CANONICAL_PARENTS[k] == c)
            rest_dir = g_parent @ tgt_offsets[tidx[child]]
            g = min_rotation(rest_dir, q[child] - q[c]) @ g_parent
        glob[c] = g
        local[:, tidx[c]] = np.swapaxes(g_parent, -1, -2) @ g

    hip_centre_offset = 0.5 * (tgt_offsets[tidx["left_hip"]] + tgt_offsets[tidx["right_hip"]]) * mpu
    root_m = mid_hip * ratio - np.einsum("tab,b->ta", glob["hips"], hip_centre_offset)
    out = Motion(target, local, root_m / mpu, motion.fps, name or motion.name)
    if ground:
        out.root_translation[:, 1] += ground_offsets(out) / mpu
    return out


def _pitch(d: np.ndarray) -> np.ndarray:
    """Downward pitch (radians) of vectors: 0 horizontal, positive pointing down."""
    return np.arctan2(-d[..., 1], np.linalg.norm(d[..., [0, 2]], axis=-1))


def _rest_pitch(toe_offset: np.ndarray) -> float:
    return float(_pitch(np.asarray(toe_offset, dtype=np.float64)))


def flat_foot_pitch(foot: np.ndarray, ankle: np.ndarray, fps: float, leg: float) -> float:
    """Pitch of the ankle-to-toe vector when the foot stands flat: the median over the
    frames where the ankle is lowest and still. Rigs differ (CMU's toe joint is the ball
    of the foot, 10–20 degrees below the ankle), so this is measured per clip."""
    h = ankle[:, 1]
    speed = np.linalg.norm(np.gradient(ankle, axis=0), axis=1) * fps if len(h) > 1 else np.zeros(len(h))
    low = h <= np.quantile(h, 0.25)
    still = speed < 0.3 * leg
    pick = low & still
    if pick.sum() < 3:
        pick = low
    return float(np.median(_pitch(foot[pick])))


def _repitch_foot(foot: np.ndarray, ankle: np.ndarray, fps: float, leg: float, target_pitch: float) -> np.ndarray:
    """Turn the source foot vectors (T, 3) down by (target rest pitch - source flat pitch)
    in their own vertical plane, so feet that stand flat in the capture stand flat on
    the character (whose rest foot has ``target_pitch``)."""
    delta = target_pitch - flat_foot_pitch(foot, ankle, fps, leg)
    horiz = foot[:, [0, 2]]
    hn = np.linalg.norm(horiz, axis=1)
    length = np.linalg.norm(foot, axis=1)
    beta = _pitch(foot) + delta
    dirh = horiz / np.maximum(hn, 1e-12)[:, None]
    out = np.empty_like(foot)
    out[:, 0] = np.cos(beta) * dirh[:, 0] * length
    out[:, 2] = np.cos(beta) * dirh[:, 1] * length
    out[:, 1] = -np.sin(beta) * length
    vertical = hn < 1e-3 * np.maximum(length, 1e-12)  # pointing straight up/down: keep
    out[vertical] = foot[vertical]
    return out


# --- ground contact -------------------------------------------------------------------

def foot_points(skeleton: Skeleton) -> list[int]:
    """Indices of the canonical ankle and toe joints (left ankle, left toe, right ankle,
    right toe); the sole points of :func:`sole_points` hang off these."""
    return [skeleton.index(n) for n in ("left_ankle", "left_toe", "right_ankle", "right_toe")]


#: Order of the four sole points returned by :func:`sole_points`.
SOLE_POINTS = ("left_heel", "left_toe_tip", "right_heel", "right_toe_tip")


def sole_level(skeleton: Skeleton) -> float:
    """Height (metres, rest pose) of the soles: the lowest of the foot joints and the
    toes' end sites (which the canonical skeleton puts on the sole)."""
    rp = rest_positions(skeleton)
    names = ("left_ankle", "left_toe", "right_ankle", "right_toe", "left_toe_end", "right_toe_end")
    return float(min(rp[skeleton.index(n), 1] for n in names if skeleton.get(n) is not None))


def sole_points(motion: Motion, rot: np.ndarray | None = None, pos: np.ndarray | None = None) -> np.ndarray:
    """(T, 4, 3) world positions in metres of the points that actually touch the table:
    each foot's heel (on the sole, under the ankle) and toe tip (the toe's end site).

    Contacts and skating are judged on these, not on the ankle and toe *joints*: when a
    foot rolls from heel to toe the ankle joint swings forward a few centimetres while
    nothing slides, which a joint-based measure would count as skating.
    """
    sk = motion.skeleton
    if rot is None or pos is None:
        rot, pos = global_transforms(motion)
    a = world_from_native(sk) * sk.metres_per_unit
    out = np.empty((motion.n_frames, 4, 3))
    level = sole_level(sk) / sk.metres_per_unit
    rp = rest_positions(sk, metres_yup=False)
    for k, side in enumerate(("left", "right")):
        ankle, toe = sk.index(f"{side}_ankle"), sk.index(f"{side}_toe")
        tip = sk.get(f"{side}_toe_end")
        heel_local = np.array([0.0, level - rp[ankle, 1], -0.15 * abs(sk.joints[toe].offset[2])])
        heel = pos[:, ankle] + np.einsum("tab,b->ta", rot[:, ankle], heel_local)
        toe_tip = pos[:, tip] if tip is not None else pos[:, toe]
        out[:, 2 * k] = heel @ a.T
        out[:, 2 * k + 1] = toe_tip @ a.T
    return out


def foot_heights(motion: Motion, pos: np.ndarray | None = None) -> np.ndarray:
    """(T, 4) height in metres of the sole points (:data:`SOLE_POINTS`) above y = 0."""
    return sole_points(motion)[:, :, 1]


def contacts(
    motion: Motion,
    pos: np.ndarray | None = None,
    height_tol: float = 0.06,
    speed_tol: float = 1.0,
) -> np.ndarray:
    """(T, 4) booleans: sole point (:data:`SOLE_POINTS`; ``pos`` is their (T, 4, 3)
    positions when already computed) in contact with the ground.

    A point is in contact when it is within ``height_tol`` leg lengths of the clip's
    lowest foot height *nearby in time* (grounds are not always at y=0 in the source)
    and moves slower than ``speed_tol`` leg lengths per second. Thresholds are in leg
    lengths so the same numbers work for a 1.7 m actor and a 12 cm character.
    """
    pos = sole_points(motion) if pos is None else pos
    leg = skeleton_leg_length(motion.skeleton)
    h = pos[:, :, 1]
    vel = np.gradient(pos, axis=0) * motion.fps if motion.n_frames > 1 else np.zeros_like(pos)
    speed = np.linalg.norm(vel, axis=-1)
    slow = speed < speed_tol * leg
    # Local ground level: the lowest *slow* sole point within +-1 s (robust to sloped or
    # offset floors, and not fooled by a swinging toe that dips low).
    win = max(1, int(round(motion.fps)))
    low = np.where(slow, h, np.inf).min(axis=1)
    low = np.where(np.isfinite(low), low, h.min(axis=1))
    ground = minimum_filter1d(low, size=2 * win + 1, mode="nearest")
    return (h - ground[:, None] < height_tol * leg) & slow


def ground_offsets(motion: Motion) -> np.ndarray:
    """(T,) vertical shift in metres that puts the lowest foot point in contact on y = 0,
    interpolated linearly across flight phases (and held at the ends)."""
    pos = sole_points(motion)
    h = pos[:, :, 1]
    contact = contacts(motion, pos)
    touching = contact.any(axis=1)
    # The lowest *standing* foot point goes on the table, not a swinging toe that skims
    # lower than the standing foot (pinning that one would make it scrape along).
    low = np.where(contact, h, np.inf).min(axis=1)
    low = np.where(touching, low, h.min(axis=1))
    t = np.arange(motion.n_frames)
    if not touching.any():  # never on the ground (a clip of pure flight): lowest frame on it
        return np.full(motion.n_frames, -float(low.min()))
    off = np.interp(t, t[touching], -low[touching])
    # Light smoothing (about 0.1 s) removes contact-flag flicker without lifting feet.
    k = max(1, int(round(0.05 * motion.fps)))
    if k > 1 and motion.n_frames > 2 * k:
        kernel = np.ones(2 * k + 1) / (2 * k + 1)
        padded = np.pad(off, k, mode="edge")
        smooth = np.convolve(padded, kernel, mode="valid")
        off = np.where(touching, off, smooth)
    # A swinging toe may still brush a little below the surface (the character's feet
    # are not the actor's); lifting the body for it would unplant the standing foot.
    return off
