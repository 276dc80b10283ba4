"""The frontal feature set (``"frontal"``): MR17's body-part distances as *one camera in
front of the body* sees them, for "Act it out" (a child performs, the tablet's camera
films, the library answers).

Why: a monocular pose estimator's depth (the coordinate along the camera's axis) is its
worst coordinate — on synthetic performances MediaPipe's world landmarks are 11–17 cm off
per joint in depth, against a few cm across the image — and 3-D distances mix that error
into every feature (issue 18: 0.48 class accuracy with 3-D MR17 against 0.78 frontal).
So depth is dropped, for the library and the query alike:

1. **Turn to face the camera.** The clip is turned about the vertical so that its *mean
   heading* faces +Z (the camera): the body's *across* direction (left→right hip plus
   left→right shoulder, horizontal, unit vectors summed over the clip —
   :func:`mean_heading`) is rotated onto −X, the direction a body facing +Z has from its
   left hip to its right hip in StoryBeam's Y-up world. A performer who faces the tablet
   and a library walk that travels along any direction then agree.
2. **Drop depth.** Z is set to 0: every "distance" is then a 2-D distance in the frontal
   (X, Y) plane, every "height" and "above" is unchanged (it is vertical already).
3. **MR17's 17 features** (:data:`~retrieval.features.relational.MR17`) on those frontal
   positions. Heights need the root's true height above the floor; a camera query gets
   it from the image (:mod:`retrieval.motion.landmarks`).
4. **Arms per arm length** (``normalise="arms"``): a feature involving a hand or an
   elbow is divided by the arm length (shoulder→elbow→hand), every other by the leg
   length. The performer's proportions are not the library's: the human-proportioned
   test figure's arm is 0.65 leg lengths, the kid character's 0.70, the 15 CMU skeletons'
   0.52–0.61 (median 0.58); per-leg-length arm features then carry a per-performer
   bias (+0.1 leg lengths on hand distances, measured on the tuning renders) that
   per-arm-length ones do not. A camera take has no rest pose, so its bone lengths are
   measured over the take (:func:`measured_rest`). Measured on the tuning seed's 30
   "person" takes (MediaPipe 0.10.21 as the estimator, whole-clip library), 1-NN with
   the trial left out: per leg length 0.67, per arm length
   0.80, per chain length (``"chain"``) 0.77, the true-joint ceiling 0.80 for all
   three (``frontal_legs`` and ``frontal_chain`` stay registered for that comparison).

5. **Leg extension relative to the segment** (:attr:`FrontalFeatureSet.relative`): the
   two ankle–hip distances are divided by their (joint) median over the clip — over the
   take for a query, over each library window for the act search
   (:meth:`FrontalFeatureSet.relative_to_segment`). They say how far the legs are
   stretched relative to what is usual in that segment, not relative to a leg length
   measured through the knees: on the kid character BlazePose puts the knees about 0.23
   leg lengths low, so the measured hip→knee→ankle length is long and, per that length,
   every ankle–hip distance came out 0.17–0.22 short (legs read as bent: walks answered
   as runs and jumps). Dividing by a scalar per segment is idempotent, so a window cut
   from a clip whose features were made relative over the whole clip gets the same
   values as the window made relative on its own. Measured on seed 1 (60 takes per
   figure, ``ar.body``, with :func:`~retrieval.motion.landmarks.consistent_sides`):
   kid 0.633 → 0.733, person 0.933 → 0.933, true-joint ceiling 0.933 → 0.933
   (docs/notebook/act-it-out.md).

6. **Heights weighted ×2, standing on a higher floor** (:data:`HEIGHT_WEIGHT`,
   :data:`FRONTAL_FLOOR_PERCENTILE`): the three heights (hips and ankles above the
   floor) count twice in the distance, so a jump's flight — the body leaving the floor, the clearest
   thing a child does — is not outvoted by the 14 arm and leg-spread columns; and the
   floor is the 30th percentile of the per-frame lowest foot, not the 2nd. The floor
   first: a foot kicking towards a near lens comes nearer and reads *lower* in the image
   (at 2.2 m a foot 0.6 m nearer is magnified 1.4×), so the 2nd percentile of the lowest
   foot sat on the kick's lowest frames, 0.2 leg lengths under the standing foot, and
   every height of the take read 0.2 L high (hips 1.25 → 1.45 L on CMU's kicks filmed
   "towards" and "wide-close", ``storybeam bench act-cameras``): kicks answered walk or
   jump. The standing foot spends most of any take on the floor, so the 30th percentile
   is the floor it stands on, for mocap and camera alike. Weighting the heights alone
   multiplied that error (towards-up kicks 0.89 → 0.11); with the floor fixed the
   weighting helps every condition of the synthetic bench (mean 0.904 → 0.936), the
   rendered guard (seed 2: person 0.883 → 0.950, kid 0.750 → 0.783) and the real
   development set (25 → 30 of 47). Variants and figures: docs/notebook/act-it-out.md,
   2026-11-28, second session.

No turning rate: with depth dropped, a turn is not observable from the frontal
coordinates, and the performer faces the tablet anyway. A body that turns inside the
clip (a pirouette) is seen as the camera sees it: from the side for part of the clip.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from retrieval.features.relational import MR17, FeatureError, FeatureSet, register_feature_set
from retrieval.motion import CANONICAL_JOINTS, CANONICAL_PARENTS

#: Canonical joints whose left→right vectors give the body's across direction.
ACROSS_PAIRS: tuple[tuple[str, str], ...] = (("left_hip", "right_hip"), ("left_shoulder", "right_shoulder"))


def mean_heading(pos: np.ndarray, joint_map: dict[str, int]) -> float:
    """The clip's mean heading (radians, about +Y): the yaw of the summed unit horizontal
    left→right vectors of the hips and the shoulders over every frame, measured so that a
    body facing +Z (its right side on −X) has heading 0 and positive is a turn to the
    body's left (counter-clockwise seen from above). A clip with no horizontal across
    vector (all frames degenerate) has heading 0."""
    pos = np.asarray(pos, dtype=np.float64)
    total = np.zeros(2)
    for left, right in ACROSS_PAIRS:
        v = pos[:, joint_map[right]][:, [0, 2]] - pos[:, joint_map[left]][:, [0, 2]]
        n = np.linalg.norm(v, axis=1, keepdims=True)
        ok = (n[:, 0] > 1e-9) & np.all(np.isfinite(v), axis=1)
        total += (v[ok] / n[ok]).sum(axis=0)
    if not np.linalg.norm(total) > 1e-9:
        return 0.0
    # across of a body facing +Z is (-1, 0) in (x, z); a yaw of a turns it to (-cos a, sin a)
    return float(np.arctan2(total[1], -total[0]))


def face_camera(pos: np.ndarray, joint_map: dict[str, int], keep_depth: bool = False) -> np.ndarray:
    """(T, J, 3) positions turned about +Y (through the origin) so the clip's
    :func:`mean_heading` is 0 (facing +Z), depth (Z) set to 0 unless ``keep_depth``."""
    pos = np.asarray(pos, dtype=np.float64)
    a = -mean_heading(pos, joint_map)
    c, s = np.cos(a), np.sin(a)
    rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # yaw by a (right-handed, Y up)
    out = pos @ rot.T
    if not keep_depth:
        out[..., 2] = 0.0
    return out


@dataclass(frozen=True)
class FrontalFeatureSet(FeatureSet):
    """A :class:`FeatureSet` computed on the clip turned to face the camera with depth
    dropped (:func:`face_camera`); ``keep_depth`` keeps Z (an ablation: turned, 3-D)."""

    keep_depth: bool = False
    #: Features divided by their joint median over the segment (see the module
    #: docstring, step 5): names of distance features of ``specs``.
    relative: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        unknown = [n for n in self.relative if n not in self.names]
        if unknown:
            raise FeatureError(f"feature set {self.name!r}: relative features {', '.join(unknown)} are not among "
                               f"its features")

    def relative_to_segment(self, features: np.ndarray) -> np.ndarray:
        """(T, dim) features with the :attr:`relative` columns divided by the median over
        the T frames of their per-frame mean (one divisor for them all; left unchanged
        when that median is not positive or T is 0). A new float64 array; idempotent."""
        out = np.array(features, dtype=np.float64)
        if not self.relative or len(out) == 0:
            return out
        if out.ndim != 2 or out.shape[1] != self.dim:
            raise FeatureError(f"feature set {self.name!r}: features must be (T, {self.dim}), got {out.shape}")
        cols = [self.names.index(n) for n in self.relative]
        typical = float(np.median(out[:, cols].mean(axis=1)))
        if typical > 1e-9:
            out[:, cols] /= typical
        return out

    def from_positions(self, pos: np.ndarray, joint_map: dict[str, int], body_size: float,
                       fps: float | None = None, rest: np.ndarray | None = None) -> np.ndarray:
        pos = np.asarray(pos, dtype=np.float64)
        if pos.ndim != 3 or pos.shape[2] != 3:
            raise FeatureError(f"positions must be (T, J, 3), got {pos.shape}")
        missing = sorted({j for pair in ACROSS_PAIRS for j in pair} - set(joint_map))
        if missing:
            raise FeatureError(f"feature set {self.name!r} needs joints {', '.join(missing)}")
        return self.relative_to_segment(super().from_positions(face_camera(pos, joint_map, self.keep_depth),
                                                               joint_map, body_size, fps, rest))


#: Weight of the three "height" features in the frontal set (module docstring, step 6).
HEIGHT_WEIGHT = 2.0
#: Percentile of the per-frame lowest foot the frontal set's heights stand on (step 6).
FRONTAL_FLOOR_PERCENTILE = 30.0

#: The registered frontal set: MR17's specs on the turned, depth-free clip, arm features
#: divided by the arm length, heights weighted and on the frontal floor (see the module
#: docstring).
FRONTAL = register_feature_set(FrontalFeatureSet(
    name="frontal",
    specs=tuple(replace(s, weight=HEIGHT_WEIGHT) if s.kind == "height" else s for s in MR17.specs),
    normalise="arms",
    description="MR17 on the clip turned to its mean heading, depth dropped (one camera in front), "
                "arm features per arm length, ankle-hip distances per their median over the segment, "
                f"heights x{HEIGHT_WEIGHT:g} above the {FRONTAL_FLOOR_PERCENTILE:g}th percentile of the "
                "lowest foot",
    relative=("lankle_lhip", "rankle_rhip"),
    floor_percentile=FRONTAL_FLOOR_PERCENTILE,
))





#: Direction of each canonical bone (child relative to parent) in the T-pose that
#: :func:`measured_rest` lays the measured lengths along (only lengths matter to the
#: normalisations that read a rest pose).
_T_POSE_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "spine": (0, 1, 0), "neck": (0, 1, 0), "head": (0, 1, 0),
    "left_shoulder": (1, 0, 0), "left_elbow": (1, 0, 0), "left_hand": (1, 0, 0),
    "right_shoulder": (-1, 0, 0), "right_elbow": (-1, 0, 0), "right_hand": (-1, 0, 0),
    "left_hip": (1, 0, 0), "left_knee": (0, -1, 0), "left_ankle": (0, -1, 0), "left_toe": (0, 0, 1),
    "right_hip": (-1, 0, 0), "right_knee": (0, -1, 0), "right_ankle": (0, -1, 0), "right_toe": (0, 0, 1),
}


def measured_rest(pos: np.ndarray, joint_map: dict[str, int]) -> np.ndarray:
    """A rest pose (J, 3) for a clip that has none (a camera take): every canonical bone
    gets its median 3-D length over the clip, laid out as a T-pose. Bone lengths do not
    change with the pose, so the median is the estimator's best guess of the body's."""
    pos = np.asarray(pos, dtype=np.float64)
    rest = np.zeros((pos.shape[1], 3))
    for name in CANONICAL_JOINTS:  # parents come first
        parent = CANONICAL_PARENTS[name]
        if parent is None or name not in joint_map or parent not in joint_map:
            continue
        length = float(np.median(np.linalg.norm(pos[:, joint_map[name]] - pos[:, joint_map[parent]], axis=1)))
        rest[joint_map[name]] = rest[joint_map[parent]] + length * np.array(_T_POSE_DIRECTIONS[name], float)
    return rest


for _norm in ("legs", "chain"):  # the normalisations it was compared with (docs/notebook/act-it-out.md)
    register_feature_set(FrontalFeatureSet(name=f"frontal_{_norm}", specs=MR17.specs, normalise=_norm))

__all__ = ["ACROSS_PAIRS", "FRONTAL", "FRONTAL_FLOOR_PERCENTILE", "HEIGHT_WEIGHT", "FrontalFeatureSet", "face_camera",
           "mean_heading", "measured_rest"]
