"""Per-frame relational features: 17 body-part distances after Müller & Röder (SCA 2006).

The research turns every frame into a real vector of 17 distances between body parts and
does not list them. Ours (:data:`MR17`) are chosen so that each one answers a question a
child's story motion poses — are the hands together, is a leg stretched, is a foot off the
ground — and so that none depends on where the performer stands, which way they face, how
tall they are or which skeleton recorded them:

==  ======================  ==========================================================
 #  name                    why
==  ======================  ==========================================================
 1  hand_hand               clapping, arms spread (dance), arm swing phase (walk/run)
 2  ankle_ankle             stride length: walk vs run, feet together in a jump
 3  knee_knee               leg spread independent of foot placement (kicks, dance)
 4  elbow_elbow             arm opening even when the hands are close to the body
 5  lhand_head              hand raised to / above the head (dance, reach)
 6  rhand_head              (mirror of 5)
 7  lhand_rshoulder         arm swing across / away from the body (walk, run, dance)
 8  rhand_lshoulder         (mirror of 7)
 9  lankle_lhip             leg extension = knee bend (crouch before a jump, running)
10  rankle_rhip             (mirror of 9)
11  lhand_lshoulder         arm extension = elbow bend (punch-like dance moves, running)
12  rhand_rshoulder         (mirror of 11)
13  lankle_height           left foot above the floor: kick, step phase, flight
14  rankle_height           (mirror of 13)
15  hips_height             root above the floor: crouch, jump flight, standing
16  lhand_above_head        signed hand height over the head: arms raised vs down
17  rhand_above_head        (mirror of 16)
==  ======================  ==========================================================

Pairs 1–12 are 3-D Euclidean distances, hence invariant to the body's position and heading.
Heights 13–15 are measured above the clip's *floor*: a low percentile of the lowest
foot joint (ankle or toe) over the clip, so a jump's flight phase shows as the whole body
rising, while the file's own ground offset (BVH converters shift it) cancels out; a set
with a ``floor_window`` takes the floor over a second or so either side of each frame
instead, so standing on a step is not flight.
16–17 are signed vertical offsets (hand y minus head y).

No pair mixes an upper-body joint (neck, head, shoulders, elbows, hands) with a lower-body
one (hips, legs, feet): skeletons disagree about the thorax. CMU's BVH conversions give
``Neck`` a zero offset from ``Spine1``, which drops the thorax bone and moves the whole
upper body about 12 cm down relative to the Acclaim original (measured on 01_01: every
upper-body joint off by the thorax vector, every lower-body joint identical). A hand-to-hip
distance would therefore change with the file format; hand-to-shoulder and hand-to-head
distances do not.

Every value is divided by the performer's *leg length* (hip→knee→ankle, both legs
averaged) measured on the skeleton's rest pose: bone lengths do not depend on the rest
posture (T-pose or A-pose) but do scale with the performer, so a child-sized and an
adult-sized skeleton doing the same motion give the same numbers. Leg length rather than
height because skeletons disagree about where the "head" joint sits (Acclaim's head is a
bone start, Character Creator's is near the eyes), while hips, knees and ankles agree.

The feature set is swappable: :class:`FeatureSet` holds a list of :class:`FeatureSpec`
and a registry (:func:`register_feature_set`, :func:`get_feature_set`) maps names to sets,
so an index records which set it was built with and an experiment can try another.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.ndimage import gaussian_filter1d, percentile_filter

from retrieval.errors import StoryBeamError
from retrieval.motion import (
    CANONICAL_INDEX,
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    Motion,
    Skeleton,
    canonical_joint_map,
    canonical_pose,
    canonical_rest,
    positions,
    rest_positions,
)

#: Percentile of the per-frame lowest foot height taken as the clip's floor. A low
#: percentile rather than the minimum, so one glitched frame does not move the floor.
FLOOR_PERCENTILE = 2.0

_FOOT_JOINTS = ("left_ankle", "left_toe", "right_ankle", "right_toe")
_ANKLES = ("left_ankle", "right_ankle")


class FeatureError(StoryBeamError):
    """Features cannot be computed for a motion (unknown feature set, bad skeleton)."""


@dataclass(frozen=True)
class FeatureSpec:
    """One feature: ``kind`` is "distance" (|a−b|), "height" (a above the clip's floor),
    "lowest" (the lower of a and b above the clip's floor: both feet off it, a flight),
    "above" (signed vertical offset a.y − b.y), "heading_rate" (the body's turning rate,
    see :func:`heading_rate`; joints are left hip, right hip, left shoulder, right
    shoulder), or "across" / "forward" (the horizontal offset a − b along the body's own
    left-to-right or forward axis, see :func:`body_axes`; joints are a, b, then the four
    heading joints); ``joints`` are canonical joint names; ``weight`` multiplies the value."""

    name: str
    kind: str
    joints: tuple[str, ...]
    why: str = ""
    weight: float = 1.0


@dataclass(frozen=True)
class FeatureSet:
    """An ordered list of features, all divided by the skeleton's leg length."""

    name: str
    specs: tuple[FeatureSpec, ...]
    description: str = ""
    #: "legs": every length divided by the leg length (MR17); "arms": a feature that
    #: involves a hand or an elbow divided by the arm length (:func:`arm_length`), every
    #: other by the leg length; "chain": a distance or vertical offset between joints a
    #: and b divided by the rest-pose length of the canonical chain joining them (see
    #: :func:`chain_length`), heights by the leg length.
    normalise: str = "legs"
    #: Subtract each column's mean over the clip (a per-clip constant offset — what a
    #: different skeleton's proportions and joint placement mostly add — cancels).
    centre: bool = False
    #: "source": the file's own joints and bone lengths; "canonical": every frame first
    #: re-posed onto the canonical body (:func:`~retrieval.motion.canonical_pose`: the
    #: source's bone directions at canonical bone lengths), so a skeleton's proportions,
    #: rest pose and joint placement drop out before any distance is taken.
    body: str = "source"
    #: Seconds either side of a frame over which its floor is taken (0: the whole clip,
    #: :func:`clip_floor`). A local floor keeps the floor where a performer stands on a
    #: step or a box for longer than that (CMU's walks on uneven terrain, 03_03/03_04,
    #: stand 0.35-0.57 leg lengths above the clip's lowest ground, a jump's apex height), while
    #: a jump's apex, within half a flight time (well under a second) of the take-off,
    #: still measures from the ground it left.
    floor_window: float = 0.0
    #: Percentile of the per-frame lowest foot joint that "height" features stand on
    #: (:func:`clip_floor`).
    floor_percentile: float = FLOOR_PERCENTILE
    #: How many leading columns the 2-bit codes of a search see (0: all). Columns after
    #: them enter the exact re-ranking and the clip summaries only (the StoryBeam set's
    #: hand placement: :mod:`retrieval.features.storybeam_set`).
    coded: int = 0

    @property
    def dim(self) -> int:
        return len(self.specs)

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.specs]

    @property
    def floor_joints(self) -> tuple[str, ...]:
        """The joints whose lowest defines the floor of "height" features: ankles and toes
        on the file's body; the ankles alone on the canonical body, whose toe is a fixed
        length along the source's ankle->toe direction — a direction rigs disagree on at
        rest (a flat or a pointed foot), so a standing ankle is the floor's only
        rig-independent mark."""
        return _ANKLES if self.body == "canonical" else _FOOT_JOINTS

    def joints_used(self) -> set[str]:
        used = {j for s in self.specs for j in s.joints}
        if any(s.kind in _FLOOR_KINDS for s in self.specs):
            used.update(_FOOT_JOINTS)
        return used

    @property
    def code_columns(self) -> int | None:
        """The columns the codes see, as :meth:`Quantizer.fit <retrieval.codes.Quantizer.fit>`
        takes them: None for all."""
        return self.coded if 0 < self.coded < self.dim else None

    @property
    def needs_fps(self) -> bool:
        """Whether a feature is a rate (its value depends on the frame rate)."""
        return any(s.kind in _RATE_KINDS for s in self.specs)

    def from_positions(self, pos: np.ndarray, joint_map: dict[str, int], body_size: float,
                       fps: float | None = None, rest: np.ndarray | None = None) -> np.ndarray:
        """(T, J, 3) positions in metres, Y up -> (T, dim) float64 features.

        ``joint_map`` maps canonical names to joint indices; ``body_size`` (metres) divides
        every length (not the heading rate, which is an angle per second and needs ``fps``);
        a set with ``normalise="chain"`` needs ``rest``, the (J, 3) rest-pose positions.
        """
        pos = np.asarray(pos, dtype=np.float64)
        if pos.ndim != 3 or pos.shape[2] != 3:
            raise FeatureError(f"positions must be (T, J, 3), got {pos.shape}")
        if not body_size > 0:
            raise FeatureError(f"body size must be positive, got {body_size}")
        missing = sorted(self.joints_used() - set(joint_map))
        if missing:
            raise FeatureError(f"feature set {self.name!r} needs joints {', '.join(missing)}")
        if self.body == "canonical":
            missing = sorted(set(CANONICAL_JOINTS) - set(joint_map))
            if missing:
                raise FeatureError(f"feature set {self.name!r} re-poses the canonical body: it needs joints "
                                   f"{', '.join(missing)}")
            pos, joint_map, body_size, rest = canonical_pose(pos, joint_map, body_size), CANONICAL_INDEX, 1.0, \
                canonical_rest()
        elif self.body != "source":
            raise FeatureError(f"feature set {self.name!r}: unknown body {self.body!r} (source or canonical)")

        def p(name: str) -> np.ndarray:
            return pos[:, joint_map[name]]

        floor = None
        axes: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray]] = {}
        out = np.empty((pos.shape[0], self.dim))
        scale = np.full(self.dim, 1.0 / body_size)
        if self.normalise == "chain":
            if rest is None:
                raise FeatureError(f"feature set {self.name!r} divides by chain lengths: it needs the rest pose")
            for k, spec in enumerate(self.specs):
                if spec.kind in ("distance", "above"):
                    length = chain_length(spec.joints[0], spec.joints[1], rest, joint_map)
                    if not length > 1e-6:
                        raise FeatureError(f"feature {spec.name!r}: zero rest length between {spec.joints}")
                    scale[k] = 1.0 / length
        elif self.normalise == "arms":
            if rest is None:
                raise FeatureError(f"feature set {self.name!r} divides by the arm length: it needs the rest pose")
            arms = arm_length(rest, joint_map)
            for k, spec in enumerate(self.specs):
                if any(j.endswith(("_hand", "_elbow")) for j in spec.joints):
                    scale[k] = 1.0 / arms
        for k, spec in enumerate(self.specs):
            if spec.kind == "distance":
                a, b = spec.joints
                out[:, k] = np.linalg.norm(p(a) - p(b), axis=1)
            elif spec.kind in _FLOOR_KINDS:
                if floor is None:
                    if self.floor_window > 0 and (fps is None or not fps > 0):
                        raise FeatureError(f"feature set {self.name!r} takes its floor over "
                                           f"{self.floor_window:g} s: it needs the frame rate")
                    window = int(round(self.floor_window * fps)) if self.floor_window > 0 else 0
                    floor = clip_floor(np.stack([p(f)[:, 1] for f in self.floor_joints], axis=1),
                                       window, self.floor_percentile)
                out[:, k] = np.min([p(j)[:, 1] for j in spec.joints], axis=0) - floor
            elif spec.kind == "above":
                a, b = spec.joints
                out[:, k] = p(a)[:, 1] - p(b)[:, 1]
            elif spec.kind in ("across", "forward"):
                if fps is None or not fps > 0:
                    raise FeatureError(f"feature {spec.name!r} smooths the heading over time: it needs the frame rate")
                key = tuple(spec.joints[2:])
                if key not in axes:
                    axes[key] = body_axes(pos, [joint_map[j] for j in key], fps)
                a, b = spec.joints[:2]
                h = (p(a) - p(b))[:, [0, 2]]
                out[:, k] = (h * axes[key][0 if spec.kind == "across" else 1]).sum(axis=1)
            elif spec.kind == "heading_rate":
                if fps is None or not fps > 0:
                    raise FeatureError(f"feature {spec.name!r} is a rate: it needs the frame rate")
                out[:, k] = heading_rate(pos, [joint_map[j] for j in spec.joints], fps)
                scale[k] = 1.0
            else:  # guarded at registration, kept for hand-made sets
                raise FeatureError(f"feature {spec.name!r}: unknown kind {spec.kind!r}")
        out = out * scale * np.array([s.weight for s in self.specs])
        if self.centre and len(out):
            out -= out.mean(axis=0)
        return out


