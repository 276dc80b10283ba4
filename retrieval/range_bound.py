"""Range-cover bound: an order-aware lower bound of the look-up DTW over runs.

The envelope bound (:mod:`retrieval.lower_bounds`) lets every query frame take its
cheapest partner *anywhere* in the candidate, so two clips with the same poses in a
different order get a low bound. This bound keeps the order, at the resolution of runs,
for O(runs × runs) work — far less than the exact run-length DP (O(runs × frames)).

**Definition.** Runs of equal codes: query runs p = 0..P−1 with heights ``h_p``, candidate
runs q = 0..Q−1, block costs ``c[p, q] = D[A_p, B_q]``. Over all sequences of column-run
ranges ``[e_p, x_p]`` (one per query run) with ``e_0 = 0``, ``x_{P−1} = Q−1``,
``e_p <= x_p`` and ``e_{p+1} ∈ {x_p, x_p + 1}``, minimise

    Σ_p h_p · min_{e_p <= q <= x_p} c[p, q].

**Proof that it is a lower bound of the (raw) DTW.** Take any warping path. The columns it
visits in the rows of query run p form a contiguous range (the path is connected and
monotone); let ``[e_p, x_p]`` be the candidate runs that range touches. The path starts in
run 0 of both clips and ends in the last runs; the next query run's first cell lies one
step after run p's last cell, in the same column or the next, so ``e_{p+1}`` is ``x_p`` or
``x_p + 1``. Every one of the ``h_p`` rows of run p has at least one path cell, each costing
at least the cheapest block in the range. So the path's cost is at least the sum for its
own range sequence, hence at least the minimum over all of them. Costs are non-negative
throughout. The same holds with the roles of query and candidate swapped (column runs
covered by ranges of query runs); the search uses both.

With ``rle_is_exact`` every term is an exact float64 (a float32 cost times a small
integer, sums far below 2^53 units), so the inequality holds bit for bit and comparing
``bound / (len(a) + len(b))`` with the k-th best distance is exact.

**Algorithm.** ``f_p[x]`` = the minimum for runs 0..p with run p's range ending at x;
``g[e] = min(f_{p−1}[e], f_{p−1}[e−1])`` and ``f_p[x] = min_{e<=x} g[e] + h_p·min c[p, e..x]``.
A stack of groups of e with equal range minimum (increasing bottom to top) with running
minima gives every ``f_p[x]`` in amortised O(1), so the bound costs O(P·Q).

**Early abandoning.** ``min_x f_p[x]`` bounds the cost of the rows of runs 0..p, and
``rest[p]`` (the envelope of the rows after run p) that of the rest, so when their sum
exceeds the limit no path is within it: the function returns inf.
"""
from __future__ import annotations

import numpy as np

from .compact_table import DiffTable
from .dtw import HAVE_NUMBA, numba
from .runlength import run_length_encode


def range_cover_numpy(cost: np.ndarray, heights: np.ndarray) -> float:
    """Reference (no abandoning, O(P·Q²)): the raw row range-cover bound of a
    (query runs × candidate runs) block-cost matrix with query run heights."""
    cost = np.asarray(cost, dtype=np.float64)
    h = np.asarray(heights, dtype=np.float64)
    kx, ky = cost.shape
    f = h[0] * np.minimum.accumulate(cost[0])
    for p in range(1, kx):
        g = f.copy()
        g[1:] = np.minimum(f[1:], f[:-1])
        rng = np.full((ky, ky), np.inf)  # rng[e, x] = min cost[p, e..x] (x >= e)
        for e in range(ky):
            rng[e, e:] = np.minimum.accumulate(cost[p, e:])
        f = np.min(g[:, None] + h[p] * rng, axis=0)
    return float(f[-1])


def range_lower_bound(a: np.ndarray, b: np.ndarray, table: DiffTable) -> float:
    """Normalised max(row, column) range-cover bound of two code sequences (numpy):
    <= their normalised DTW (module docstring)."""
    av, al = run_length_encode(np.asarray(a))
    bv, bl = run_length_encode(np.asarray(b))
    cost = table.lookup(av[:, None], bv[None, :])
    return max(range_cover_numpy(cost, al), range_cover_numpy(cost.T, bl)) / (len(a) + len(b))


