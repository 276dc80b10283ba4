"""Foot locking with an analytic two-bone leg IK on the canonical skeleton.

Moving the root can hold *one* standing foot still, but not two (double support), and
not the heel-then-toe roll of a step after the body has been bent along a curve. So each
foot point (ankle, toe) that is on the ground is pinned to one spot for its whole
contact (the median of where it was), with short linear fades in and out, and each leg
is re-solved to reach it: hip fixed, thigh and shin lengths fixed, knee kept in the
plane the original knee bent in, foot orientation unchanged. Closed form, vectorised
over frames, no iterations.
"""
from __future__ import annotations

import numpy as np

from retrieval.animation.retarget import sole_points
from retrieval.motion import Motion, axis_rotation, global_transforms, min_rotation


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of each run of True."""
    m = np.concatenate([[False], mask.astype(bool), [False]])
    d = np.diff(m.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _anchor_track(points: np.ndarray, contact: np.ndarray, fade: int) -> tuple[np.ndarray, np.ndarray]:
    """(T, 2) anchor xz and (T,) weight for one foot point: weight 1 during each contact
    run (anchor = median position of the run), fading linearly to 0 over ``fade``
    frames on both sides."""
    t = len(points)
    anchor = points[:, [0, 2]].copy()
    weight = np.zeros(t)
    for a, b in _runs(contact):
        if b - a < 2:
            continue
        spot = np.median(points[a:b][:, [0, 2]], axis=0)
        lo, hi = max(0, a - fade), min(t, b + fade)
        ramp = np.ones(hi - lo)
        k = np.arange(lo, hi)
        before, after = k < a, k >= b
        ramp[before] = 1.0 - (a - k[before]) / (fade + 1.0)
        ramp[after] = 1.0 - (k[after] - b + 1) / (fade + 1.0)
        take = ramp > weight[lo:hi]
        weight[lo:hi] = np.where(take, ramp, weight[lo:hi])
        anchor[lo:hi] = np.where(take[:, None], spot, anchor[lo:hi])
    return anchor, weight


def two_bone_knee(hip: np.ndarray, target: np.ndarray, knee_hint: np.ndarray, l1: float, l2: float) -> np.ndarray:
    """Knee positions (T, 3) so that |knee-hip| = l1 and |target-knee| = l2 (the target
    pulled in to reach if it is too far), bending towards ``knee_hint``."""
    axis = target - hip
    d = np.linalg.norm(axis, axis=-1, keepdims=True)
    d_ok = np.clip(d, abs(l1 - l2) + 1e-6, l1 + l2 - 1e-6)
    u = axis / np.maximum(d, 1e-12)
    x = (l1 * l1 - l2 * l2 + d_ok * d_ok) / (2 * d_ok)
    y = np.sqrt(np.maximum(l1 * l1 - x * x, 0.0))
    pole = knee_hint - hip
    pole = pole - np.sum(pole * u, axis=-1, keepdims=True) * u
    pn = np.linalg.norm(pole, axis=-1, keepdims=True)
    fallback = np.cross(u, np.array([1.0, 0.0, 0.0]))
    pole = np.where(pn > 1e-9, pole / np.maximum(pn, 1e-12), fallback / np.maximum(np.linalg.norm(fallback, axis=-1, keepdims=True), 1e-12))
    return hip + u * x + pole * y


def lock_feet(motion: Motion, contact: np.ndarray, fade_frames: int = 3) -> Motion:
    """``motion`` (canonical skeleton, Y up) with the sole points flagged in ``contact``
    (T, 4, in :data:`retrieval.animation.retarget.SOLE_POINTS` order: left heel, left toe tip,
    right heel, right toe tip) held still on the table."""
    sk = motion.skeleton
    rot, pos = global_transforms(motion)
    soles = sole_points(motion, rot, pos) / sk.metres_per_unit  # native units, like pos
    out = motion.copy()
    for side, (ih, it) in (("left", (0, 1)), ("right", (2, 3))):
        hip, knee, ankle = (sk.index(f"{side}_{n}") for n in ("hip", "knee", "ankle"))
        anc_h, w_h = _anchor_track(soles[:, ih], contact[:, ih], fade_frames)
        anc_t, w_t = _anchor_track(soles[:, it], contact[:, it], fade_frames)
        if not (w_h.any() or w_t.any()):
            continue
        # The foot is rigid: move it so the locked sole point(s) stay on their spot.
        shift_h = anc_h - soles[:, ih][:, [0, 2]]
        shift_t = anc_t - soles[:, it][:, [0, 2]]
        # One pivot per foot: the toe tip once it is down (the foot rolls over it), else
        # the heel; a short crossfade between the two keeps the foot from jumping.
        pivot_toe = np.clip(w_t, 0.0, 1.0)
        shift = (1 - pivot_toe)[:, None] * shift_h * w_h[:, None] + pivot_toe[:, None] * shift_t
        target = pos[:, ankle].copy()
        target[:, [0, 2]] += shift
        # Both heel and toe down (a flat foot): also turn the foot about the vertical
        # through the pinned toe so the heel stays on its spot too (bending the path
        # turns the body, and the foot with it, while it stands).
        both = np.minimum(w_h, w_t)
        toe_now = soles[:, it][:, [0, 2]] + shift
        heel_now = soles[:, ih][:, [0, 2]] + shift
        v_now, v_want = heel_now - toe_now, anc_h - toe_now
        ang = np.arctan2(v_now[:, 0], v_now[:, 1]) - np.arctan2(v_want[:, 0], v_want[:, 1])
        ang = -np.angle(np.exp(1j * ang)) * both * (pivot_toe > 0.5)
        yaw = axis_rotation("Y", ang)
        rel = target[:, [0, 2]] - toe_now
        c, sn = np.cos(ang), np.sin(ang)
        target[:, 0] = toe_now[:, 0] + c * rel[:, 0] + sn * rel[:, 1]
        target[:, 2] = toe_now[:, 1] - sn * rel[:, 0] + c * rel[:, 1]
        foot_rot = yaw @ rot[:, ankle]
        l1 = float(np.linalg.norm(sk.joints[knee].offset))
        l2 = float(np.linalg.norm(sk.joints[ankle].offset))
        new_knee = two_bone_knee(pos[:, hip], target, pos[:, knee], l1, l2)
        g_parent = rot[:, sk.joints[hip].parent]
        g_hip = min_rotation(pos[:, knee] - pos[:, hip], new_knee - pos[:, hip]) @ rot[:, hip]
        g_knee_tmp = g_hip @ motion.rotations[:, knee]
        shin_now = np.einsum("tab,b->ta", g_knee_tmp, sk.joints[ankle].offset)
        g_knee = min_rotation(shin_now, target - new_knee) @ g_knee_tmp
        tr = lambda m: np.swapaxes(m, -1, -2)
        # Where the ankle really ends up (the target may be out of the leg's reach, e.g.
        # at toe-off with the leg stretched behind): there the foot turns about the
        # ankle so that the pinned sole point still lands on its spot — the ankle
        # extends instead of the toe sliding.
        shin_dir = target - new_knee
        ankle_now = new_knee + l2 * shin_dir / np.maximum(np.linalg.norm(shin_dir, axis=1, keepdims=True), 1e-12)
        g_foot = foot_rot
        pin = np.where((pivot_toe > 0.5)[:, None], np.concatenate([anc_t, soles[:, it][:, 1:2]], axis=1)[:, [0, 2, 1]],
                       np.concatenate([anc_h, soles[:, ih][:, 1:2]], axis=1)[:, [0, 2, 1]])
        pin_point = np.where((pivot_toe > 0.5)[:, None], soles[:, it], soles[:, ih])
        foot_vec = np.einsum("tab,tb->ta", yaw, pin_point - pos[:, ankle])  # ankle -> pinned point, turned
        want = pin - ankle_now
        weight = np.maximum(w_h, w_t)
        turn = min_rotation(foot_vec, want)
        # only where the reach was short (elsewhere want == foot_vec up to rounding)
        short = np.linalg.norm(ankle_now - target, axis=1) > 1e-6 * max(l1 + l2, 1e-9)
        apply = short & (weight > 0)
        g_foot = np.where(apply[:, None, None], turn @ g_foot, g_foot)
        out.rotations[:, hip] = tr(g_parent) @ g_hip
        out.rotations[:, knee] = tr(g_hip) @ g_knee
        out.rotations[:, ankle] = tr(g_knee) @ g_foot  # the foot keeps its orientation unless out of reach
    return out
