"""Row-by-row look-up DTW with early abandoning and a pruned corridor — the fast search's
exact frame-level DP: :func:`plain_dtw_raw` compiled (numba), :func:`dtw_rows_numpy` its
numpy twin (the tablet's), each row one min-plus scan.

Recurrence (as in :mod:`retrieval.dtw.kernels`): ``D[i, j] = c[i, j] + min(D[i−1, j],
D[i, j−1], D[i−1, j−1])``, ``D[0, 0] = c[0, 0]``. With ``m[j] = min(D[i−1, j],
D[i−1, j−1])`` (``m[0] = D[i−1, 0]``; for row 0, ``m[0] = 0`` and ``m[j > 0] = ∞``), row i
is ``D[i, j] = min_{k ≤ j} (m[k] + c[i, k] + … + c[i, j])``: unrolling the horizontal
term, the last vertical or diagonal entry into the row is at some column k ≤ j and the
path then runs right to j. With the prefix sums ``C[j] = Σ_{t ≤ j} c[i, t]`` that is
``D[i, j] = C[j] + min_{k ≤ j} (m[k] − C[k−1])`` — one ``cumsum``, one subtraction, one
``minimum.accumulate`` and one addition per row, instead of a Python-level loop over
anti-diagonals.

**Exactness.** The scan adds and subtracts in another order than the plain DP. Under
:func:`~retrieval.dtw.runlength.rle_is_exact` every cost is a float32 multiple of one
quantum and every partial sum (and difference of two, bounded by the same total) is an
integer number of quanta below 2⁵³ of them, so every operation is exact and the result is
bit-identical to the seed's DP. Callers use it only under that condition
(:meth:`retrieval.search.fast.FastSearcher` falls back to the anti-diagonal DP otherwise).

**Orientation.** DTW with a symmetric recurrence is the same on the transposed cost
matrix (a warping path read with rows and columns swapped is a warping path of the same
cells; with exact sums the value is bit-identical), so the scan runs over the shorter
side: fewer, longer vectorised rows.

**Early abandoning.** ``rest_row[i]`` (a lower bound of what any path pays in the rows
after i) and ``rest_col[j]`` (in the columns after j) make a cell dead when its value
plus the larger of the two exceeds ``limit`` (tested as ``value > min(limit − rest_col,
limit − rest_row)``; callers give the limit a relative slack of 10⁻⁹ and shrink the
bounds by as much, so rounding there can never kill a cell within the limit): every path
through it costs more. Dead
cells are set to ∞ (a path within the limit never passes one, so the result within the
limit is unchanged) and the DP returns ∞ as soon as a row is all dead.
"""
from __future__ import annotations

import numpy as np

from retrieval.dtw.jit import HAVE_NUMBA, numba


def dtw_rows_numpy(cost: np.ndarray, rest_row: np.ndarray | None = None, rest_col: np.ndarray | None = None,
                   limit: float = np.inf) -> float:
    """Raw DTW over a dense (rows, cols) float64 cost matrix by row min-plus scans; ∞ when
    it exceeds ``limit`` (see the module docstring for the bounds ``rest_row``/``rest_col``)."""
    cost = np.asarray(cost, dtype=np.float64)
    nx, ny = cost.shape
    rr = np.zeros(nx) if rest_row is None else np.asarray(rest_row, dtype=np.float64)
    rc = np.zeros(ny) if rest_col is None else np.asarray(rest_col, dtype=np.float64)
    if nx > ny:  # fewer, longer rows: the DP is symmetric (exact sums), the loop is per row
        cost, rr, rc, nx, ny = np.ascontiguousarray(cost.T), rc, rr, ny, nx
    abandon = limit != np.inf
    if abandon:
        room = limit - rc  # a cell is dead when value + max(rest of rows, rest of columns) > limit
    m = np.full(ny, np.inf)
    m[0] = 0.0
    row = m
    sc = 0  # cells left of the row above's first live cell are dead: every row starts there
    for i in range(nx):
        c = cost[i, sc:].cumsum()
        shifted = np.empty_like(c)
        shifted[0] = 0.0
        shifted[1:] = c[:-1]
        row = c + np.minimum.accumulate(m - shifted)
        if abandon:
            dead = row > np.minimum(room[sc:], limit - rr[i])
            row[dead] = np.inf
            first = int(dead.argmin())  # the first live cell (0 when every cell is dead)
            if dead[first]:
                return np.inf
            if first > 0:
                row = row[first:]
                sc += first
        m = row.copy()
        np.minimum(m[1:], row[:-1], out=m[1:])
    return float(row[-1])


if HAVE_NUMBA:  # optional: numba (the kernel below exists only where it is installed)

    @numba.njit(cache=True, nogil=True)
    def plain_dtw_raw(a_row, b, R, lo, hi, rest_row, rest_col, limit, norm, prev, cur):
        """Row-by-row look-up DTW with band limits, early abandoning and a pruned corridor
        (cells whose value plus the bound of the rows/columns still to come exceeds the
        limit are dead; a row stops where nothing live can feed it): the numbers of
        the seed's look-up DTW (:func:`retrieval.dtw.kernels.dtw_codes`) with the difference table whenever the result
        is within the limit, inf otherwise. ``a_row[i]`` is query frame i's row of ``R``
        (the fast search's ``query_rows``), so a cell costs one look-up, as in the seed's full table."""
        nx, ny = a_row.shape[0], b.shape[0]
        inf = np.inf
        # the exact test (v + x) / norm > limit is done only near or above the limit
        near = limit * norm * (1.0 - 1e-9)
        for j in range(ny):
            prev[j] = inf
        ihi = -1  # live column range of the previous row (row -1: only the virtual start)
        ilo = 0
        for i in range(nx):
            for j in range(ny):
                cur[j] = inf
            Ri = R[a_row[i]]
            rr = rest_row[i]
            jstart = lo[i]
            if i > 0 and ilo > jstart:
                jstart = ilo
            nlo = -1
            nhi = -1
            for j in range(jstart, hi[i] + 1):
                if j > ihi + 1 and (j == 0 or cur[j - 1] == inf) and not (i == 0 and j == 0):
                    break  # only a dead left neighbour could feed this cell and the rest
                if i == 0 and j == 0:
                    best = 0.0
                else:
                    best = inf
                    if i > 0:
                        best = prev[j]
                        if j > 0 and prev[j - 1] < best:
                            best = prev[j - 1]
                    if j > 0 and cur[j - 1] < best:
                        best = cur[j - 1]
                v = np.float64(Ri[b[j]]) + best
                x = rest_col[j]
                if rr > x:
                    x = rr
                if v == inf or (v + x > near and (v + x) / norm > limit):
                    cur[j] = inf  # dead: no path through it can finish within the limit
                else:
                    cur[j] = v
                    if nlo < 0:
                        nlo = j
                    nhi = j
            if nlo < 0:
                return inf
            ilo = nlo
            ihi = nhi
            prev, cur = cur, prev
        return prev[ny - 1]
