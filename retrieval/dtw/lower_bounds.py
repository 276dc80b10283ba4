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
