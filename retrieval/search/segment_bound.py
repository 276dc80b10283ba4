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

**Where to cut.** The proof holds for *any* split of the query's runs into consecutive
segments, so the split only decides how tight the bound is. Taking the minimum over a
segment loses least when the segment's codes are alike: with ``D`` a sum of per-component
level costs, ``D[a_i, v] >= min_{j ∈ s} D[a_j, v]`` gives away at most what the segment's
codes differ by. :func:`segment_split_adaptive` merges the query's runs greedily, always
the two neighbouring segments whose union has the smallest *height × diameter* (total
frames times the largest ``D`` between two of its codes), until ``n_segments`` remain.
On the six slowest of 69 queries over 33 204 derived clips it left 1.1–2.6× fewer
candidates to the full range-cover bound than an even split with as many segments
(docs/notebook/retrieval-speed.md).

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


def segment_split_adaptive(run_codes: np.ndarray, run_heights: np.ndarray, n_segments: int,
                           table) -> np.ndarray:
    """Run boundaries of ``min(n_runs, n_segments)`` segments, cut where the query's codes
    change most (module docstring, "Where to cut"): start from one segment per run and merge
    the neighbouring pair whose union has the smallest ``(H_a + H_b) · diam(a ∪ b)`` (``diam``:
    the largest ``D`` between two of its codes through ``table``, a
    :class:`~retrieval.codes.tables.DiffTable`; ties: the leftmost pair) until
    ``n_segments`` remain. The reference of the compiled ``segment_split_adaptive_nb``."""
    codes = np.asarray(run_codes, dtype=np.int64)
    heights = np.asarray(run_heights, dtype=np.float64)
    n = len(codes)
    target = max(1, min(n, int(n_segments)))
    D = table.lookup(codes[:, None], codes[None, :]) if n else np.zeros((0, 0))
    starts = list(range(n))
    ends = list(range(1, n + 1))
    h = list(heights)
    diam = [0.0] * n

    def merged(i: int) -> tuple[float, float]:
        d = max(diam[i], diam[i + 1], float(D[starts[i]:ends[i], starts[i + 1]:ends[i + 1]].max()))
        return (h[i] + h[i + 1]) * d, d

    cost = [merged(i)[0] for i in range(n - 1)]
    while len(starts) > target:
        i = int(np.argmin(cost))
        _, d = merged(i)
        ends[i], h[i], diam[i] = ends[i + 1], h[i] + h[i + 1], d
        del starts[i + 1], ends[i + 1], h[i + 1], diam[i + 1], cost[i]
        if i < len(cost):
            cost[i] = merged(i)[0]
        if i > 0:
            cost[i - 1] = merged(i - 1)[0]
    return np.array(starts + [n], dtype=np.int64)