#: Standard deviation (seconds) of the Gaussian that smooths the body's heading before
#: its rate is taken: long enough to average out the pelvis's and shoulders' swing over a
#: stride (about 1 s at a walk), short enough to keep a quarter turn (1–2 s) visible.
HEADING_SMOOTH_SECONDS = 0.25


def _across(pos: np.ndarray, pairs: Sequence[int]) -> np.ndarray:
    """(T, 2) sum of the unit horizontal (x, z) left→right vectors of the (left, right)
    joint-index ``pairs``: the body's across direction, pelvis and shoulder swing partly
    cancelling (zero where a pair's joints coincide horizontally)."""
    across = np.zeros((pos.shape[0], 2))
    for left, right in zip(pairs[0::2], pairs[1::2]):
        v = pos[:, right][:, [0, 2]] - pos[:, left][:, [0, 2]]
        n = np.linalg.norm(v, axis=1, keepdims=True)
        across += np.divide(v, n, out=np.zeros_like(v), where=n > 1e-9)
    return across


def body_axes(pos: np.ndarray, pairs: Sequence[int], fps: float,
              smooth_seconds: float = HEADING_SMOOTH_SECONDS) -> tuple[np.ndarray, np.ndarray]:
    """The body's own horizontal axes per frame: ((T, 2) unit left→right, (T, 2) unit
    forward), as (x, z) components, from the ``pairs`` of (left, right) joint indices
    (hips, shoulders; :func:`_across`), smoothed over time like :func:`heading_rate` (a
    Gaussian of ``smooth_seconds``, so the pelvis's swing over a stride does not rock
    the frame). Forward is up × left→right, i.e. the way the chest faces on a Y-up
    right-handed skeleton. Projecting a horizontal offset (a hand minus the neck) on
    them says *where* the hand is — out to the side, across the body, in front of the
    chest — whatever way the performer faces: what a distance cannot (a hand to the
    side and a hand in front are as far from the shoulder). Frames with no defined
    across direction keep the nearest defined one (all (1, 0) when none is)."""
    across = _across(np.asarray(pos, dtype=np.float64), pairs)
    sigma = smooth_seconds * fps
    if sigma > 0 and len(across) > 1:
        across = gaussian_filter1d(across, sigma, axis=0, mode="nearest")
    n = np.linalg.norm(across, axis=1)
    ok = n > 1e-9
    if not ok.any():
        across, n, ok = np.tile([1.0, 0.0], (len(across), 1)), np.ones(len(across)), np.ones(len(across), bool)
    elif not ok.all():
        idx = np.flatnonzero(ok)
        nearest = idx[np.clip(np.searchsorted(idx, np.arange(len(across))), 0, len(idx) - 1)]
        across, n = across[nearest], n[nearest]
    across = across / n[:, None]
    forward = np.column_stack([across[:, 1], -across[:, 0]])
    return across, forward


