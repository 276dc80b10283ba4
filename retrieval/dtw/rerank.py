"""Early-abandoning exact DTW on float features, for re-ranking a shortlist
(:mod:`retrieval.library.storybeam_search`): the compiled kernels (numba) beside their numpy
twins (:func:`sequential_cost_matrix`, :func:`dtw_features_many`).

:func:`dtw_features_abandon` is bit for bit :func:`retrieval.dtw.dtw_features`'s
recurrence (each cell's Euclidean cost summed dimension by dimension), with early
abandoning. (A matrix-product form of the cost matrix, ``‖x‖² + ‖y‖² − 2 x·yᵀ``, was
measured and dropped: with one BLAS thread it was no faster on these clips, 0.132 against
0.124 s for 1 230 CMU pairs, and with OpenBLAS's default threads far slower on a busy
machine; docs/notebook/results.md.)

Without a band the compiled path computes each row's costs first, with the frame
index innermost (the loop runs on vectors, three dimensions per pass; each cell still
sums its squares dimension by dimension in the same order, so each cost is bit for bit
the same), then the recurrence with the boundary cells peeled off (no branches on
``i``, ``j``; a minimum of the same three values is the same whatever the order of
comparisons), two rows at a time, staggered, so that two independent chains of
additions overlap in the CPU: bit for bit the per-cell kernel's distance and the same
abandoning decisions (every row's minimum is still checked), about 4× fewer seconds than
the per-cell kernel on CMU clips (tests compare them; docs/notebook/results.md measures the
search).

:func:`dtw_features_abandon` returns exactly :func:`retrieval.dtw.dtw_features` (the same
Euclidean frame cost, the same recurrence in the same order, normalised by
``len(x) + len(y)``) whenever that distance is at most ``limit``; above ``limit`` it
returns either that distance or ``inf`` (``inf`` as soon as it is certain to exceed it). Proof of the bound: every warping path visits every row
``i`` of the cost matrix, and cumulative costs only grow along a path (frame costs are
non-negative), so the final cost is at least the smallest cumulative cost in any row;
once a whole row's minimum exceeds ``limit · (len(x) + len(y))`` the distance must exceed
``limit``. (A relative slack of 1e-12 on the limit keeps exact ties from being abandoned
by rounding.) The numpy path (no numba, the tablet's) computes the full distance with
the squares summed in the compiled kernel's order (:func:`sequential_cost_matrix`), so
both paths give the same distances bit for bit, and compares.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from retrieval.dtw.jit import HAVE_NUMBA, numba
from retrieval.dtw.kernels import band_limits, dtw_cost_numpy, dtw_features, resolve_backend

if HAVE_NUMBA:  # optional: numba (the kernels below exist only where it is installed)
    from retrieval.dtw.kernels import dtw_euclid_nb

_SLACK = 1e-12

if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True, fastmath=False)
    def _nb_row_costs(x, i, yt, s):  # pragma: no cover - compiled
        # s[j] = Euclidean cost of (x[i], y[j]); j innermost over the transposed y so the
        # loop runs on vectors, three dimensions per pass over s (a third of the loads and
        # stores of s), each cell's squares still added one by one in dimension order
        ny = yt.shape[1]
        d = x.shape[1]
        for j in range(ny):
            s[j] = 0.0
        k = 0
        while k + 3 <= d:
            x0 = x[i, k]
            x1 = x[i, k + 1]
            x2 = x[i, k + 2]
            y0 = yt[k]
            y1 = yt[k + 1]
            y2 = yt[k + 2]
            for j in range(ny):
                t = x0 - y0[j]
                a = s[j] + t * t
                t = x1 - y1[j]
                a = a + t * t
                t = x2 - y2[j]
                s[j] = a + t * t
            k += 3
        while k < d:
            xv = x[i, k]
            for j in range(ny):
                t = xv - yt[k, j]
                s[j] += t * t
            k += 1
        for j in range(ny):
            s[j] = np.sqrt(s[j])

    @numba.njit(cache=True, nogil=True, fastmath=False)
    def _nb_dtw_euclid_abandon_rows(x, yt, raw_limit):  # pragma: no cover - compiled
        # no band: rows two at a time, staggered — cell (i, j) and cell (i+1, j) in one
        # step, two independent dependency chains for the CPU to overlap (the recurrence is
        # latency-bound); each cell is still its cost plus the minimum of the same three
        # neighbours, so every value is bit for bit the per-cell kernel's. ``rows``: three
        # row buffers used in rotation (the last finished row, then rows i and i+1).
        nx = x.shape[0]
        ny = yt.shape[1]
        rows = np.empty((3, ny))
        s = np.empty(ny)
        s2 = np.empty(ny)
        _nb_row_costs(x, 0, yt, s)
        v = s[0]
        rows[0, 0] = v
        rowmin = v
        for j in range(1, ny):
            v = s[j] + v
            rows[0, j] = v
            if v < rowmin:
                rowmin = v
        if rowmin > raw_limit:
            return np.inf
        p = 0  # the last finished row's buffer
        i = 1
        while i < nx:
            pair = i + 1 < nx  # a last row alone runs beside a row of zero costs, never read
            _nb_row_costs(x, i, yt, s)
            if pair:
                _nb_row_costs(x, i + 1, yt, s2)
            else:
                s2[:] = 0.0
            prev = rows[p]
            cur = rows[(p + 1) % 3]
            nxt = rows[(p + 2) % 3]
            v = s[0] + prev[0]
            cur[0] = v
            m1 = v
            w = s2[0] + v
            nxt[0] = w
            m2 = w
            for j in range(1, ny):
                a = prev[j]
                b = prev[j - 1]
                if b < a:
                    a = b
                if v < a:
                    a = v
                v = s[j] + a
                cur[j] = v
                if v < m1:
                    m1 = v
                c = v
                e = cur[j - 1]
                if e < c:
                    c = e
                if w < c:
                    c = w
                w = s2[j] + c
                nxt[j] = w
                if w < m2:
                    m2 = w
            if m1 > raw_limit or (pair and m2 > raw_limit):
                return np.inf
            p = (p + 2) % 3 if pair else (p + 1) % 3
            i += 2
        return rows[p, ny - 1]


def sequential_cost_matrix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(len(x), len(y)) Euclidean frame costs with the squares summed dimension by
    dimension in order — the compiled kernel's order, so the numpy path (the tablet's)
    gives bit for bit the numba path's distances and rankings."""
    s = np.zeros((len(x), len(y)))
    for k in range(x.shape[1]):
        t = x[:, k, None] - y[None, :, k]
        s += t * t
    return np.sqrt(s)


