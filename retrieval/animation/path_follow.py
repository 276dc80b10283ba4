"""Make a retargeted clip walk along a path a child drew on the table.

The path is a 2-D polyline on the table in metres. StoryBeam's motion world is Y up with
the table at y = 0; it is the AR *scene frame* (``ar/render/projector_view.py``): origin
at the board centre, X = board x, Z = board y (board z points into the table). The path
arrives already in scene ``(X, Z)``: the app lays a story's table paths into the scene
with its one mapping, :func:`app.player.placement.table_to_scene`.

How a clip is laid on the path (all IK-free):

1. **Clip space.** A cyclic clip (walk, run) is looped at its best loop point
   (:func:`retrieval.animation.transitions.find_loop`) until it covers the path; one-shot clips are
   crossfaded in at chosen distances. This gives one long motion that travels wherever
   the capture travelled.
2. **Its own course.** The root's ground track is smoothed over one gait cycle: the
   smoothed track ``C(t)`` is where the clip is *going* (its arc length ``S(t)`` and
   heading ``phi(t)``, which carries the clip's own heading drift); the rest,
   ``L(t) = R(-phi) (root - C)``, is the sway of the hips within a step.
3. **Bending.** Output time runs the clip at a rate k (0.7–1.4×, fitted to a duration or
   to the path's timestamps); at clip time t the character is at arc length ``S(t)`` of
   the (lightly smoothed) path: root = ``P(S) + R(theta(S)) L(t)``, and the whole body
   is turned by ``theta(S) - phi(t)`` so it faces along the path tangent. Distance along
   the path equals distance the clip travels, so time-scaling never makes feet slide.
4. **Planting.** Bending turns the body about the root, so on curves a standing foot
   would slide by about (foot's distance from the centre line / radius) of the step.
   During contacts the root is moved by minus the stance foot's slide, which plants it;
   the small accumulated offset is bled off slowly so the path error stays bounded.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d, uniform_filter1d

from retrieval.animation.foot_lock import lock_feet
from retrieval.animation.retarget import (
    contacts,
    skeleton_leg_length,
    sole_level,
    sole_points,
)
from retrieval.animation.transitions import (
    LoopPoints,
    TransitionError,
    crossfade,
    find_loop,
    find_transition,
    loop_motion,
    pose_distance,
    pose_features,
    root_heading,
    rotate_y,
)
from retrieval.errors import StoryBeamError
from retrieval.motion import Motion, rest_positions, slerp_matrices

#: Playback-rate limits that still look natural.
RATE_LIMITS = (0.7, 1.4)


class PathError(StoryBeamError):
    """A path is unusable (too few points, zero length, not finite)."""


# --- the path ------------------------------------------------------------------------------

@dataclass
class TablePath:
    """A polyline on the table, ``points`` (N, 2) metres in board coordinates, with
    optional ``times`` (N,) seconds at which the character should pass each point."""

    points: np.ndarray
    times: np.ndarray | None = None

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
            raise PathError(f"a path needs at least two (x, y) points, got shape {p.shape}")
        if not np.isfinite(p).all():
            raise PathError("path points must be finite numbers")
        keep = np.concatenate([[True], np.linalg.norm(np.diff(p, axis=0), axis=1) > 1e-9])
        p = p[keep]
        if len(p) < 2:
            raise PathError("path has zero length (all points coincide)")
        self.points = p
        if self.times is not None:
            t = np.asarray(self.times, dtype=np.float64)[keep]
            if t.shape != (len(p),) or not np.isfinite(t).all() or np.any(np.diff(t) <= 0):
                raise PathError("path times must be finite, one per point, strictly increasing")
            self.times = t - t[0]

    @property
    def cumulative(self) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(self.points, axis=0), axis=1))])

    @property
    def length(self) -> float:
        return float(self.cumulative[-1])


def straight_path(length_m: float = 0.6, start=(0.0, 0.0), heading_deg: float = 0.0, n: int = 2) -> TablePath:
    """A straight path of ``length_m`` from ``start`` (heading 0 = board +x)."""
    h = np.radians(heading_deg)
    s = np.linspace(0.0, length_m, max(2, n))
    return TablePath(np.asarray(start) + np.outer(s, [np.cos(h), np.sin(h)]))


def s_curve_path(length_m: float = 0.6, amplitude_m: float = 0.08, start=(0.0, 0.0), n: int = 60) -> TablePath:
    """An S: a sine of one full period and ``amplitude_m`` across a ``length_m`` run along +x."""
    x = np.linspace(0.0, length_m, n)
    y = amplitude_m * np.sin(2 * np.pi * x / length_m)
    return TablePath(np.asarray(start) + np.stack([x, y], axis=1))


@dataclass
class _Curve:
    """Dense, smoothed arc-length parametrisation of a path: position and heading."""

    s: np.ndarray
    xz: np.ndarray
    heading: np.ndarray  # unwrapped yaw of the tangent, from +Z towards +X

    def at(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = np.asarray(d, dtype=np.float64)
        x = np.interp(d, self.s, self.xz[:, 0])
        z = np.interp(d, self.s, self.xz[:, 1])
        h = np.interp(d, self.s, self.heading)
        # Beyond the ends, continue straight along the end tangent.
        for mask, k in ((d < 0, 0), (d > self.s[-1], -1)):
            if np.any(mask):
                over = d[mask] - self.s[k]
                x[mask] = self.xz[k, 0] + over * np.sin(self.heading[k])
                z[mask] = self.xz[k, 1] + over * np.cos(self.heading[k])
        return np.stack([x, z], axis=-1), h


def _smooth_curve(path: TablePath, sigma_m: float, step_m: float = 0.001) -> _Curve:
    """Resample the polyline every ``step_m`` and smooth it (Gaussian, ``sigma_m``) so the
    heading turns gradually through the corners of a hand-drawn line."""
    cum = path.cumulative
    n = max(3, int(np.ceil(cum[-1] / step_m)) + 1)
    s = np.linspace(0.0, cum[-1], n)
    xz = np.stack([np.interp(s, cum, path.points[:, 0]), np.interp(s, cum, path.points[:, 1])], axis=1)
    sig = sigma_m / (s[1] - s[0])
    if sig > 0.5:
        pad = int(4 * sig) + 1
        d0 = xz[1] - xz[0]
        d1 = xz[-1] - xz[-2]
        head = xz[0] - np.outer(np.arange(pad, 0, -1), d0)
        tail = xz[-1] + np.outer(np.arange(1, pad + 1), d1)
        ext = np.concatenate([head, xz, tail])
        xz = gaussian_filter1d(ext, sig, axis=0, mode="nearest")[pad:-pad]
    seg = np.linalg.norm(np.diff(xz, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    tangent = np.gradient(xz, axis=0)
    heading = np.unwrap(np.arctan2(tangent[:, 0], tangent[:, 1]))
    return _Curve(s, xz, heading)


# --- the clip's own course -----------------------------------------------------------

@dataclass
class _Course:
    """A clip's smoothed ground track: arc length S, heading phi, hip sway L (T, 2)."""

    s: np.ndarray
    heading: np.ndarray
    sway: np.ndarray


