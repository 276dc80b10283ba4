"""Joining clips: loop points of cyclic clips, transition points between clips, and
root-aligned crossfades.

Two pose distances are used, for two jobs:

* :func:`pose_features` — joint positions relative to the root's ground point, with the
  root's heading removed and divided by leg length, plus their velocities. Exact but
  costs a (T×T) distance matrix in floats; used to find a cyclic clip's best loop.
* the retrieval quantiser's *frame codes* and their distance table
  (:mod:`retrieval.codes.quantizer`): one integer per frame and one table look-up per frame
  pair, the research's trick. :func:`find_transition` uses it to pick where to leave one
  clip and enter the next, which is what it was made for — many candidate pairs, cheap
  to compare.

A crossfade aligns the incoming clip's root (ground position and heading) with the
outgoing clip's at the transition frame, then slerps every joint over ``blend`` frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import cdist

from retrieval.animation.retarget import skeleton_leg_length
from retrieval.codes import table_lookup
from retrieval.errors import StoryBeamError
from retrieval.features import motion_features
from retrieval.motion import (
    Motion,
    axis_rotation,
    global_transforms,
    positions,
    slerp_matrices,
    world_from_native,
)


class TransitionError(StoryBeamError):
    """Clips cannot be joined (too short, different skeletons)."""


# --- headings and root alignment -------------------------------------------------------

def root_heading(motion: Motion) -> np.ndarray:
    """(T,) yaw in radians of the root's forward (+Z) axis, measured from +Z towards +X,
    in the Y-up world (the root's rotation is its global rotation)."""
    fwd = motion.rotations[:, 0, :, 2]  # third column: where the root's +Z points
    return np.arctan2(fwd[:, 0], fwd[:, 2])


def rotate_y(angle: np.ndarray | float) -> np.ndarray:
    """Rotation matrices about the world Y axis (yaw), positive from +Z towards +X."""
    return axis_rotation("Y", np.asarray(angle, dtype=np.float64))


def align_root(motion: Motion, frame: int, ground_xz: np.ndarray, yaw: float) -> Motion:
    """A copy of ``motion`` turned about Y and shifted on the ground so that at ``frame``
    its root stands over ``ground_xz`` (native units, x and z) with heading ``yaw``."""
    out = motion.copy()
    delta = float(yaw - root_heading(motion.slice(frame, frame + 1))[0])
    r = rotate_y(delta)
    pivot = motion.root_translation[frame].copy()
    rel = motion.root_translation - pivot
    rel[:, 1] = 0.0
    moved = rel @ r.T
    out.root_translation[:, 0] = moved[:, 0] + ground_xz[0]
    out.root_translation[:, 2] = moved[:, 2] + ground_xz[1]
    out.rotations[:, 0] = r @ motion.rotations[:, 0]
    return out


# --- pose features and loop points -----------------------------------------------------

def pose_features(motion: Motion, velocity_weight: float = 0.3) -> np.ndarray:
    """(T, F) heading-free, size-free pose descriptors (see module docstring)."""
    pos = positions(motion)
    leg = skeleton_leg_length(motion.skeleton)
    root = pos[:, :1].copy()
    root[..., 1] = 0.0
    rel = pos - root
    yaw = root_heading_world(motion)
    unturn = rotate_y(-yaw)  # (T, 3, 3)
    local = np.einsum("tab,tjb->tja", unturn, rel) / leg
    vel = np.gradient(local, axis=0) * motion.fps / 1.5 if motion.n_frames > 1 else np.zeros_like(local)
    # velocities in leg lengths per second, divided by a typical walking speed
    t = motion.n_frames
    return np.concatenate([local.reshape(t, -1), velocity_weight * vel.reshape(t, -1)], axis=1)


def root_heading_world(motion: Motion) -> np.ndarray:
    """Root heading in the Y-up world (differs from :func:`root_heading` only for
    Z-up source files)."""
    rot, _ = global_transforms(motion.slice(0, motion.n_frames))
    fwd = np.einsum("ab,tb->ta", world_from_native(motion.skeleton), rot[:, 0, :, 2])
    return np.arctan2(fwd[:, 0], fwd[:, 2])


def pose_distance(fa: np.ndarray, fb: np.ndarray) -> np.ndarray:
    """RMS distance between rows of two feature arrays, (A, B)."""
    return cdist(fa, fb) / np.sqrt(fa.shape[1])


@dataclass(frozen=True)
class LoopPoints:
    """Play frames ``start .. end-1``, then jump back to ``start`` (``end`` resembles
    ``start``). ``cost`` is the pose distance between frames ``end`` and ``start``."""

    start: int
    end: int
    cost: float

    @property
    def period(self) -> int:
        return self.end - self.start


def find_loop(
    motion: Motion,
    min_period_s: float = 0.6,
    max_period_s: float = 3.0,
    blend_frames: int = 0,
    features: np.ndarray | None = None,
) -> LoopPoints:
    """Best loop of a cyclic clip: the frame pair (start, end) with the smallest pose
    distance, at least ``min_period_s`` apart, leaving ``blend_frames`` after ``end`` for
    a crossfade. Longer loops win ties slightly (more variety, fewer seams)."""
    t = motion.n_frames
    lo = int(round(min_period_s * motion.fps))
    hi = int(round(max_period_s * motion.fps))
    if t - blend_frames - 1 < lo + 1:
        raise TransitionError(
            f"{motion.name or 'clip'}: {t} frames is too short to loop (needs a {min_period_s} s cycle)"
        )
    f = pose_features(motion) if features is None else features
    d = pose_distance(f, f)
    i, j = np.meshgrid(np.arange(t), np.arange(t), indexing="ij")
    gap = j - i
    valid = (gap >= lo) & (gap <= hi) & (j + blend_frames < t)
    score = np.where(valid, d - 0.002 * gap / max(hi, 1), np.inf)
    k = int(np.argmin(score))
    a, b = divmod(k, t)
    return LoopPoints(int(a), int(b), float(d[a, b]))


# --- crossfades --------------------------------------------------------------------------

def _smoothstep(x: np.ndarray) -> np.ndarray:
    return x * x * (3 - 2 * x)


def crossfade(x: Motion, y: Motion, i: int, j: int, blend: int) -> Motion:
    """``x[:i]``, then ``blend`` frames fading from ``x[i:]`` into ``y[j:]`` (``y`` aligned
    so that its frame ``j`` stands where ``x``'s frame ``i`` stands, same heading), then
    the rest of ``y``. Needs ``i + blend <= len(x)`` and ``j + blend <= len(y)``."""
    if x.skeleton.names != y.skeleton.names:
        raise TransitionError("cannot join clips on different skeletons; retarget them first")
    blend = int(max(0, min(blend, x.n_frames - i, y.n_frames - j)))
    pos_i = x.root_translation[i, [0, 2]]
    yaw_i = float(root_heading(x.slice(i, i + 1))[0])
    ya = align_root(y, j, pos_i, yaw_i)
    if abs(y.fps - x.fps) > 1e-6:
        raise TransitionError(f"clips have different frame rates ({x.fps} and {y.fps}); resample first")
    parts_rot = [x.rotations[:i]]
    parts_root = [x.root_translation[:i]]
    if blend:
        w = _smoothstep((np.arange(blend) + 1.0) / (blend + 1.0))
        xr, yr = x.rotations[i : i + blend], ya.rotations[j : j + blend]
        parts_rot.append(slerp_matrices(xr, yr, np.broadcast_to(w[:, None], xr.shape[:2])))
        xt, yt = x.root_translation[i : i + blend], ya.root_translation[j : j + blend]
        parts_root.append(xt * (1 - w[:, None]) + yt * w[:, None])
    parts_rot.append(ya.rotations[j + blend :])
    parts_root.append(ya.root_translation[j + blend :])
    return Motion(x.skeleton, np.concatenate(parts_rot), np.concatenate(parts_root), x.fps,
                  x.name if x.name == y.name else f"{x.name}+{y.name}")


def loop_motion(motion: Motion, loop: LoopPoints, n_cycles: int, blend: int) -> Motion:
    """``n_cycles`` repetitions of the loop (plus the lead-in before ``loop.start`` and
    the tail after ``loop.end``), each seam crossfaded over ``blend`` frames with the root
    carried on, so the character keeps walking forward instead of jumping back."""
    if loop.end + blend > motion.n_frames:
        raise TransitionError("loop end leaves no frames for the crossfade")
    out = motion
    seam = loop.end  # output index of the current copy's loop end
    for _ in range(max(0, n_cycles - 1)):
        out = crossfade(out, motion, seam, loop.start, blend)
        seam += loop.period
    return out


# --- transitions between different clips -----------------------------------------------

@dataclass(frozen=True)
class Transition:
    """Leave clip A at frame ``a_frame`` and enter clip B at ``b_frame``; ``cost`` is the
    code-table distance summed over a short window (see :func:`find_transition`)."""

    a_frame: int
    b_frame: int
    cost: float


def code_cost_matrix(codes_a: np.ndarray, codes_b: np.ndarray, table) -> np.ndarray:
    """(A, B) code-table distances between every frame of A and every frame of B."""
    aa = np.repeat(codes_a[:, None], len(codes_b), axis=1)
    bb = np.repeat(codes_b[None, :], len(codes_a), axis=0)
    return np.asarray(table_lookup(table, aa.ravel(), bb.ravel()), dtype=np.float64).reshape(aa.shape)


def find_transition(
    cost: np.ndarray,
    window: int,
    a_range: tuple[int, int] | None = None,
    b_range: tuple[int, int] | None = None,
    refine=None,
    shortlist: int = 100,
) -> Transition:
    """Cheapest (a, b) in a frame-to-frame cost matrix, comparing ``window`` frames
    ahead (a crossfade of that length needs the two clips to *stay* alike, not only to
    touch): ``sum_k cost[a + k, b + k]``. With ``refine(a, b) -> float`` the
    ``shortlist`` cheapest pairs are re-ranked by it."""
    na, nb = cost.shape
    w = max(1, int(window))
    a0, a1 = a_range or (0, na)
    b0, b1 = b_range or (0, nb)
    a1, b1 = min(a1, na - w), min(b1, nb - w)
    if a1 <= a0 or b1 <= b0:
        raise TransitionError("clips too short for a transition window")
    # Sum along diagonals with a cumulative sum over the (a+k, b+k) shift.
    acc = np.zeros((a1 - a0, b1 - b0))
    for k in range(w):
        acc += cost[a0 + k : a1 + k, b0 + k : b1 + k]
    if refine is None:
        k = int(np.argmin(acc))
        ia, ib = divmod(k, acc.shape[1])
        return Transition(a0 + ia, b0 + ib, float(acc[ia, ib] / w))
    # Two stages: the cheap table ranks every pair, the exact measure picks among the
    # best ``shortlist`` (2-bit codes tie often; the exact distance breaks the ties).
    flat = acc.ravel()
    top = np.argpartition(flat, min(shortlist, flat.size) - 1)[:shortlist]
    best = min(top, key=lambda k: refine(a0 + k // acc.shape[1], b0 + k % acc.shape[1]))
    ia, ib = divmod(int(best), acc.shape[1])
    return Transition(a0 + ia, b0 + ib, float(acc[ia, ib] / w))


# --- the research's code table as a transition cost ------------------------------------

def code_transition_cost(quantizer, table=None):
    """A ``cost(a, b) -> (A, B)`` function for :func:`find_transition` and
    :func:`retrieval.animation.path_follow.follow_path` that compares frames by their 2-bit PCA
    codes through the code-distance table (see :mod:`retrieval.codes.quantizer`): one look-up
    per frame pair. ``quantizer`` is a fitted :class:`~retrieval.codes.quantizer.Quantizer`
    (e.g. ``MotionIndex.matcher.quantizer``); ``table`` defaults to its own table."""
    tab = quantizer.table() if table is None else table

    def cost(a: Motion, b: Motion) -> np.ndarray:
        ca = quantizer.encode(motion_features(a))
        cb = quantizer.encode(motion_features(b))
        return code_cost_matrix(ca, cb, tab)

    return cost


def pose_cost(a: Motion, b: Motion) -> np.ndarray:
    """The exact (float) pose distance matrix, for judging transitions."""
    return pose_distance(pose_features(a), pose_features(b))


@dataclass(frozen=True)
class TransitionJudgement:
    """Pose distance (leg lengths, windowed like :func:`find_transition`) of the
    transition picked by the code table, against random transition points."""

    chosen: Transition
    chosen_pose_cost: float
    random_pose_cost_mean: float
    random_pose_cost_median: float
    random_beaten_fraction: float


def judge_transition(
    a: Motion, b: Motion, code_cost, window: int, n_random: int = 200, seed: int = 0, refine: bool = False
) -> TransitionJudgement:
    """Pick the transition (a -> b) by ``code_cost`` (re-ranking its shortlist on the
    exact distance when ``refine``) and score it, and ``n_random`` uniformly random
    transition points, on the exact pose distance."""
    exact = pose_cost(a, b)
    w = max(1, int(window))

    def windowed(i: int, j: int) -> float:
        return float(np.mean([exact[i + k, j + k] for k in range(w)]))

    chosen = find_transition(code_cost(a, b), window, refine=windowed if refine else None)

    rng = np.random.default_rng(seed)
    ri = rng.integers(0, a.n_frames - w, n_random)
    rj = rng.integers(0, b.n_frames - w, n_random)
    rand = np.array([windowed(i, j) for i, j in zip(ri, rj)])
    c = windowed(chosen.a_frame, chosen.b_frame)
    return TransitionJudgement(chosen, c, float(rand.mean()), float(np.median(rand)), float(np.mean(c < rand)))