def dtw_features_many(x: np.ndarray, ys: Sequence[np.ndarray], band: int | None = None,
                      max_bytes: int = 64 << 20) -> np.ndarray:
    """Normalised Euclidean-cost DTW of ``x`` to each of ``ys`` on numpy (the tablet's
    re-ranking), all candidates in one anti-diagonal sweep: each numpy call works on every
    candidate's diagonal at once, so a shortlist of 64 costs about as many calls as one
    DTW (the per-pair numpy DP is bound by the cost of its calls, not its arithmetic).

    Bit for bit :func:`dtw_features_abandon` without a limit, pair by pair: each
    candidate's costs are :func:`sequential_cost_matrix`'s (the same subtraction, square
    and sum per dimension, in order), each cell is its cost plus the minimum of the same
    three neighbours. Candidates of different lengths are padded with infinite costs on
    the right, which no cell of a shorter candidate reads (a cell depends only on cells in
    its own and earlier columns), and each candidate's distance is read from its own last
    cell when the sweep reaches it. Cells outside a band are infinite, as in the per-pair
    path. Candidates go in groups whose diagonal-major costs stay under about ``max_bytes``."""
    xf = np.ascontiguousarray(x, dtype=np.float64)
    refs = [np.ascontiguousarray(y, dtype=np.float64) for y in ys]
    out = np.empty(len(refs))
    if not refs:
        return out
    for r in refs:
        if xf.ndim != 2 or r.ndim != 2 or r.shape[1] != xf.shape[1] or not len(r) or not len(xf):
            dtw_features(xf, r, band, "numpy")  # raises the DTWError naming the problem
    nx = len(xf)
    # similar lengths share a group (up to twice the shortest: the padding costs less than another sweep)
    order = np.argsort([len(r) for r in refs], kind="stable")
    start = 0
    while start < len(order):
        first = len(refs[order[start]])
        stop = start + 1
        while (stop < len(order) and len(refs[order[stop]]) <= 2 * first
               and (stop + 1 - start) * (nx + len(refs[order[stop]])) * nx * 8 <= max_bytes):
            stop += 1
        group = order[start:stop]
        out[group] = _many_numpy(xf, [refs[g] for g in group], band)
        start = stop
    return out