if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True)
    def range_cover_raw(C, heights, transpose, rest, limit, norm, f, g, st_min, st_g, st_acc):  # pragma: no cover
        """Raw range-cover bound of the block costs ``C`` (rows = query runs; with
        ``transpose`` the roles swap: rows are ``C``'s columns), or inf as soon as
        ``(min_x f_p[x] + rest[p]) / norm > limit``. Work arrays: length >= runs of the
        covering side."""
        inf = np.inf
        if transpose:
            kx, ky = C.shape[1], C.shape[0]
        else:
            kx, ky = C.shape[0], C.shape[1]
        near = limit * norm * (1.0 - 1e-9)  # the exact division test runs only near the limit
        h = np.float64(heights[0])
        m = inf
        mn = inf
        for x in range(ky):
            cv = C[x, 0] if transpose else C[0, x]
            if cv < m:
                m = cv
            f[x] = h * m
            if f[x] < mn:
                mn = f[x]
        v = mn + rest[0]
        if v > near and v / norm > limit:
            return inf
        for p in range(1, kx):
            h = np.float64(heights[p])
            g[0] = f[0]
            for x in range(1, ky):
                g[x] = f[x] if f[x] < f[x - 1] else f[x - 1]
            top = 0
            mn = inf
            for x in range(ky):
                cv = C[x, p] if transpose else C[p, x]
                bg = g[x]
                while top > 0 and st_min[top - 1] >= cv:
                    if st_g[top - 1] < bg:
                        bg = st_g[top - 1]
                    top -= 1
                st_min[top] = cv
                st_g[top] = bg
                val = bg + h * cv
                if top > 0 and st_acc[top - 1] < val:
                    val = st_acc[top - 1]
                st_acc[top] = val
                top += 1
                f[x] = val
                if val < mn:
                    mn = val
            v = mn + rest[p]
            if v > near and v / norm > limit:
                return inf
        return f[ky - 1]

    @numba.njit(cache=True, nogil=True)
    def range_cover_suffix(C, heights, before, limit, norm, rest2, B, Bn, st_min, st_g, st_acc):  # pragma: no cover
        """The row range-cover bound computed backwards, which also yields an order-aware
        "cost still to come" for the exact DP's corridor.

        ``B_p[e]`` = the minimum over range sequences of runs p..P−1 with ``e_p = e`` (and
        ``x_{P−1} = Q−1``) of Σ h·min c. ``rest2[p, x] = min_{e >= x} B_{p+1}[e]`` (0 for the
        last run) bounds the cost of the rows after run p of any path that is in candidate
        run x at the end of run p: run p's range ends at ``x_p >= x`` and run p+1's starts
        at ``x_p`` or ``x_p + 1``. It is never below the envelope suffix (a minimum over a
        subset of columns). Returns ``B_0[0]`` (the bound; equal to the forward
        :func:`range_cover_raw`), or inf as soon as ``(min_e B_p[e] + before[p]) / norm >
        limit`` where ``before[p]`` bounds the rows before run p. ``rest2``: (P, Q) output;
        work arrays of length >= Q."""
        inf = np.inf
        kx, ky = C.shape[0], C.shape[1]
        near = limit * norm * (1.0 - 1e-9)
        for x in range(ky):
            rest2[kx - 1, x] = 0.0
        h = np.float64(heights[kx - 1])
        m = inf
        mn = inf
        for e in range(ky - 1, -1, -1):
            cv = C[kx - 1, e]
            if cv < m:
                m = cv
            B[e] = h * m
            if B[e] < mn:
                mn = B[e]
        v = mn + before[kx - 1]
        if v > near and v / norm > limit:
            return inf
        for p in range(kx - 2, -1, -1):
            # rest2[p, x] = suffix minimum of B_{p+1}; Bn[x] = min(B_{p+1}[x], B_{p+1}[x+1])
            m = inf
            for x in range(ky - 1, -1, -1):
                if B[x] < m:
                    m = B[x]
                rest2[p, x] = m
                Bn[x] = B[x] if (x == ky - 1 or B[x] < B[x + 1]) else B[x + 1]
            h = np.float64(heights[p])
            top = 0
            mn = inf
            for e in range(ky - 1, -1, -1):
                cv = C[p, e]
                bg = Bn[e]
                while top > 0 and st_min[top - 1] >= cv:
                    if st_g[top - 1] < bg:
                        bg = st_g[top - 1]
                    top -= 1
                st_min[top] = cv
                st_g[top] = bg
                val = bg + h * cv
                if top > 0 and st_acc[top - 1] < val:
                    val = st_acc[top - 1]
                st_acc[top] = val
                top += 1
                B[e] = val
                if val < mn:
                    mn = val
            v = mn + before[p]
            if v > near and v / norm > limit:
                return inf
        return B[0]
