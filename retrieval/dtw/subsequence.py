"""Subsequence search: where in a long, unsegmented take does a short query occur?

Open-begin / open-end DTW over codes (the setting of Forbes & Fiume's search in long
recordings): the query's first frame may align with *any* frame of the take at no cost
for skipping what comes before, and its last frame with any later frame —

    D[0, j] = c(0, j)                      (free start at every take frame j)
    D[i, j] = c(i, j) + min(D[i−1, j], D[i−1, j−1], D[i, j−1])
    end     = argmin_j D[x−1, j]           (free end)

with ``c`` the seed's table look-up. Each cell carries the take frame where its path
started, so the match comes back as (start, end) frames. Among equally cheap predecessors a
cell keeps the earliest start, and among equally cheap ends the longest match wins (then
the earliest): in code space a clip's boundary inside a run of equal codes is invisible,
and the longest reading is the one that covers the whole planted clip; the numba and numpy
paths follow the same rule and give the same numbers. ``distance`` is the raw cost over
``x + (end − start + 1)``, the same normalisation as the clip-to-clip DTW.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from retrieval.codes import DiffTable
from retrieval.dtw.jit import HAVE_NUMBA, numba
from retrieval.dtw.kernels import DTWError, check_codes, resolve_backend
from retrieval.dtw.runlength import rle_is_exact


@dataclass(frozen=True)
class SubsequenceMatch:
    start: int  # first take frame of the match (inclusive)
    end: int  # last take frame of the match (inclusive)
    distance: float  # raw / (len(query) + end − start + 1)
    raw: float

    def as_dict(self) -> dict:
        return {"start": self.start, "end": self.end, "distance": self.distance, "raw": self.raw}


if HAVE_NUMBA:  # optional: numba (the kernels below exist only where it is installed)
    from retrieval.dtw.runlength import diff_cost

    @numba.njit(cache=True, nogil=True)
    def _nb_subsequence(q, take, F, absdiff, shift, mask):
        nx, ny = q.shape[0], take.shape[0]
        prev = np.empty(ny)
        cur = np.empty(ny)
        ps = np.empty(ny, np.int64)
        cs = np.empty(ny, np.int64)
        for j in range(ny):
            prev[j] = diff_cost(q[0], take[j], F, absdiff, shift, mask)
            ps[j] = j
        for i in range(1, nx):
            qi = q[i]
            for j in range(ny):
                best = prev[j]
                st = ps[j]
                if j > 0:
                    if prev[j - 1] < best or (prev[j - 1] == best and ps[j - 1] < st):
                        best = prev[j - 1]
                        st = ps[j - 1]
                    if cur[j - 1] < best or (cur[j - 1] == best and cs[j - 1] < st):
                        best = cur[j - 1]
                        st = cs[j - 1]
                cur[j] = diff_cost(qi, take[j], F, absdiff, shift, mask) + best
                cs[j] = st
            prev, cur = cur, prev
            ps, cs = cs, ps
        end = 0
        for j in range(1, ny):
            if prev[j] < prev[end] or (prev[j] == prev[end] and j - ps[j] > end - ps[end]):
                end = j
        return ps[end], end, prev[end]


def _np_subsequence(q: np.ndarray, take: np.ndarray, table: DiffTable) -> tuple[int, int, float]:
    """Row by row over the query, vectorised over the take. The horizontal carry
    ``cur[j] = row[j] + min(best[j], cur[j−1])`` is a min-plus scan:
    ``cur[j] = S[j] + min_{k≤j}(best[k] − S[k−1])`` with ``S`` the running sum of the row —
    one ``cumsum`` and one ``minimum.accumulate``. The scan adds in another order than the
    sequential loop, so it is used when those sums are exact (:func:`rle_is_exact`, true
    for the seed's tables); otherwise a plain loop keeps the numba path's numbers."""
    cost = table.lookup(q[:, None], take[None, :])
    ny = len(take)
    exact = rle_is_exact(table.F, len(q) + ny)
    idx = np.arange(ny)
    prev = cost[0].copy()
    ps = idx.copy()
    for i in range(1, len(q)):
        best = prev.copy()
        st = ps.copy()
        diag = np.full(ny, np.inf)
        diag[1:] = prev[:-1]
        dstart = np.concatenate(([0], ps[:-1]))
        take_diag = (diag < best) | ((diag == best) & (dstart < st))
        best = np.where(take_diag, diag, best)
        st = np.where(take_diag, dstart, st)
        row = cost[i]
        if exact:
            s_incl = np.cumsum(row)
            s_before = s_incl - row
            vals = best - s_before
            runmin = np.minimum.accumulate(vals)
            # among tied k the sequential rule keeps the earliest start: a running min of
            # the starts of the cells that reach the running minimum, restarted at every
            # strict new minimum (segments are shifted apart by a large offset)
            seg = np.cumsum(np.concatenate(([True], runmin[1:] < runmin[:-1])))
            big = ny + 1
            key = np.where(vals == runmin, st, big) - seg * 2 * big
            cs = np.minimum.accumulate(key) + seg * 2 * big
            cur = s_incl + runmin
        else:
            cur = np.empty(ny)
            cs = np.empty(ny, np.int64)
            c_prev, s_prev = np.inf, 0
            for j in range(ny):
                b, s = best[j], st[j]
                if j > 0 and (c_prev < b or (c_prev == b and s_prev < s)):
                    b, s = c_prev, s_prev
                c_prev = row[j] + b
                s_prev = s
                cur[j], cs[j] = c_prev, s_prev
        prev, ps = cur, cs
    span = np.arange(ny) - ps
    ties = np.flatnonzero(prev == prev.min())
    end = int(ties[np.argmax(span[ties])])  # the longest of equally cheap matches, earliest first
    return int(ps[end]), end, float(prev[end])


def find_subsequence(query: np.ndarray, take: np.ndarray, table: DiffTable, backend: str = "auto") -> SubsequenceMatch:
    """Best match of ``query`` codes inside ``take`` codes (see the module docstring)."""
    q = check_codes(query, table.size, "query")
    t = check_codes(take, table.size, "take")
    if len(q) < 1 or len(t) < 1:
        raise DTWError("query and take must be non-empty")
    shift = 2 * table.low_dims
    if resolve_backend(backend) == "numba":
        start, end, raw = _nb_subsequence(q, t, table.F, table.absdiff, shift, (1 << shift) - 1)
    else:
        start, end, raw = _np_subsequence(q, t, table)
    start, end, raw = int(start), int(end), float(raw)
    return SubsequenceMatch(start, end, raw / (len(q) + end - start + 1), raw)