#: Candidates whose cost matrices are built together: a block's per-dimension
#: temporaries (4 × 105 × 105 float64 for a 3.5 s take: 350 kB) stay in the core's
#: cache instead of streaming m whole matrices through memory 17 times (63 windows of
#: the bundled act library: 22 → 12 ms, bit for bit the same).
COST_BLOCK = 4


def _costs_many(x: np.ndarray, refs: Sequence[np.ndarray], ny: int) -> np.ndarray:
    """(m, len(x), ny) Euclidean frame costs of ``x`` to each of ``refs`` (zero-padded to
    ``ny`` frames), each summed dimension by dimension in order as
    :func:`sequential_cost_matrix`, built :data:`COST_BLOCK` candidates at a time."""
    m, nx, dims = len(refs), x.shape[0], x.shape[1]
    y_t = np.zeros((m, dims, ny))  # per candidate, one contiguous row per dimension
    for c, r in enumerate(refs):
        y_t[c, :, :len(r)] = r.T
    x_t = np.ascontiguousarray(x.T)
    cost = np.empty((m, nx, ny))
    t = np.empty((min(COST_BLOCK, m), nx, ny))
    for s in range(0, m, COST_BLOCK):
        e = min(m, s + COST_BLOCK)
        block, tb = cost[s:e], t[: e - s]
        block.fill(0.0)
        for k in range(dims):  # subtract, square, add, per dimension: sequential_cost_matrix's order
            np.subtract(x_t[k][None, :, None], y_t[s:e, k][:, None, :], out=tb)
            np.multiply(tb, tb, out=tb)
            np.add(block, tb, out=block)
    return np.sqrt(cost, out=cost)


def _many_numpy(x: np.ndarray, refs: Sequence[np.ndarray], band: int | None) -> np.ndarray:
    nx, dims = x.shape
    lens = np.array([len(r) for r in refs])
    ny = int(lens.max())
    m = len(refs)
    nd = nx + ny - 1
    cost = _costs_many(x, refs, ny)
    # cells a candidate does not have (its padding) or that lie outside the band: inf
    for c, n in enumerate(lens):
        cost[c, :, n:] = np.inf
        if band is not None:
            lo, hi = band_limits(nx, int(n), band)
            cols = np.arange(ny)[None, :]
            cost[c][(cols < lo[:, None]) | (cols > hi[:, None])] = np.inf
    # every cell's cost laid out by anti-diagonal, g[c, d, i] = cost of (i, d - i) (inf
    # off the matrix), so the sweep reads each diagonal as a contiguous slice. Cell (i, j)
    # sits at offset (i + j)·nx + i = i·(nx + 1) + j·nx of its candidate's block: one
    # strided copy writes them all (the last at nx·nd - 1, inside the block)
    g = np.full((m, nd, nx), np.inf)
    step = g.itemsize
    np.lib.stride_tricks.as_strided(g, shape=(m, nx, ny), strides=(nd * nx * step, (nx + 1) * step, nx * step),
                                    writeable=True)[...] = cost
    # dtw_cost_numpy's sweep with a leading candidate axis: diagonal arrays indexed by i + 1,
    # index 0 standing for row -1 (inf, except the virtual D[-1, -1] = 0 seeding D[0, 0])
    before = np.full((m, nx + 1), np.inf)
    before[:, 0] = 0.0
    last = np.full((m, nx + 1), np.inf)
    spare = np.full((m, nx + 1), np.inf)
    best = np.empty((m, nx))
    result = np.empty(m)
    finish = nx - 1 + lens - 1  # the diagonal of each candidate's last cell
    for d in range(nd):
        np.minimum(last[:, :nx], last[:, 1:], out=best)
        np.minimum(best, before[:, :nx], out=best)
        new = spare
        new[:, 0] = np.inf  # row -1
        np.add(g[:, d, :], best, out=new[:, 1:])
        done = np.flatnonzero(finish == d)
        if len(done):
            result[done] = new[done, nx]
        spare = before
        before, last = last, new
    return result / (nx + lens)


