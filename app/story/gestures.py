"""Reading a child's finger strokes: thinning, loops (spins) and arcs (hops).

Pure functions on lists of (x, y, t) in table metres, so they are tested without a
screen. A small closed loop drawn inside a path means "spin here"; a short arc drawn from
the path back onto the path means "hop here".
"""
from __future__ import annotations

import math

import numpy as np

Point = tuple[float, float, float]

#: Successive samples closer than this are merged (a resting finger makes many events).
MIN_STEP_M = 0.004
#: A loop longer than this is a path that crosses itself, not a spin.
MAX_SPIN_LOOP_M = 0.45
MIN_SPIN_LOOP_M = 0.06
#: How close to the path a hop arc must start and end.
HOP_SNAP_M = 0.06


def thin(points: list[Point], min_step: float = MIN_STEP_M) -> list[Point]:
    """Drop samples that moved less than ``min_step`` metres (keeps the last one)."""
    out: list[Point] = []
    for p in points:
        if not out or math.hypot(p[0] - out[-1][0], p[1] - out[-1][1]) >= min_step:
            out.append(p)
    if points and out[-1] != points[-1] and len(out) > 1:
        out[-1] = points[-1]
    return out


def _length(points: list[Point]) -> float:
    return sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(points, points[1:]))


def find_spins(path: list[Point]) -> tuple[list[Point], list[float]]:
    """Find small loops in a stroke: returns the path with each loop cut out and the
    times where the spins start.

    A loop is a self-crossing whose enclosed stretch is between ``MIN_SPIN_LOOP_M`` and
    ``MAX_SPIN_LOOP_M`` long. Cutting the loop out keeps the character in place while it
    spins (the path's times stay increasing).
    """
    if len(path) < 4:
        return list(path), []
    xy = np.asarray([(p[0], p[1]) for p in path], dtype=float)
    out: list[Point] = []
    spins: list[float] = []
    i = 0
    n = len(path)
    while i < n - 1:
        out.append(path[i])
        a, b = xy[i], xy[i + 1]
        j = _first_crossing(xy, i, a, b)
        if j is not None:
            loop = path[i + 1:j + 1]
            loop_len = _length(loop)
            if MIN_SPIN_LOOP_M <= loop_len <= MAX_SPIN_LOOP_M:
                spins.append(path[i][2])
                i = j + 1  # resume after the crossing segment
                continue
        i += 1
    if out[-1] != path[-1]:
        out.append(path[-1])
    return out, spins


def _first_crossing(xy: np.ndarray, i: int, a: np.ndarray, b: np.ndarray) -> int | None:
    """Index j of the first later segment (j, j+1), not adjacent to i, crossing (a, b)."""
    if i + 2 >= len(xy) - 1:
        return None
    c = xy[i + 2:-1]
    d = xy[i + 3:]

    def orient(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    o1 = orient(a, b, c)
    o2 = orient(a, b, d)
    o3 = orient(c, d, a)
    o4 = orient(c, d, b)
    hits = np.nonzero((o1 * o2 < 0) & (o3 * o4 < 0))[0]
    return int(hits[0]) + i + 2 if hits.size else None


def _nearest(path: list[Point], x: float, y: float) -> tuple[float, int]:
    xy = np.asarray([(p[0], p[1]) for p in path], dtype=float)
    d = np.hypot(xy[:, 0] - x, xy[:, 1] - y)
    k = int(np.argmin(d))
    return float(d[k]), k


def hop_time(stroke: list[Point], path: list[Point]) -> float | None:
    """If ``stroke`` is an arc from the path back onto it, the path time of the hop.

    An arc: both ends within ``HOP_SNAP_M`` of the path, ends at least 3 cm apart, and the
    stroke bulges out from the straight line between its ends by at least a quarter of
    that line's length. Anything else returns None (the stroke is a new path).
    """
    if len(path) < 2 or len(stroke) < 3:
        return None
    (x0, y0, _), (x1, y1, _) = stroke[0], stroke[-1]
    d0, k0 = _nearest(path, x0, y0)
    d1, _ = _nearest(path, x1, y1)
    chord = math.hypot(x1 - x0, y1 - y0)
    if d0 > HOP_SNAP_M or d1 > HOP_SNAP_M or chord < 0.03:
        return None
    ux, uy = (x1 - x0) / chord, (y1 - y0) / chord
    bulge = max(abs((p[0] - x0) * uy - (p[1] - y0) * ux) for p in stroke)
    if bulge < 0.25 * chord or _length(stroke) > 4 * chord + 0.2:
        return None
    return path[k0][2] - path[0][2]
