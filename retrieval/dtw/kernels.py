"""Dynamic time warping over quantised codes (cost = table look-up) and over real features.

Two interchangeable back-ends give the same numbers:

* ``"numba"`` — compiled row-by-row kernels (``cache=True``) that never build the cost
  matrix: each cell costs one table look-up (or a 17-D Euclidean distance). This is what
  the desktop tools and the experiment use.
* ``"numpy"`` — no numba (Android has no numba/llvmlite): the cost matrix is built with
  one fancy-indexing look-up, then the recurrence runs one anti-diagonal at a time, each
  diagonal a handful of vectorised operations. For codes it is bit-identical to the
  numba path (the same float64 additions in the same order; ``min`` is exact); for real
  features the frame distances can differ in the last bits (numpy sums the 17 squares in
  another order).

Recurrence (0-based): ``D[i, j] = cost(i, j) + min(D[i−1, j], D[i, j−1], D[i−1, j−1])``
with ``D[0, 0] = cost(0, 0)``; the result is ``D[x−1, y−1]``.

**Length normalisation.** A warping path between clips of x and y frames has between
max(x, y) and x+y−1 cells, so raw DTW grows with the clips' lengths and a 1-NN search
would favour short references. By default the distance is divided by ``x + y`` (the
path-length bound), making it a mean cost per step that compares across lengths.
``normalize=False`` gives the raw sum.

**Band.** ``band=r`` restricts row i to columns within r of the straight line from (0, 0)
to (x−1, y−1), i.e. ``|j − i·(y−1)/(x−1)| ≤ r``. The effective radius is at least the
line's slope, so the corner cells always connect; ``band=None`` is unconstrained.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from retrieval.codes import SplitTable
from retrieval.dtw.jit import BACKENDS, HAVE_NUMBA, numba
from retrieval.errors import StoryBeamError


class DTWError(StoryBeamError):
    """Bad DTW input (empty sequence, unknown back-end, codes outside the table)."""


# --------------------------------------------------------------------------- helpers
def band_limits(nx: int, ny: int, band: int | None) -> tuple[np.ndarray, np.ndarray]:
    """Per-row inclusive column limits (lo, hi) as int64 arrays of length nx."""
    if band is None:
        return np.zeros(nx, dtype=np.int64), np.full(nx, ny - 1, dtype=np.int64)
    if band < 0:
        raise DTWError(f"band must be >= 0, got {band}")
    if nx == 1:
        return np.zeros(1, dtype=np.int64), np.full(1, ny - 1, dtype=np.int64)
    slope = (ny - 1) / (nx - 1)
    r = max(float(band), slope, 1.0 if ny > 1 else 0.0)
    centre = np.arange(nx) * slope
    lo = np.clip(np.ceil(centre - r - 1e-9), 0, ny - 1).astype(np.int64)
    hi = np.clip(np.floor(centre + r + 1e-9), 0, ny - 1).astype(np.int64)
    return lo, hi


def resolve_backend(backend: str) -> str:
    if backend not in BACKENDS:
        raise DTWError(f"unknown DTW back-end {backend!r} (choose from {', '.join(BACKENDS)})")
    if backend == "auto":
        return "numba" if HAVE_NUMBA else "numpy"
    if backend == "numba" and not HAVE_NUMBA:
        raise DTWError("numba back-end requested but numba is not installed")
    return backend


def check_codes(codes: np.ndarray, size: int, what: str) -> np.ndarray:
    c = np.ascontiguousarray(codes, dtype=np.int32)
    if c.ndim != 1 or c.size == 0:
        raise DTWError(f"{what} codes must be a non-empty 1-D array, got shape {np.shape(codes)}")
    if c.min() < 0 or c.max() >= size:
        raise DTWError(f"{what} codes must lie in [0, {size}), got [{c.min()}, {c.max()}]")
    return c


def _table_size(table: np.ndarray | SplitTable) -> int:
    if isinstance(table, SplitTable):
        return table.low.shape[0] * table.high.shape[0]
    if table.ndim != 2 or table.shape[0] != table.shape[1]:
        raise DTWError(f"table must be square, got {table.shape}")
    return table.shape[0]


# --------------------------------------------------------------------------- numba kernels
if HAVE_NUMBA:
    # Each kernel writes the recurrence's min over the three predecessors out in full. A
    # shared @njit helper for it gave the same numbers but ran the code kernel about 5x
    # slower (2.1 ms -> 10.7 ms for one 1000x1000 code pair, measured side by side on an
    # idle machine; the cause was not investigated). Keep the copies. Measured again with
    # numba 0.68 and ``inline="always"`` (issue 30): 17 -> 40 ms for a 1000x1000 pair on a
    # busy machine, so the fast search's corridor DP (:func:`retrieval.dtw.rowscan.plain_dtw_raw`)
    # keeps its copy too. The re-ranking's banded kernel is :func:`dtw_euclid_nb` itself.

    @numba.njit(cache=True, nogil=True)
    def _nb_dtw_table(a, b, table, lo, hi):
        nx, ny = a.shape[0], b.shape[0]
        inf = np.inf
        prev = np.full(ny, inf)
        cur = np.full(ny, inf)
        for i in range(nx):
            if i >= 2:  # cur holds row i-2: clear its band only (keeps banded runs cheap)
                for j in range(lo[i - 2], hi[i - 2] + 1):
                    cur[j] = inf
            row = table[a[i]]
            for j in range(lo[i], hi[i] + 1):
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
                cur[j] = row[b[j]] + best
            prev, cur = cur, prev
        return prev[ny - 1]

    @numba.njit(cache=True, nogil=True)
    def _nb_dtw_split(a_lo, a_hi, b_lo, b_hi, low, high, lo, hi):
        nx, ny = a_lo.shape[0], b_lo.shape[0]
        inf = np.inf
        prev = np.full(ny, inf)
        cur = np.full(ny, inf)
        for i in range(nx):
            if i >= 2:
                for j in range(lo[i - 2], hi[i - 2] + 1):
                    cur[j] = inf
            row_lo = low[a_lo[i]]
            row_hi = high[a_hi[i]]
            for j in range(lo[i], hi[i] + 1):
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
                cost = np.float64(row_lo[b_lo[j]]) + np.float64(row_hi[b_hi[j]])
                cur[j] = cost + best
            prev, cur = cur, prev
        return prev[ny - 1]

    @numba.njit(cache=True, nogil=True, fastmath=False)
    def dtw_euclid_nb(x, y, lo, hi, raw_limit):
        """Raw Euclidean-cost DTW of feature rows ``x``, ``y`` within the band ``lo``/``hi``,
        or inf as soon as a whole row's minimum exceeds ``raw_limit`` (every path crosses
        every row and costs only grow along it; ``raw_limit = inf``: the plain DTW, every
        row to the end). The re-ranking's banded path (:mod:`retrieval.dtw.rerank`) passes
        its limit; each cell sums its squares dimension by dimension."""
        nx, ny, d = x.shape[0], y.shape[0], x.shape[1]
        inf = np.inf
        prev = np.full(ny, inf)
        cur = np.full(ny, inf)
        for i in range(nx):
            if i >= 2:
                for j in range(lo[i - 2], hi[i - 2] + 1):
                    cur[j] = inf
            rowmin = inf
            for j in range(lo[i], hi[i] + 1):
                s = 0.0
                for k in range(d):
                    t = x[i, k] - y[j, k]
                    s += t * t
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
                v = np.sqrt(s) + best
                cur[j] = v
                if v < rowmin:
                    rowmin = v
            if rowmin > raw_limit:
                return inf
            prev, cur = cur, prev
        return prev[ny - 1]

    @numba.njit(cache=True, nogil=True)
    def band_limits_nb(nx, ny, band, lo, hi):
        """:func:`band_limits`, compiled (band >= 0; band < 0 means none)."""
        if band < 0 or nx == 1:
            for i in range(nx):
                lo[i] = 0
                hi[i] = ny - 1
            return
        slope = (ny - 1) / (nx - 1)
        r = float(band)
        if slope > r:
            r = slope
        one = 1.0 if ny > 1 else 0.0
        if one > r:
            r = one
        for i in range(nx):
            centre = i * slope
            x = np.ceil(centre - r - 1e-9)
            y = np.floor(centre + r + 1e-9)
            lo[i] = int(min(max(x, 0.0), ny - 1))
            hi[i] = int(min(max(y, 0.0), ny - 1))


# --------------------------------------------------------------------------- numpy path
def dtw_cost_numpy(cost: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Anti-diagonal DTW over a dense float64 cost matrix (cells outside the band ignored)."""
    nx, ny = cost.shape
    cols = np.arange(ny)
    cost = np.where((cols[None, :] >= lo[:, None]) & (cols[None, :] <= hi[:, None]), cost, np.inf)
    # Diagonal arrays are indexed by i + 1; index 0 stands for row -1 (always inf, except
    # the virtual D[-1, -1] = 0 that seeds D[0, 0] = cost[0, 0]).
    before = np.full(nx + 1, np.inf)
    before[0] = 0.0
    last = np.full(nx + 1, np.inf)
    for d in range(nx + ny - 1):
        i = np.arange(max(0, d - ny + 1), min(nx - 1, d) + 1)
        up, left, diag = last[i], last[i + 1], before[i]
        best = np.minimum(np.minimum(up, left), diag)
        new = np.full(nx + 1, np.inf)
        new[i + 1] = cost[i, d - i] + best
        before, last = last, new
    return float(last[nx])


