"""Segment-cover bound: a cheap, coarser range-cover bound (a filter before the full one).

The range-cover bound (:mod:`retrieval.dtw.range_bound`) costs O(query runs × candidate
runs) per candidate. Here the query's runs are merged into a few **segments** of
consecutive runs (rows ``r_s .. r_{s+1} − 1`` of the query, height ``H_s``), and the block
cost of segment s against candidate run q is the cheapest of its codes:

    C[s, q] = min_{i ∈ segment s} D[a_i, B_q]   (one load: ``Rs[s, v_q]``, precomputed per query)

**Bound.** With ``w_q`` the candidate run widths,

    rows:    min over y_0 <= ... <= y_{S−1} of Σ_s H_s · C[s, y_s]
    columns: min over z_0 <= ... <= z_{Q−1} of Σ_q w_q · C[z_q, q]

and the bound is the larger, divided by ``len(a) + len(b)``.

*Proof that each is <= the raw DTW.* Take any warping path. *Rows:* the path's cells in
the rows of segment s touch a contiguous range of candidate runs ``[e_s, x_s]`` (the path
is connected and monotone), and the next segment's range starts at ``x_s`` or ``x_s + 1``.
Each of the ``H_s`` rows has at least one cell, costing ``D[a_i, B_q] >= C[s, q] >= min_{q ∈
[e_s, x_s]} C[s, q]``; choosing ``y_s`` as that minimiser gives a monotone choice
(``y_{s+1} >= e_{s+1} >= x_s >= y_s``) whose sum is <= the path's cost. *Columns:* the same
with the roles swapped: the cells in candidate run q's ``w_q`` columns lie in a contiguous
range of segments, each cell costing at least ``C[segment, q]``. So every path costs at
least both minima, and so does the cheapest, the DTW. Costs are >= 0 throughout. ∎

It is the range-cover bound of :mod:`retrieval.dtw.range_bound` applied to the query with
its runs coarsened (a segment of one run gives exactly the row range-cover bound), so it is
never larger than that bound; it costs S × Q cells instead of P × Q.

**Algorithm.** Both minima by the monotone-choice DP in one forward sweep over the (segment
× candidate run) grid: ``f_s[q] = min(f_s[q − 1], H_s · C[s, q] + f_{s−1}[q])`` and
``g_q[s] = min(g_q[s − 1], w_q · C[s, q] + g_{q−1}[s])`` (``f_{−1} = g_{−1} = 0``); the bounds
are ``f_{S−1}[Q−1]`` and ``g_{Q−1}[S−1]``. With exact sums (``rle_is_exact``) every term is an
exact float64, so the comparison with the k-th best distance is exact.

:func:`segment_cover_numpy` is the reference; :func:`segment_rows` builds ``Rs`` and ``H``.
"""
from __future__ import annotations

import numpy as np

from retrieval.dtw.jit import HAVE_NUMBA, numba
from retrieval.dtw.range_bound import monotone_cover_numpy


def segment_cover_numpy(C: np.ndarray, seg_heights: np.ndarray, run_widths: np.ndarray) -> float:
    """Raw max(rows, columns) segment-cover bound of a (segments × candidate runs) cost
    matrix ``C`` (module docstring), by the monotone-choice DP of the range-cover module."""
    C = np.asarray(C, dtype=np.float64)
    return max(monotone_cover_numpy(C, seg_heights), monotone_cover_numpy(C.T, run_widths))


def segment_split(n_runs: int, n_segments: int) -> np.ndarray:
    """Run boundaries of ``min(n_runs, n_segments)`` segments of near-equal run counts:
    segment s holds runs ``bounds[s] .. bounds[s+1] − 1``."""
    s = max(1, min(int(n_runs), int(n_segments)))
    return np.array([(i * n_runs + s // 2) // s for i in range(s + 1)], dtype=np.int64)


if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True)
    def segment_rows(R, q_rows, q_heights, bounds, Rs, H):  # pragma: no cover - compiled
        """``Rs[s, t] = min_{p ∈ segment s} R[q_rows[p], t]`` and ``H[s] = Σ_{p ∈ s}
        q_heights[p]`` for the segments ``bounds`` (:func:`segment_split`)."""
        nv = R.shape[1]
        for s in range(bounds.shape[0] - 1):
            h = 0
            for t in range(nv):
                Rs[s, t] = np.inf
            for p in range(bounds[s], bounds[s + 1]):
                h += q_heights[p]
                Rp = R[q_rows[p]]
                for t in range(nv):
                    if Rp[t] < Rs[s, t]:
                        Rs[s, t] = Rp[t]
            H[s] = h

    @numba.njit(cache=True, nogil=True)
    def segment_cover_nb(Rs, H, c_codes, c_widths, F, G):  # pragma: no cover - compiled
        """The raw max(rows, columns) segment-cover bound of one candidate (runs
        ``c_codes`` as vocabulary indices, widths ``c_widths``), the DP of the module
        docstring; work arrays ``F`` (>= candidate runs) and ``G`` (>= segments)."""
        ns = H.shape[0]
        ky = c_codes.shape[0]
        for q in range(ky):
            F[q] = 0.0  # f_{-1}[q]
        # rows: f_s[q] = min(f_s[q - 1], H_s * C[s, q] + f_{s-1}[q])
        for s in range(ns):
            h = np.float64(H[s])
            Rss = Rs[s]
            fr = np.inf  # f_s[q - 1]
            for q in range(ky):
                cv = np.float64(Rss[c_codes[q]])
                t = h * cv + F[q]
                if fr < t:
                    t = fr
                F[q] = t
                fr = t
        rows = F[ky - 1]
        # columns: g_q[s] = min(g_q[s - 1], w_q * C[s, q] + g_{q-1}[s])
        for s in range(ns):
            G[s] = 0.0  # g_{-1}[s]
        for q in range(ky):
            w = np.float64(c_widths[q])
            code = c_codes[q]
            gr = np.inf  # g_q[s - 1]
            for s in range(ns):
                t = w * np.float64(Rs[s, code]) + G[s]
                if gr < t:
                    t = gr
                G[s] = t
                gr = t
        cols = G[ns - 1]
        return rows if rows > cols else cols