def heading_rate(pos: np.ndarray, pairs: Sequence[int], fps: float,
                 smooth_seconds: float = HEADING_SMOOTH_SECONDS) -> np.ndarray:
    """(T,) signed turning rate of the body about the vertical, in radians per second
    (positive = counter-clockwise seen from above, i.e. a left turn for a Y-up, Z-forward
    body).

    Method: ``pairs`` lists joint indices as (left, right) pairs (hips, shoulders); the
    body's *across* direction is the sum of the unit horizontal left→right vectors of the
    pairs, so pelvis and shoulder swing partly cancel. Its yaw angle is unwrapped, smoothed
    with a Gaussian of ``smooth_seconds`` (edges reflected), and differentiated with
    central differences times ``fps``. A rate rather than the heading itself, because the
    heading depends on which way the performer happens to face (the features must not),
    while its rate does not; the across vector of a rigid yaw rotates exactly with the
    body, so the rate is invariant to bone lengths, units, root offset and the up axis's
    horizontal frame, and it is resampled consistently (a rate, not a per-frame step)."""
    pos = np.asarray(pos, dtype=np.float64)
    across = _across(pos, pairs)
    if pos.shape[0] < 2:
        return np.zeros(pos.shape[0])
    yaw = np.unwrap(np.arctan2(-across[:, 1], across[:, 0]))
    sigma = smooth_seconds * fps
    if sigma > 0:
        yaw = gaussian_filter1d(yaw, sigma, mode="nearest")
    return np.gradient(yaw) * fps