def _lookup_matrix(a: np.ndarray, b: np.ndarray, table: np.ndarray | SplitTable) -> np.ndarray:
    if isinstance(table, SplitTable):
        return table.lookup(a[:, None], b[None, :])
    return table[a[:, None], b[None, :]].astype(np.float64)


def _euclidean_matrix(x: np.ndarray, y: np.ndarray, max_block_bytes: int = 32 << 20) -> np.ndarray:
    """(nx, ny) Euclidean frame distances, computed in row blocks so the (rows, ny, d)
    temporary stays under ``max_block_bytes`` (two 120 fps clips of 20 s would otherwise
    need gigabytes)."""
    nx, ny, d = x.shape[0], y.shape[0], x.shape[1]
    rows = max(1, max_block_bytes // max(1, ny * d * 8))
    out = np.empty((nx, ny))
    for start in range(0, nx, rows):
        block = x[start:start + rows, None, :] - y[None, :, :]
        out[start:start + rows] = np.sqrt((block**2).sum(axis=2))
    return out


def _split_codes(codes: np.ndarray, table: SplitTable) -> tuple[np.ndarray, np.ndarray]:
    shift = 2 * table.low_dims
    return (codes & ((1 << shift) - 1)).astype(np.int32), (codes >> shift).astype(np.int32)


# --------------------------------------------------------------------------- public API
def dtw_codes(
    a: np.ndarray,
    b: np.ndarray,
    table: np.ndarray | SplitTable,
    band: int | None = None,
    backend: str = "auto",
    normalize: bool = True,
) -> float:
    """DTW distance between two code sequences whose frame cost is ``table[a_i, b_j]``.

    ``table`` is a square float32 table or a :class:`~retrieval.codes.quantizer.SplitTable`.
    Normalised by ``len(a) + len(b)`` unless ``normalize=False``.
    """
    size = _table_size(table)
    a = check_codes(a, size, "first")
    b = check_codes(b, size, "second")
    lo, hi = band_limits(len(a), len(b), band)
    if resolve_backend(backend) == "numba":
        if isinstance(table, SplitTable):
            a_lo, a_hi = _split_codes(a, table)
            b_lo, b_hi = _split_codes(b, table)
            raw = _nb_dtw_split(a_lo, a_hi, b_lo, b_hi, table.low, table.high, lo, hi)
        else:
            raw = _nb_dtw_table(a, b, table, lo, hi)
    else:
        raw = dtw_cost_numpy(_lookup_matrix(a, b, table), lo, hi)
    return float(raw) / (len(a) + len(b)) if normalize else float(raw)


def _check_features(x: np.ndarray, what: str) -> np.ndarray:
    f = np.ascontiguousarray(x, dtype=np.float64)
    if f.ndim == 1:
        f = f[:, None]
    if f.ndim != 2 or f.shape[0] == 0:
        raise DTWError(f"{what} features must be a non-empty (frames, dims) array, got {np.shape(x)}")
    return f


def dtw_features(
    x: np.ndarray,
    y: np.ndarray,
    band: int | None = None,
    backend: str = "auto",
    normalize: bool = True,
) -> float:
    """DTW distance between real feature sequences (T, d) with Euclidean frame cost."""
    x = _check_features(x, "first")
    y = _check_features(y, "second")
    if x.shape[1] != y.shape[1]:
        raise DTWError(f"feature widths differ: {x.shape[1]} vs {y.shape[1]}")
    lo, hi = band_limits(len(x), len(y), band)
    if resolve_backend(backend) == "numba":
        raw = dtw_euclid_nb(x, y, lo, hi, np.inf)
    else:
        raw = dtw_cost_numpy(_euclidean_matrix(x, y), lo, hi)
    return float(raw) / (len(x) + len(y)) if normalize else float(raw)


def dtw_codes_to_many(
    query: np.ndarray,
    references: Sequence[np.ndarray],
    table: np.ndarray | SplitTable,
    band: int | None = None,
    backend: str = "auto",
) -> np.ndarray:
    """Normalised code-DTW distances from one query to each reference."""
    return np.array([dtw_codes(query, r, table, band, backend) for r in references])


def dtw_features_to_many(
    query: np.ndarray,
    references: Sequence[np.ndarray],
    band: int | None = None,
    backend: str = "auto",
) -> np.ndarray:
    """Normalised feature-DTW distances from one query to each reference."""
    return np.array([dtw_features(query, r, band, backend) for r in references])
