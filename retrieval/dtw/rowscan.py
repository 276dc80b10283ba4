"""Row-by-row look-up DTW in numpy, each row one min-plus scan, with early abandoning —
the tablet's (no numba) exact DP for the fast search.

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