def arm_length(rest: np.ndarray, joint_map: dict[str, int]) -> float:
    """Mean shoulder→elbow→hand length of both arms on the rest pose (metres)."""
    total = 0.0
    for side in ("left", "right"):
        total += chain_length(f"{side}_shoulder", f"{side}_hand", rest, joint_map)
    if not total > 1e-6:
        raise FeatureError("zero arm length, cannot normalise")
    return total / 2.0


def chain_length(a: str, b: str, rest: np.ndarray, joint_map: dict[str, int]) -> float:
    """Rest-pose length (metres) of the canonical chain joining canonical joints ``a`` and
    ``b``: the sum of the distances between consecutive canonical joints on the tree path
    a → common ancestor → b (:data:`~retrieval.motion.CANONICAL_PARENTS`), measured
    between the joints they map to, so a file's extra joints (clavicles, twist bones)
    do not count. Dividing a distance between a and b by it gives the fraction of the
    chain's full reach — the same number for the same joint angles whatever the
    performer's bone lengths, as long as the proportions *within* the chain agree."""
    def up(j: str) -> list[str]:
        out = [j]
        while CANONICAL_PARENTS[out[-1]] is not None:
            out.append(CANONICAL_PARENTS[out[-1]])
        return out

    pa, pb = up(a), up(b)
    common = next(j for j in pa if j in pb)
    path = pa[: pa.index(common) + 1] + pb[: pb.index(common)][::-1]
    pts = rest[[joint_map[j] for j in path]]
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def clip_floor(foot_heights: np.ndarray, window: int = 0,
               percentile: float = FLOOR_PERCENTILE) -> float | np.ndarray:
    """The floor of a clip from (T, k) foot-joint heights: a low ``percentile`` of each
    frame's lowest foot joint (see :data:`FLOOR_PERCENTILE`) over the whole clip, or,
    with ``window`` > 0, over the frames within ``window`` of each frame (a (T,) floor
    per frame, the clip's ends repeated; see :attr:`FeatureSet.floor_window`)."""
    if foot_heights.size == 0:
        return 0.0
    lowest = foot_heights.min(axis=1)
    if window > 0 and len(lowest) > 1:
        return percentile_filter(lowest, percentile, size=2 * window + 1, mode="nearest")
    return float(np.percentile(lowest, percentile))