def _numpy_abandon(x: np.ndarray, y: np.ndarray, limit: float, band: int | None) -> float:
    xf = np.ascontiguousarray(x, dtype=np.float64)
    yf = np.ascontiguousarray(y, dtype=np.float64)
    if xf.ndim != 2 or yf.ndim != 2 or xf.shape[1] != yf.shape[1] or not len(xf) or not len(yf):
        return dtw_features(xf, yf, band, "numpy")  # raises the DTWError naming the problem
    n = len(xf) + len(yf)
    lo, hi = band_limits(len(xf), len(yf), band)
    d = float(dtw_cost_numpy(sequential_cost_matrix(xf, yf), lo, hi)) / n
    return d if d <= limit * (1 + _SLACK) else np.inf


def rows_kernel_ready(backend: str = "auto") -> bool:
    """Whether :func:`dtw_features_abandon_t` can run (the compiled back-end is chosen)."""
    return HAVE_NUMBA and resolve_backend(backend) == "numba"


def dtw_features_abandon_t(x: np.ndarray, y_t: np.ndarray, limit: float = np.inf) -> float:
    """:func:`dtw_features_abandon` with no band on the compiled path, for a caller that has
    checked its arrays once (the re-ranking of one query): ``x`` (frames, d) and ``y_t``
    (d, frames) C-contiguous float64, ``d`` equal, neither empty, and
    :func:`rows_kernel_ready`. The same kernel and the same result, without the per-call
    checks (they cost as much as a short re-ranking DTW)."""
    n = x.shape[0] + y_t.shape[1]
    raw_limit = limit * n * (1 + _SLACK) if limit < np.inf else np.inf
    return float(_nb_dtw_euclid_abandon_rows(x, y_t, raw_limit)) / n


def dtw_features_abandon(x: np.ndarray, y: np.ndarray, limit: float = np.inf, band: int | None = None,
                         backend: str = "auto", y_t: np.ndarray | None = None) -> float:
    """Normalised Euclidean-cost DTW of float features ``x``, ``y`` (as
    :func:`~retrieval.dtw.dtw_features`), or ``inf`` once it must exceed ``limit``
    (a distance above ``limit`` may also come back as itself). ``y_t``: ``y.T`` as a
    C-contiguous float64 array, when the caller keeps one (the re-ranking does, to save
    the copy per candidate); used by the compiled no-band path only."""
    if (y_t is not None and band is None and HAVE_NUMBA and x.dtype == np.float64 and x.flags.c_contiguous
            and x.ndim == 2 and len(x) and y_t.ndim == 2 and y_t.shape[0] == x.shape[1] and y_t.shape[1]
            and y_t.dtype == np.float64 and y_t.flags.c_contiguous and resolve_backend(backend) == "numba"):
        n = len(x) + y_t.shape[1]
        raw_limit = limit * n * (1 + _SLACK) if limit < np.inf else np.inf
        return float(_nb_dtw_euclid_abandon_rows(x, y_t, raw_limit)) / n
    if resolve_backend(backend) != "numba":
        return _numpy_abandon(x, y, limit, band)
    xf = np.ascontiguousarray(x, dtype=np.float64)
    yf = np.ascontiguousarray(y, dtype=np.float64)
    if xf.ndim != 2 or yf.ndim != 2 or xf.shape[1] != yf.shape[1] or not len(xf) or not len(yf):
        return dtw_features(xf, yf, band, backend)  # raises the DTWError naming the problem
    n = len(xf) + len(yf)
    raw_limit = limit * n * (1 + _SLACK) if np.isfinite(limit) else np.inf
    if band is None:
        return float(_nb_dtw_euclid_abandon_rows(xf, np.ascontiguousarray(yf.T), raw_limit)) / n
    lo, hi = band_limits(len(xf), len(yf), band)
    return float(dtw_euclid_nb(xf, yf, lo, hi, raw_limit)) / n