if HAVE_NUMBA:
    from retrieval.dtw.runlength import diff_cost

    @numba.njit(cache=True, nogil=True)
    def _cross_diameter(codes, a0, a1, b0, b1, F, absdiff, shift, mask):  # pragma: no cover - compiled
        """The largest D between a code of runs a0..a1-1 and one of runs b0..b1-1."""
        d = 0.0
        for i in range(a0, a1):
            for j in range(b0, b1):
                x = diff_cost(codes[i], codes[j], F, absdiff, shift, mask)
                if x > d:
                    d = x
        return d

    @numba.njit(cache=True, nogil=True)
    def segment_split_adaptive_nb(codes, heights, n_segments, F, absdiff, shift, mask):  # pragma: no cover
        """Compiled :func:`segment_split_adaptive` (same boundaries: the same merges in the
        same order, ties to the leftmost pair). Segments live in a linked list; each merge
        updates the two costs next to it."""
        n = codes.shape[0]
        target = n_segments if n_segments < n else n
        if target < 1:
            target = 1
        start = np.arange(n)
        end = np.arange(1, n + 1)
        h = np.empty(n)
        for i in range(n):
            h[i] = np.float64(heights[i])
        diam = np.zeros(n)
        nxt = np.arange(1, n + 1)  # next live segment (n: none)
        prv = np.arange(-1, n - 1)
        cost = np.full(n, np.inf)  # cost[i]: merging live segment i with nxt[i]
        cdiam = np.zeros(n)
        for i in range(n - 1):
            d = max(diam[i], diam[i + 1], _cross_diameter(codes, start[i], end[i], start[i + 1], end[i + 1],
                                                          F, absdiff, shift, mask))
            cdiam[i] = d
            cost[i] = (h[i] + h[i + 1]) * d
        live = n
        while live > target:
            best = np.inf
            i = -1
            j = 0
            while j < n:  # live segments in order: the leftmost minimum
                if cost[j] < best:
                    best = cost[j]
                    i = j
                j = nxt[j]
            k = nxt[i]
            end[i] = end[k]
            h[i] += h[k]
            diam[i] = cdiam[i]
            nxt[i] = nxt[k]
            if nxt[k] < n:
                prv[nxt[k]] = i
            cost[k] = np.inf
            live -= 1
            for m in (prv[i], i):
                if m >= 0:
                    r = nxt[m]
                    if r < n:
                        d = max(diam[m], diam[r], _cross_diameter(codes, start[m], end[m], start[r], end[r],
                                                                  F, absdiff, shift, mask))
                        cdiam[m] = d
                        cost[m] = (h[m] + h[r]) * d
                    else:
                        cost[m] = np.inf
        out = np.empty(live + 1, np.int64)
        j = 0
        t = 0
        while j < n:
            out[t] = start[j]
            t += 1
            j = nxt[j]
        out[live] = n
        return out

    @numba.njit(cache=True, nogil=True)
    def segment_bounds_nb(nruns, nseg):
        """Run boundaries of ``nseg`` segments of near-equal run counts (the compiled
        :func:`segment_split`, ``nseg <= nruns``)."""
        b = np.empty(nseg + 1, np.int64)
        for s in range(nseg + 1):
            b[s] = (s * nruns + nseg // 2) // nseg
        return b

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
    def segment_cover_nb(Rs, H, c_codes, c_widths, F, G, limit=np.inf):  # pragma: no cover - compiled
        """The raw max(rows, columns) segment-cover bound of one candidate (runs
        ``c_codes`` as vocabulary indices, widths ``c_widths``), the DP of the module
        docstring; work arrays ``F`` and ``G`` (>= candidate runs).

        Both DPs run in one sweep, segment by segment, each along the candidate's runs:
        the rows' ``f_s[q]`` as in the docstring, the columns' ``g_q[s]`` with ``G[q]``
        holding ``g_q[s − 1]`` from the previous segment. The two chains are independent,
        so the processor overlaps them, and each cost is loaded once for both (the same
        operations in the same order per cell as two separate DPs: the same bits).

        **Early exit.** ``f_s[Q − 1] <= f_{s+1}[Q − 1]`` (each step adds a cost >= 0 and
        takes a minimum over the same or a longer prefix), so the rows' bound is at least
        ``f_s[Q − 1]`` after any segment s; once that exceeds ``limit`` (raw) the
        candidate cannot be within it, and the value so far (> ``limit``, and itself a lower
        bound) is returned."""
        ns = H.shape[0]
        ky = c_codes.shape[0]
        for q in range(ky):
            F[q] = 0.0  # f_{-1}[q]
            G[q] = np.inf  # g_q[-1]
        for s in range(ns):
            h = np.float64(H[s])
            Rss = Rs[s]
            fr = np.inf  # f_s[q - 1]
            gl = 0.0  # g_{q-1}[s], g_{-1}[s] = 0
            for q in range(ky):
                cv = np.float64(Rss[c_codes[q]])
                t = h * cv + F[q]
                if fr < t:
                    t = fr
                F[q] = t
                fr = t
                u = np.float64(c_widths[q]) * cv + gl
                if G[q] < u:
                    u = G[q]
                G[q] = u
                gl = u
            if fr > limit:
                return fr
        rows = F[ky - 1]
        cols = G[ky - 1]
        return rows if rows > cols else cols