def leg_length(skeleton: Skeleton, joint_map: dict[str, int] | None = None) -> float:
    """Mean hip→knee→ankle length of both legs on the rest pose, in metres."""
    jm = joint_map if joint_map is not None else canonical_joint_map(skeleton)
    rest = rest_positions(skeleton)
    total = 0.0
    for side in ("left", "right"):
        hip, knee, ankle = (rest[jm[f"{side}_{part}"]] for part in ("hip", "knee", "ankle"))
        total += np.linalg.norm(knee - hip) + np.linalg.norm(ankle - knee)
    size = total / 2.0
    if not size > 1e-6:
        raise FeatureError(f"skeleton {skeleton.name or '(unnamed)'}: zero leg length, cannot normalise")
    return float(size)


def _d(name: str, a: str, b: str, why: str) -> FeatureSpec:
    return FeatureSpec(name, "distance", (a, b), why)


#: The 17 Müller–Röder-style distances used by default (see the module docstring).
MR17 = FeatureSet(
    name="mr17",
    description="17 body-part distances after Müller & Röder, divided by leg length",
    specs=(
        _d("hand_hand", "left_hand", "right_hand", "clapping, arms spread, arm swing phase"),
        _d("ankle_ankle", "left_ankle", "right_ankle", "stride length, feet together"),
        _d("knee_knee", "left_knee", "right_knee", "leg spread independent of the feet"),
        _d("elbow_elbow", "left_elbow", "right_elbow", "arm opening"),
        _d("lhand_head", "left_hand", "head", "hand raised to the head"),
        _d("rhand_head", "right_hand", "head", "hand raised to the head"),
        _d("lhand_rshoulder", "left_hand", "right_shoulder", "arm swing across / away from the body"),
        _d("rhand_lshoulder", "right_hand", "left_shoulder", "arm swing across / away from the body"),
        _d("lankle_lhip", "left_ankle", "left_hip", "leg extension (knee bend)"),
        _d("rankle_rhip", "right_ankle", "right_hip", "leg extension (knee bend)"),
        _d("lhand_lshoulder", "left_hand", "left_shoulder", "arm extension (elbow bend)"),
        _d("rhand_rshoulder", "right_hand", "right_shoulder", "arm extension (elbow bend)"),
        FeatureSpec("lankle_height", "height", ("left_ankle",), "foot off the floor: kick, step, flight"),
        FeatureSpec("rankle_height", "height", ("right_ankle",), "foot off the floor: kick, step, flight"),
        FeatureSpec("hips_height", "height", ("hips",), "crouch, jump flight"),
        FeatureSpec("lhand_above_head", "above", ("left_hand", "head"), "arms raised vs down"),
        FeatureSpec("rhand_above_head", "above", ("right_hand", "head"), "arms raised vs down"),
    ),
)

