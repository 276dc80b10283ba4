"""Lower bounds of the look-up DTW (:func:`retrieval.dtw.kernels.dtw_codes`, length-normalised by
``len(a) + len(b)``), used to skip candidates without running their DTW.

Every warping path from (0, 0) to (x−1, y−1) visits every row and every column, and both
corners; costs are non-negative. Hence, for the frame cost ``D``:

* **LB_Kim** — ``D[a_0, b_0] + D[a_last, b_last]`` (just ``D[a_0, b_0]`` when the corners
  coincide, i.e. both clips have one frame).
* **envelope, rows** — ``Σ_i min_j D[a_i, b_j]``: every query frame is matched at least once,
  at no less than its cheapest partner. This is LB_Keogh with the window = the whole
  candidate (no band: the seed's DTW is unconstrained); since only the candidate's *set of
  distinct codes* matters, it costs |distinct(a)| × |distinct(b)| look-ups (about 30 × 30
  on the shared clips) instead of x·y cells, with each distinct query code counted with
  its multiplicity.
* **envelope, columns** — the same with the roles swapped.

The bound used is the maximum of the three, divided by ``x + y`` like the DTW. With a
Sakoe–Chiba band the DTW can only grow, so the same bounds stay valid. The suffix sums of
the per-row minima also give the early-abandoning bound "cost still to come" used while a
DTW runs (:mod:`retrieval.search.fast`).

This module holds the plain numpy versions (reference and Android path); the compiled
ones in :mod:`retrieval.search.fast` compute the same sums in the same order.
:func:`library_bounds` computes the same three bounds for a whole library at once (the
tablet's search): one look-up per (distinct query code, library vocabulary code), then
``minimum.reduceat`` / ``add.reduceat`` over each clip's distinct codes.
"""
from __future__ import annotations

import numpy as np

from retrieval.codes import DiffTable


def distinct_counts(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted distinct codes and how often each occurs (int32, int64)."""
    vals, counts = np.unique(np.asarray(codes), return_counts=True)
    return vals.astype(np.int32), counts.astype(np.int64)


def lb_kim(a: np.ndarray, b: np.ndarray, table: DiffTable) -> float:
    """Normalised LB_Kim (corner cells)."""
    raw = float(table.lookup(a[0], b[0]))
    if len(a) > 1 or len(b) > 1:
        raw += float(table.lookup(a[-1], b[-1]))
    return raw / (len(a) + len(b))


def envelope_sums(a: np.ndarray, b: np.ndarray, table: DiffTable) -> tuple[float, float]:
    """Raw (rows, columns) envelope sums: Σ_i min_j D[a_i, b_j] and Σ_j min_i D[a_i, b_j]."""
    ua, ca = distinct_counts(a)
    ub, cb = distinct_counts(b)
    d = table.lookup(ua[:, None], ub[None, :])
    rows = 0.0
    for v in d.min(axis=1) * ca:  # sequential float64 sum (the compiled kernel's order)
        rows += float(v)
    cols = 0.0
    for v in d.min(axis=0) * cb:
        cols += float(v)
    return rows, cols


def lb_envelope(a: np.ndarray, b: np.ndarray, table: DiffTable) -> float:
    """Normalised max(rows, columns) envelope bound."""
    rows, cols = envelope_sums(a, b, table)
    return max(rows, cols) / (len(a) + len(b))


def lower_bound(a: np.ndarray, b: np.ndarray, table: DiffTable) -> float:
    """The bound the fast search uses: max(LB_Kim, envelope rows, envelope columns)."""
    return max(lb_kim(a, b, table), lb_envelope(a, b, table))


def library_bounds(a: np.ndarray, vocab: np.ndarray, dist_vidx: np.ndarray, dist_cnt: np.ndarray,
                   dist_off: np.ndarray, first: np.ndarray, last: np.ndarray, lengths: np.ndarray,
                   table: DiffTable) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`lower_bound` of query ``a`` against every clip of a library, vectorised.

    The library is given by its vocabulary (sorted distinct codes it uses), each clip's
    distinct codes as indices into it (``dist_vidx[dist_off[c]:dist_off[c+1]]``) with their
    counts, its first and last codes and its length. The bounds are those of the module
    docstring (each proven there): LB_Kim on the corners, the row envelope Σ_u count(u) ·
    min_v D[u, v] over the clip's distinct codes v, the column envelope Σ_v count(v) ·
    min_u D[u, v] over the query's distinct codes u; the maximum divided by ``x + y``.

    Returns ``(bounds, rowmin, colmin, a_didx, R)``: ``rowmin[u, c]`` = query code u's
    cheapest code in clip c, ``colmin[t]`` = vocabulary code t's cheapest query code,
    ``a_didx[i]`` = frame i's index among the query's distinct codes, and ``R[u, t] =
    D[u, vocab[t]]`` (float64), from which the search reads its cost matrices."""
    a = np.asarray(a)
    ua, a_didx, ca = np.unique(a, return_inverse=True, return_counts=True)
    R = table.lookup(ua[:, None], np.asarray(vocab)[None, :]).astype(np.float64)
    starts = np.asarray(dist_off[:-1], dtype=np.int64)
    rowmin = np.minimum.reduceat(R[:, dist_vidx], starts, axis=1)
    rows = (rowmin * ca[:, None].astype(np.float64)).sum(axis=0)
    colmin = R.min(axis=0)
    cols = np.add.reduceat(colmin[dist_vidx] * np.asarray(dist_cnt, dtype=np.float64), starts)
    lengths = np.asarray(lengths, dtype=np.int64)
    kim = table.lookup(np.full(len(first), a[0]), np.asarray(first)).astype(np.float64)
    two = (len(a) > 1) | (lengths > 1)
    kim = kim + np.where(two, table.lookup(np.full(len(last), a[-1]), np.asarray(last)).astype(np.float64), 0.0)
    bounds = np.maximum(np.maximum(kim, rows), cols) / (len(a) + lengths)
    return bounds, rowmin, colmin, a_didx.reshape(-1).astype(np.int64), R