def _course(motion: Motion, window_frames: int) -> _Course:
    mpu = motion.skeleton.metres_per_unit
    r = motion.root_translation[:, [0, 2]] * mpu
    t = len(r)
    w = max(1, min(int(window_frames), t))
    # Pad by linear extrapolation of the mean velocity at each end, so the ends of the
    # smoothed track do not stall.
    pad = w
    k = min(w, t - 1) if t > 1 else 1
    v0 = (r[k] - r[0]) / k if t > 1 else np.zeros(2)
    v1 = (r[-1] - r[-1 - k]) / k if t > 1 else np.zeros(2)
    ext = np.concatenate([r[0] - np.outer(np.arange(pad, 0, -1), v0), r, r[-1] + np.outer(np.arange(1, pad + 1), v1)])
    c = uniform_filter1d(ext, size=w, axis=0, mode="nearest")
    c = uniform_filter1d(c, size=max(1, w // 2), axis=0, mode="nearest")[pad:-pad]
    step = np.linalg.norm(np.diff(c, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    tangent = np.gradient(c, axis=0) if t > 1 else np.zeros((1, 2))
    speed = np.linalg.norm(tangent, axis=1) * motion.fps
    heading = np.arctan2(tangent[:, 0], tangent[:, 1])
    # Where the clip barely travels (standing, dancing on the spot), its "course" heading
    # is meaningless: hold the last good one (or use the body's own heading).
    leg = skeleton_leg_length(motion.skeleton)
    moving = speed > 0.1 * leg
    body = np.unwrap(root_heading(motion))
    if not moving.any():
        heading = gaussian_filter1d(body, max(1.0, motion.fps * 0.5), mode="nearest")
    else:
        idx = np.where(moving, np.arange(t), -1)
        idx = np.maximum.accumulate(idx)
        first = int(np.argmax(moving))
        idx[idx < 0] = first
        heading = np.unwrap(heading[idx])
    rel = r - c
    cos, sin = np.cos(heading), np.sin(heading)
    # L = R(-phi) (r - C): components along the clip's local (x = lateral, z = forward).
    lx = cos * rel[:, 0] - sin * rel[:, 1]
    lz = sin * rel[:, 0] + cos * rel[:, 1]
    return _Course(s, heading, np.stack([lx, lz], axis=1))


# --- following ---------------------------------------------------------------------------

@dataclass
class OneShot:
    """A one-shot clip (jump, kick, dance) to play when the character has walked
    ``at_m`` metres along the path."""

    motion: Motion
    at_m: float


@dataclass
class FollowResult:
    """The motion on the path plus what was decided on the way."""

    motion: Motion
    rate: float
    loop: LoopPoints | None
    clip_space: Motion
    info: dict = field(default_factory=dict)


def character_height(motion: Motion) -> float:
    """Standing height in metres of a canonical skeleton (soles to head top)."""
    rp = rest_positions(motion.skeleton)
    return float(rp[:, 1].max() - sole_level(motion.skeleton))


def build_clip_space(
    locomotion: Motion,
    distance_m: float,
    *,
    cyclic: bool = True,
    one_shots: list[OneShot] | None = None,
    blend_s: float = 0.3,
    loop: LoopPoints | None = None,
    transition_cost=None,
) -> tuple[Motion, LoopPoints | None, list[dict]]:
    """One long clip-space motion: the locomotion looped to cover ``distance_m`` (plus a
    margin), with one-shots crossfaded in at their distances.

    ``transition_cost(a_motion, b_motion) -> (A, B) cost matrix`` chooses the transition
    frames (defaults to the quantised-code table when given by the caller, otherwise the
    pose-feature distance).
    """
    fps = locomotion.fps
    blend = max(1, int(round(blend_s * fps)))
    mpu = locomotion.skeleton.metres_per_unit
    if cyclic:
        if loop is None:
            loop = find_loop(locomotion, blend_frames=blend)
        cycle_dist = float(np.linalg.norm(
            (locomotion.root_translation[loop.end] - locomotion.root_translation[loop.start])[[0, 2]]
        )) * mpu
        if cycle_dist < 1e-6:
            raise TransitionError(f"{locomotion.name}: the loop does not travel; is it a locomotion clip?")

    def cost_matrix(a: Motion, b: Motion) -> tuple[np.ndarray, object]:
        """(ranking cost, exact re-ranker or None): the code table ranks, the exact pose
        distance breaks its ties among the best candidates."""
        exact = pose_distance(pose_features(a), pose_features(b))
        if transition_cost is None:
            return exact, None

        def refine(i: int, j: int) -> float:
            return float(np.mean([exact[i + k, j + k] for k in range(blend) if i + k < len(exact) and j + k < exact.shape[1]]))

        return transition_cost(a, b), refine

    def travelled(m: Motion) -> np.ndarray:
        r = m.root_translation[:, [0, 2]] * mpu
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(r, axis=0), axis=1))])

    def looped_to(dist: float) -> Motion:
        if not cyclic:
            return locomotion
        n = int(np.ceil(dist / cycle_dist)) + 2
        return loop_motion(locomotion, loop, n, blend)

    events: list[dict] = []
    shots = sorted(one_shots or [], key=lambda o: o.at_m)
    # Straight-line travel overestimates the smoothed course a little (hip sway); 1.1x.
    out = looped_to((shots[0].at_m if shots else distance_m) * 1.1 + 0.0)
    for k, shot in enumerate(shots):
        dist = travelled(out)
        # Leave the locomotion near the chosen distance (within one cycle after it).
        lo = int(np.searchsorted(dist, shot.at_m))
        span = loop.period if (cyclic and loop) else int(fps)
        a_range = (max(0, lo - span // 2), max(lo - span // 2 + 1, lo + span // 2))
        sm = shot.motion
        cost, refine = cost_matrix(out, sm)
        tr_in = find_transition(cost, blend, a_range=a_range, b_range=(0, max(1, sm.n_frames // 4)), refine=refine)
        # Come back into the locomotion from the shot's last quarter.
        next_dist = shots[k + 1].at_m if k + 1 < len(shots) else distance_m
        back = looped_to(max(0.2, (next_dist - shot.at_m)) * 1.1 + 0.5)
        cost_back, refine_back = cost_matrix(sm, back)
        tr_out = find_transition(
            cost_back, blend, a_range=(max(tr_in.b_frame + blend + 1, 3 * sm.n_frames // 4), sm.n_frames),
            b_range=(0, loop.period if (cyclic and loop) else max(1, back.n_frames // 2)), refine=refine_back,
        )
        joined = crossfade(out, sm, tr_in.a_frame, tr_in.b_frame, blend)
        shot_start = tr_in.a_frame
        exit_at = shot_start + (tr_out.a_frame - tr_in.b_frame)
        joined = crossfade(joined, back, exit_at, tr_out.b_frame, blend)
        events.append({"clip": sm.name, "at_m": shot.at_m, "frames": [int(shot_start), int(exit_at + blend)],
                       "enter_cost": tr_in.cost, "exit_cost": tr_out.cost})
        out = joined
    return out, loop, events


def follow_path(
    motion: Motion,
    path: TablePath,
    *,
    fps: float = 30.0,
    cyclic: bool = True,
    duration_s: float | None = None,
    rate: float | None = None,
    rate_limits: tuple[float, float] = RATE_LIMITS,
    one_shots: list[OneShot] | None = None,
    plant_feet: bool = True,
    blend_s: float = 0.3,
    path_smoothing: float = 0.1,
    transition_cost=None,
    loop: LoopPoints | None = None,
) -> FollowResult:
    """Lay ``motion`` (retargeted onto a character, at the character's size) along
    ``path``. See the module docstring for the method.

    Timing: ``rate`` (playback speed factor) if given; else fitted so the walk lasts
    ``duration_s``; else fitted to the path's timestamps; else 1.0 — always clipped to
    ``rate_limits``. ``path_smoothing`` is the Gaussian smoothing of the path's corners
    in character heights.
    """
    if motion.n_frames < 2:
        raise PathError(f"{motion.name or 'clip'} has fewer than two frames")
    height = character_height(motion)
    clip, loop, events = build_clip_space(
        motion, path.length, cyclic=cyclic, one_shots=one_shots, blend_s=blend_s,
        transition_cost=transition_cost, loop=loop,
    )
    window = loop.period if loop is not None else int(round(motion.fps))
    course = _course(clip, window)
    curve = _smooth_curve(path, path_smoothing * height)
    length = curve.s[-1]
    if course.s[-1] < length:
        raise PathError(
            f"{clip.name}: travels only {course.s[-1]:.3f} m in clip space, path needs {length:.3f} m"
        )
    t_end = float(np.interp(length, course.s, np.arange(clip.n_frames))) / clip.fps
    lo, hi = rate_limits
    times_src: np.ndarray
    if rate is not None:
        k = float(np.clip(rate, lo, hi))
        n_out = int(np.floor(t_end / k * fps)) + 1
        times_src = np.arange(n_out) * k / fps
    elif duration_s is not None:
        if duration_s <= 0:
            raise PathError("duration must be positive")
        k = float(np.clip(t_end / duration_s, lo, hi))
        n_out = int(np.floor(t_end / k * fps)) + 1
        times_src = np.arange(n_out) * k / fps
    elif path.times is not None:
        times_src, k = _track_timestamps(path, curve, course, clip.fps, fps, (lo, hi))
    else:
        k = 1.0
        n_out = int(np.floor(t_end * fps)) + 1
        times_src = np.arange(n_out) / fps
    times_src = times_src[times_src <= t_end + 1e-9]

    out = _sample_bent(clip, course, curve, times_src, fps)
    info: dict = {"rate": k, "clip_seconds": t_end, "events": events, "path_length_m": path.length}
    if plant_feet:
        contact = _contacts_at(clip, times_src)
        out, drift = _plant(out, contact)
        info["plant_max_offset_m"] = drift
        out = lock_feet(out, contact > 0.5, fade_frames=max(1, int(round(0.1 * fps))))
    return FollowResult(out, k, loop, clip, info)


def _track_timestamps(path, curve, course, clip_fps, fps, limits):
    """Clip times that pass the path's points at their timestamps as closely as the rate
    limits allow (the rate is adjusted frame by frame towards the target arc length)."""
    target_s = path.cumulative * (curve.s[-1] / path.length)
    duration = float(path.times[-1])
    n_out = int(np.floor(duration * fps)) + 1
    u = np.arange(n_out) / fps
    want_s = np.interp(u, path.times, target_s)
    frames = np.arange(len(course.s))
    want_t = np.interp(want_s, course.s, frames) / clip_fps
    lo, hi = limits
    t = np.zeros(n_out)
    for n in range(1, n_out):
        step = np.clip(want_t[n] - t[n - 1], lo / fps, hi / fps)
        t[n] = t[n - 1] + step
    k = float(t[-1] / max(u[-1], 1e-9))
    return t, k


def _interp_frames(clip: Motion, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    f = np.clip(times * clip.fps, 0, clip.n_frames - 1)
    i0 = np.floor(f).astype(int)
    i1 = np.minimum(i0 + 1, clip.n_frames - 1)
    w = f - i0
    return i0, i1, w


def _sample_bent(clip: Motion, course: _Course, curve: _Curve, times: np.ndarray, fps: float) -> Motion:
    i0, i1, w = _interp_frames(clip, times)
    nj = clip.skeleton.n_joints
    rot = slerp_matrices(clip.rotations[i0], clip.rotations[i1], np.broadcast_to(w[:, None], (len(times), nj)))
    lerp = lambda a: a[i0] * (1 - w.reshape((-1,) + (1,) * (a.ndim - 1))) + a[i1] * w.reshape((-1,) + (1,) * (a.ndim - 1))
    s = lerp(course.s)
    phi = lerp(course.heading)
    sway = lerp(course.sway)
    height = lerp(clip.root_translation[:, 1])
    where, theta = curve.at(s)
    c, sn = np.cos(theta), np.sin(theta)
    # R(theta) applied to (lateral, forward) = world (x, z)
    x = where[:, 0] + c * sway[:, 0] + sn * sway[:, 1]
    z = where[:, 1] - sn * sway[:, 0] + c * sway[:, 1]
    mpu = clip.skeleton.metres_per_unit
    root = np.stack([x / mpu, height, z / mpu], axis=1)
    rot[:, 0] = rotate_y(theta - phi) @ rot[:, 0]
    return Motion(clip.skeleton, rot, root, float(fps), clip.name)


def _contacts_at(clip: Motion, times: np.ndarray) -> np.ndarray:
    """(N, 4) contact weights of the foot points, from the clip-space motion (where the
    capture's own feet are planted), sampled at the output times."""
    c = contacts(clip).astype(np.float64)
    c = uniform_filter1d(c, size=3, axis=0, mode="nearest")
    i0, i1, w = _interp_frames(clip, times)
    return c[i0] * (1 - w[:, None]) + c[i1] * w[:, None]


def _plant(motion: Motion, contact: np.ndarray, bleed_s: float = 1.5) -> tuple[Motion, float]:
    """Move the root by minus the stance feet's horizontal slide (weighted by contact),
    then bleed the accumulated offset away with a slow high-pass (``bleed_s``)."""
    feet = sole_points(motion)[:, :, [0, 2]]  # (N, 4, 2) metres
    vel = np.diff(feet, axis=0)  # (N-1, 4, 2)
    wgt = np.minimum(contact[1:], contact[:-1])  # (N-1, 4)
    # Per foot (ankle, toe): the point that moves least carries the weight (heel-off
    # pivots on the toe, heel-strike on the heel).
    total = wgt.sum(axis=1, keepdims=True)
    slide = np.where(total > 1e-6, (wgt[..., None] * vel).sum(axis=1) / np.maximum(total, 1e-6), 0.0)
    strength = np.clip(total, 0.0, 1.0)
    step = -slide * strength
    offset = np.concatenate([np.zeros((1, 2)), np.cumsum(step, axis=0)])
    win = max(3, int(round(bleed_s * motion.fps)))
    base = uniform_filter1d(offset, size=win, axis=0, mode="nearest")
    base = uniform_filter1d(base, size=win, axis=0, mode="nearest")
    offset = offset - base
    out = motion.copy()
    mpu = motion.skeleton.metres_per_unit
    out.root_translation[:, 0] += offset[:, 0] / mpu
    out.root_translation[:, 2] += offset[:, 1] / mpu
    return out, float(np.abs(offset).max())
