"""Let a character laid on a path follow the table's surface: on top of the boxes it
crosses, jumping onto and off the ones higher than a step (issue 28, "Scan the table").

The ground is a function ``ground(x, z) -> height`` in the motion's world (the AR scene
frame: Y up, metres, the table at ``y = 0``); the app builds it from the scanned
:class:`ar.height_map.HeightMap` (this layer never imports ``ar``). Applied to the motion
:func:`retrieval.animation.follow_path` made, as one vertical offset of the root per
frame, so the gait, the path and the planted feet are untouched horizontally.

Method (per output frame ``f``):

1. **Ground under the character**: ``h_f`` is the highest ground under its root and its
   four sole points (heels, toe tips), swing foot included: a foot already over a box
   lifts the character onto it, a foot still on a box keeps it there, so no sole ever
   goes into a box's side.
2. **Edges**: a frame is on an edge where the ground rises or falls steeper than
   ``max_slope`` (default 1, 45 degrees) between consecutive frames, over their
   horizontal travel (at least ``min_run_m``, so a character standing still on a
   scan's noisy edge is not an edge); edge frames within ``merge_frames`` of each other
   are one edge, its rise ``h[end + 1] - h[start]``.
3. **Steps**: an edge whose rise is at most ``step_max_m`` (default
   :data:`STEP_MAX_M`, 4 cm: about a stair's rise for a child, and half the stage
   character's height; a rise a character can step, not climb) is walked over: the
   root's height ramps linearly to the new level over ``ramp_s``, before the edge going
   up and after it going down (so the soles never dip below the ground).
4. **Jumps**: a higher edge is jumped. Around the frame where the root crosses it, a
   window of ``jump_s`` seconds (``a..b``), widened to take in any airborne phase of the
   clip itself (no sole point in contact) that overlaps it, replaces the offset with a
   ballistic arc: ``h_a + (h_b - h_a) u + 4 u (1 - u) p`` (``u`` from 0 to 1 over the
   window) with ``p = |h_b - h_a| / 2 + clearance`` so the soles pass the edge
   ``clearance`` (default 20 % of the character's height) above its top. Before the
   crossing the arc is above the lower level and after it above the upper one (the
   difference is ``(1 - u)(Δ(2u - 1) + 4u c) >= 0``), so the feet never sink into the box.
5. **On top**: everywhere else the offset is ``h_f`` itself, so feet planted on a box
   top stand on it to the scan's accuracy.

The result carries the edges (frame, arc position, rise, jumped or walked) and the
per-frame offset, for the tests, the notebook and the stage.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from retrieval.animation.path_follow import character_height
from retrieval.animation.retarget import contacts, sole_points
from retrieval.motion import Motion

#: The highest edge walked over (metres): higher ones are jumped.
STEP_MAX_M = 0.04
#: Duration of a jump's flight (seconds) when the clip has none of its own.
JUMP_S = 0.5
#: Clearance of the soles over a jumped edge, in character heights.
CLEARANCE = 0.2

Ground = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class SurfaceEdge:
    """An edge of the ground crossed by the character: frames ``start..end`` (inclusive)
    are on it, ``rise`` metres (negative going down), ``jump`` whether it is jumped, and
    the jump's (or ramp's) window of frames ``window``."""

    start: int
    end: int
    rise: float
    jump: bool
    window: tuple[int, int]

    @property
    def crossing(self) -> int:
        return (self.start + self.end + 1) // 2


@dataclass
class SurfaceResult:
    """The motion on the surface, the offset added to its root (metres per frame), the
    ground under the root (metres per frame) and the edges found."""

    motion: Motion
    offset: np.ndarray
    ground: np.ndarray
    edges: list[SurfaceEdge] = field(default_factory=list)


def find_edges(heights: np.ndarray, travel: np.ndarray, max_slope: float = 1.0, min_run_m: float = 0.002,
               merge_frames: int = 2) -> list[tuple[int, int, float]]:
    """Edges of a ground profile sampled per frame: ``heights`` (F,) and the horizontal
    ``travel`` between consecutive frames (F - 1,), metres. Returns ``(start, end, rise)``
    with frames ``start..end`` on the edge (the change is between ``start`` and ``end + 1``)."""
    h = np.asarray(heights, np.float64)
    if len(h) < 2:
        return []
    dh = np.diff(h)
    steep = np.abs(dh) > max_slope * np.maximum(np.asarray(travel, np.float64), min_run_m)
    idx = np.flatnonzero(steep)
    edges: list[tuple[int, int, float]] = []
    for i in idx:
        if edges and i - edges[-1][1] <= merge_frames and np.sign(dh[i]) == np.sign(h[edges[-1][1] + 1] - h[edges[-1][0]]):
            edges[-1] = (edges[-1][0], int(i), 0.0)
        else:
            edges.append((int(i), int(i), 0.0))
    return [(s, e, float(h[e + 1] - h[s])) for s, e, _ in edges]


def _airborne(motion: Motion) -> np.ndarray:
    """(F,) True where no sole point of ``motion`` is in contact (the clip's own flight)."""
    return ~contacts(motion).any(axis=1)


def _widen_to_flight(a: int, b: int, airborne: np.ndarray) -> tuple[int, int]:
    """Widen ``a..b`` to cover every airborne run that overlaps it."""
    n = len(airborne)
    while a > 0 and airborne[a - 1] and airborne[a]:
        a -= 1
    while b < n - 1 and airborne[b + 1] and airborne[b]:
        b += 1
    return a, b


def follow_surface(motion: Motion, ground: Ground, *, step_max_m: float = STEP_MAX_M, jump_s: float = JUMP_S,
                   clearance: float = CLEARANCE, ramp_s: float = 0.12, max_slope: float = 1.0) -> SurfaceResult:
    """Lift ``motion`` (a path-following motion in the scene frame, soles on ``y = 0``)
    onto the surface ``ground``; see the module docstring for the method."""
    mpu = motion.skeleton.metres_per_unit
    root = motion.root_translation * mpu
    n = motion.n_frames
    soles = sole_points(motion)  # (F, 4, 3) metres: heels and toe tips
    h = np.asarray(ground(root[:, 0], root[:, 2]), np.float64).reshape(n)
    h = np.maximum(h, np.asarray(ground(soles[..., 0], soles[..., 2]), np.float64).reshape(n, -1).max(axis=1))
    travel = np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=1)
    offset = h.copy()
    fps = motion.fps
    lift = clearance * character_height(motion)
    airborne = _airborne(motion) if n > 1 else np.zeros(n, bool)
    edges: list[SurfaceEdge] = []
    taken_until = -1
    for start, end, rise in find_edges(h, travel, max_slope):
        if end <= taken_until:  # inside the previous jump's window
            continue
        jump = abs(rise) > step_max_m
        if jump:
            c = (start + end + 1) // 2
            half = max(2, int(round(jump_s * fps / 2)))
            a, b = max(0, c - half), min(n - 1, c + half)
            a, b = _widen_to_flight(a, b, airborne)
            a = max(a, taken_until + 1)
            if b <= a:
                continue
            ha, hb = h[a], h[b]
            u = (np.arange(a, b + 1) - a) / (b - a)
            p = abs(hb - ha) / 2 + lift
            offset[a:b + 1] = ha + (hb - ha) * u + 4 * u * (1 - u) * p
        else:
            # up: ramp before the edge, down: after it (the soles never dip below the ground)
            r = max(1, int(round(ramp_s * fps)))
            a, b = (max(0, start - r), min(n - 1, end + 1)) if rise > 0 else (start, min(n - 1, end + 1 + r))
            a = max(a, taken_until + 1)
            if b <= a:
                continue
            u = (np.arange(a, b + 1) - a) / (b - a)
            offset[a:b + 1] = h[a] + (h[b] - h[a]) * u
        edges.append(SurfaceEdge(start, end, rise, jump, (a, b)))
        taken_until = b
    out = motion.copy()
    out.root_translation[:, 1] += offset / mpu
    return SurfaceResult(out, offset, h, edges)


__all__ = ["STEP_MAX_M", "JUMP_S", "CLEARANCE", "Ground", "SurfaceEdge", "SurfaceResult", "find_edges",
           "follow_surface"]