_REGISTRY: dict[str, FeatureSet] = {}
_KINDS = {"distance": 2, "height": 1, "lowest": 2, "above": 2, "heading_rate": 4, "across": 6, "forward": 6}
#: Kinds measured above the clip's floor (:func:`clip_floor`).
_FLOOR_KINDS = ("height", "lowest")
#: Kinds whose value depends on the frame rate (a rate, or a heading smoothed over seconds).
_RATE_KINDS = ("heading_rate", "across", "forward")


def register_feature_set(feature_set: FeatureSet) -> FeatureSet:
    """Make ``feature_set`` available by name (an index stores the name it was built with)."""
    for s in feature_set.specs:
        if _KINDS.get(s.kind) != len(s.joints):
            raise FeatureError(f"feature {s.name!r}: kind {s.kind!r} with joints {s.joints}")
    _REGISTRY[feature_set.name] = feature_set
    return feature_set


def get_feature_set(name: str | FeatureSet = "mr17") -> FeatureSet:
    """The registered feature set called ``name`` (a FeatureSet passes through)."""
    if isinstance(name, FeatureSet):
        return name
    try:
        return _REGISTRY[name]
    except KeyError:
        raise FeatureError(f"unknown feature set {name!r} (known: {', '.join(sorted(_REGISTRY))})") from None


def available_feature_sets() -> list[str]:
    return sorted(_REGISTRY)


register_feature_set(MR17)

#: MR17 on the canonical body (:attr:`FeatureSet.body`): the same 17 columns, every frame
#: re-posed onto the canonical bone lengths first (issue 31: a pose on another skeleton),
#: heights above the floor within a second of the frame (:attr:`FeatureSet.floor_window`):
#: the pose search's set (:data:`~retrieval.library.POSE_FEATURE_SET`).
MR17_CANONICAL = register_feature_set(FeatureSet(
    name="mr17-canonical", specs=MR17.specs, body="canonical", floor_window=1.0,
    description="MR17 on the canonical body (the source's bone directions, canonical bone lengths), "
                "heights above the floor within a second"))


def motion_features(motion: Motion, feature_set: str | FeatureSet = "mr17") -> np.ndarray:
    """(T, dim) features of a motion: forward kinematics, canonical joints, leg length."""
    fs = get_feature_set(feature_set)
    jm = canonical_joint_map(motion.skeleton)
    return fs.from_positions(positions(motion), jm, leg_length(motion.skeleton, jm), motion.fps,
                             rest_positions(motion.skeleton))
