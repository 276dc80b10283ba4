"""Range-cover bound: an order-aware lower bound of the look-up DTW over runs.

The envelope bound (:mod:`retrieval.dtw.lower_bounds`) lets every query frame take its
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

**Algorithm.** The definition lets a range grow for free (a wider range can only lower its
minimum), so ``h_p·min_{e<=y<=x} c[p, y]`` is just ``h_p·c[p, y_p]`` at the range's
cheapest run ``y_p``, and the constraints chain those runs monotonically: the bound is

    min over y_0 <= y_1 <= ... <= y_{P−1} of Σ_p h_p · c[p, y_p]

(every query run picks one candidate run, never going back). Proof of the equality: a
range sequence gives such a monotone choice (``y_p`` in ``[e_p, x_p]``, ``y_{p+1} >=
e_{p+1} >= x_p >= y_p``) of the same cost; conversely a monotone choice is a range sequence
(``e_p = y_{p−1}``, ``x_p = y_p``, the last stretched to ``Q−1``) whose cost is at most the
choice's. So ``f_p[x]`` (the minimum for runs 0..p with ``y_p <= x``) obeys

    f_p[x] = min(f_p[x − 1], h_p·c[p, x] + f_{p−1}[x])

— one multiply-add and one minimum per (run, run) cell, the same arithmetic as the range
form (the tests check it against the definition, :func:`range_cover_numpy`). The columns'
bound is the same DP with the roles swapped, and :func:`range_cover_both` computes both in
one backward sweep over the grid, reading the costs straight from the query's table rows.

**Early abandoning.** Swept backwards, ``min_e X_p[e]`` (see :func:`range_cover_both`) bounds the cost of the rows of
runs p.. and ``before[p]`` (the envelope of the rows before run p) that of the others, so
when their sum exceeds the limit no path is within it: :func:`range_cover_both` returns inf.

:func:`range_cover_numpy` (the definition) and :func:`monotone_cover_numpy` (the DP) are
the numpy references; the numpy search path uses the latter.
"""
from __future__ import annotations

import numpy as np

from retrieval.codes import DiffTable
from retrieval.dtw.jit import HAVE_NUMBA, numba
from retrieval.dtw.runlength import run_length_encode


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


def monotone_cover_numpy(cost: np.ndarray, heights: np.ndarray) -> float:
    """The raw row range-cover bound by the O(P·Q) monotone-choice DP (module docstring);
    equal to :func:`range_cover_numpy`."""
    cost = np.asarray(cost, dtype=np.float64)
    h = np.asarray(heights, dtype=np.float64)
    f = np.minimum.accumulate(h[0] * cost[0])
    for p in range(1, cost.shape[0]):
        f = np.minimum.accumulate(h[p] * cost[p] + f)
    return float(f[-1])


def range_lower_bound(a: np.ndarray, b: np.ndarray, table: DiffTable) -> float:
    """Normalised max(row, column) range-cover bound of two code sequences (numpy):
    <= their normalised DTW (module docstring)."""
    av, al = run_length_encode(np.asarray(a))
    bv, bl = run_length_encode(np.asarray(b))
    cost = table.lookup(av[:, None], bv[None, :])
    return max(monotone_cover_numpy(cost, al), monotone_cover_numpy(cost.T, bl)) / (len(a) + len(b))


if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True)
    def range_cover_both(R, q_rows, q_heights, c_codes, c_widths, before, limit, norm, rest2, MX, MY, CP):
        """The row and the column range-cover bounds, each sharpened by the other, in one
        backward sweep over the (query run × candidate run) grid; the block costs are read
        straight from the query's table rows: ``c[x, e] = R[q_rows[x], c_codes[e]]``.

        ``X_x[e]``: a bound of the cost of the path's cells in query runs >= x when run x
        starts in candidate run e; ``Y_e[x]``: of its cells in candidate runs >= e when
        candidate run e starts in query run x. With ``MX_x[e] = min_{e' >= e} X_x[e']`` and
        ``MY_e[x] = min_{x' >= x} Y_e[x']`` (0 past the last run):

            X_x[e] = max(min_{y >= e} h_x·c[x, y] + MX_{x+1}[y],  MY_{e+1}[x])
            Y_e[x] = max(min_{y >= x} w_e·c[y, e] + MY_{e+1}[y],  MX_{x+1}[e])

        The first term of each is the monotone-choice DP of the module docstring; the second
        adds what the other side must still pay: the candidate runs after e are all crossed
        by rows of runs >= x, and the query runs after x by columns of runs >= e, and those
        cells lie inside the set being bounded. Each term bounds the same cells' cost, so
        their maximum does, and the recursion stays valid. Both need only the row below
        (``MX_{x+1}``) and the entry to the right (``MY_{e+1}``, ``CP``), so one row-by-row
        sweep computes them.

        Returns ``max(X_0[0], Y_0[0])`` raw (never below either plain bound), or inf as
        soon as ``(MX_x[0] + before[x]) / norm > limit`` (``before[x]``: a bound of the
        rows before run x). ``rest2[x, e] = max(MX_{x+1}[e], MY_{e+1}[x])`` bounds the cost
        of what follows any cell of block (x, e) — the exact DP's corridor uses it. Work
        arrays ``MX``, ``MY``, ``CP``: length >= number of candidate runs."""
        inf = np.inf
        kx, ky = q_rows.shape[0], c_codes.shape[0]
        near = limit * norm * (1.0 - 1e-9)
        for e in range(ky):
            MX[e] = 0.0  # MX_{x+1}[e]: nothing after the last query run
            MY[e] = inf  # MY_e[x+1]: no column run starts after the last query run
            CP[e] = inf  # min_{y > x} w_e·c[y, e] + MY_{e+1}[y]
        x0 = inf
        y0 = inf
        for x in range(kx - 1, -1, -1):
            h = np.float64(q_heights[x])
            Rx = R[q_rows[x]]
            rp = inf  # min_{y >= e} h·c[x, y] + MX_{x+1}[y]
            mx_run = inf  # MX_x[e + 1]
            my_next = 0.0  # MY_{e+1}[x]
            out = rest2[x]
            for e in range(ky - 1, -1, -1):
                cv = np.float64(Rx[c_codes[e]])
                mx_after = MX[e]
                out[e] = mx_after if mx_after > my_next else my_next
                t = np.float64(c_widths[e]) * cv + my_next
                if t < CP[e]:
                    CP[e] = t
                yv = CP[e] if CP[e] > mx_after else mx_after
                t = h * cv + mx_after
                if t < rp:
                    rp = t
                xv = rp if rp > my_next else my_next
                if xv < mx_run:
                    mx_run = xv
                MX[e] = mx_run
                if yv < MY[e]:
                    MY[e] = yv
                my_next = MY[e]
                if e == 0 and x == 0:
                    x0 = xv
                    y0 = yv
            v = MX[0] + before[x]
            if v > near and v / norm > limit:
                return inf
        return x0 if x0 > y0 else y0
