"""The block-corner DTW over runs: the fast search's ``"runs"`` mode (an upper bound of the
exact DTW), compiled beside its numpy twins.

A diagonal step through block (p, q) — run p of the first sequence × run q of the second,
cost ``c = D[A_p, B_q]`` — costs ``c·max(h_p, w_q)``, a vertical one ``c·h_p``, a horizontal
one ``c·w_q``. Each is the cost of a real warping path through the block, so the result is
>= the exact DTW (:mod:`retrieval.dtw.runlength` computes that one exactly) and equals it
when every run has length 1. The fast search uses it as the ``"runs"`` distance and, in
exact mode, as an upper bound of a few candidates' distances (the cap on the k-th best).

* :func:`runs_dtw_raw` — compiled (numba), row by row over runs, with early abandoning;
* :func:`runs_dtw_numpy` — the same operations one anti-diagonal at a time (the reference);
* :func:`runs_dtw_rows_numpy` / :func:`runs_dtw_rows_batch_numpy` — one query run (row) at a
  time as min-plus scans, for one candidate or many side by side (the tablet's path; bit for
  bit under exact sums, :func:`~retrieval.dtw.runlength.rle_is_exact`).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from retrieval.codes import DiffTable
from retrieval.dtw.jit import HAVE_NUMBA, numba

if HAVE_NUMBA:  # optional: numba (the kernels below exist only where it is installed)
    from retrieval.dtw.runlength import diff_cost

    @numba.njit(cache=True, nogil=True)
    def runs_dtw_raw(a_val, a_len, b_val, b_len, F, absdiff, shift, mask, rest_run, limit, norm, prev, cur):
        """Block-corner DTW over runs (the ``"runs"`` approximation): a diagonal step
        through block (p, q) costs c·max(h_p, w_q), a vertical one c·h_p, a horizontal one
        c·w_q. Each is the cost of a real warping path, so the result is >= the exact DTW
        (an upper bound that equals it when every run has length 1)."""
        kx, ky = a_val.shape[0], b_val.shape[0]
        inf = np.inf
        for q in range(ky):
            prev[q] = inf
        for p in range(kx):
            h = a_len[p]
            ap = a_val[p]
            m = inf
            for q in range(ky):
                w = b_len[q]
                c = diff_cost(ap, b_val[q], F, absdiff, shift, mask)
                if p == 0 and q == 0:
                    v = c * (h if h > w else w)
                else:
                    v = inf
                    if p > 0 and q > 0:
                        v = prev[q - 1] + c * (h if h > w else w)
                    if p > 0:
                        x = prev[q] + c * h
                        if x < v:
                            v = x
                    if q > 0:
                        x = cur[q - 1] + c * w
                        if x < v:
                            v = x
                cur[q] = v
                if v < m:
                    m = v
            if (m + rest_run[p]) / norm > limit:
                return inf
            prev, cur = cur, prev
        return prev[ky - 1]


def runs_dtw_numpy(cost: np.ndarray, a_len: np.ndarray, b_len: np.ndarray) -> float:
    """The ``"runs"`` block-corner DTW (see :func:`runs_dtw_raw`) over a (runs × runs) block
    cost matrix, one anti-diagonal at a time; same operations, same numbers."""
    kx, ky = cost.shape
    h = np.asarray(a_len, dtype=np.float64)
    w = np.asarray(b_len, dtype=np.float64)
    # arrays indexed by p + 1 (index 0 = virtual row -1)
    before = np.full(kx + 1, np.inf)
    last = np.full(kx + 1, np.inf)
    for d in range(kx + ky - 1):
        p = np.arange(max(0, d - ky + 1), min(kx - 1, d) + 1)
        q = d - p
        c = cost[p, q]
        diag = before[p] + c * np.maximum(h[p], w[q])
        if d == 0:
            diag = c * np.maximum(h[p], w[q])
        up = last[p] + c * h[p]  # from (p-1, q)
        lf = last[p + 1] + c * w[q]  # from (p, q-1)
        new = np.full(kx + 1, np.inf)
        new[p + 1] = np.minimum(np.minimum(diag, up), lf)
        before, last = last, new
    return float(last[kx])


def runs_dtw_rows_batch_numpy(table: DiffTable, q_runs: np.ndarray, q_lens: np.ndarray,
                              candidates: Sequence[tuple[np.ndarray, np.ndarray]], limits: np.ndarray) -> np.ndarray:
    """:func:`runs_dtw_rows_numpy` for many candidates at once: each candidate's (run values,
    run lengths) against the query's runs, raw (unnormalised) distances, ``inf`` for a
    candidate whose whole row exceeds its ``limits`` entry. Candidates are padded on the
    right to the most runs (cost 0, length 0); a padded column never feeds a real one
    (cells depend only on columns at or left of their own), and each row's minimum, the
    abandoning test, is taken over the real columns only. Per candidate the operations are
    those of :func:`runs_dtw_rows_numpy` along a leading axis: the same values bit for bit
    under exact sums (the caller's condition)."""
    m = len(candidates)
    ky = np.array([len(v) for v, _ in candidates])
    width = int(ky.max())
    vals = np.zeros((m, width), np.int64)
    w = np.zeros((m, width))
    for c, (v, ln) in enumerate(candidates):
        vals[c, :len(v)] = v
        w[c, :len(ln)] = ln
    cost = table.lookup(np.asarray(q_runs, np.int64)[:, None, None], vals[None, :, :])  # (query runs, m, width)
    return _runs_rows(cost, q_lens, w, ky, limits)


def runs_dtw_rows_numpy(cost: np.ndarray, a_len: np.ndarray, b_len: np.ndarray, limit: float = np.inf) -> float:
    """The ``"runs"`` block-corner DTW (:func:`runs_dtw_raw`) one query run (row) at a time,
    abandoned (``inf``) as soon as a whole row exceeds ``limit`` (raw, unnormalised).

    Row p from row p - 1: ``X[q] = min(prev[q-1] + c·max(h_p, w_q), prev[q] + c·h_p)`` (the
    diagonal and vertical steps, vectorised), then the horizontal steps
    ``cur[q] = min(X[q], cur[q-1] + c_q·w_q)``, a min-plus scan solved in closed form:
    with ``S[q] = Σ_{i<=q} c_i·w_i``, ``cur[q] = S[q] + min_{j<=q}(X[j] - S[j])``
    (``np.minimum.accumulate``). Every cell of a row is >= the row's minimum and every
    path crosses every row, so the distance is >= that minimum: abandoning when it exceeds
    ``limit`` is safe. The sums are regrouped, so the value equals the sequential DP bit
    for bit only when every sum is exact (:func:`retrieval.dtw.rle_is_exact`), which is
    when the caller uses it."""
    c = np.asarray(cost, dtype=np.float64)
    w = np.asarray(b_len, dtype=np.float64)
    return float(_runs_rows(c[:, None, :], a_len, w[None, :], np.array([c.shape[1]]), np.array([limit]))[0])


def _runs_rows(cost: np.ndarray, q_lens: np.ndarray, w: np.ndarray, ky: np.ndarray, limits) -> np.ndarray:
    """The row scans of :func:`runs_dtw_rows_numpy` for ``m`` candidates side by side:
    ``cost`` (query runs, m, width), ``w`` (m, width) run lengths, ``ky`` each candidate's
    real width (columns past it are padding: cost 0, length 0), ``limits`` (m,) raw."""
    m, width = w.shape
    real = np.arange(width)[None, :] < ky[:, None]
    cost = np.where(real[None], cost, 0.0)
    h = np.asarray(q_lens, dtype=np.float64)
    lim = np.asarray(limits, dtype=np.float64)
    alive = np.ones(m, bool)
    prev = None
    for p in range(cost.shape[0]):
        c = cost[p]
        if prev is None:
            x = np.full((m, width), np.inf)
            x[:, 0] = c[:, 0] * np.maximum(h[0], w[:, 0])
        else:
            x = prev + c * h[p]
            x[:, 1:] = np.minimum(x[:, 1:], prev[:, :-1] + c[:, 1:] * np.maximum(h[p], w[:, 1:]))
        steps = np.cumsum(c * w, axis=1)
        cur = steps + np.minimum.accumulate(x - steps, axis=1)
        alive &= ~(np.where(real, cur, np.inf).min(axis=1) > lim)
        if not alive.any():
            return np.full(m, np.inf)
        prev = cur
    return np.where(alive, prev[np.arange(m), ky - 1], np.inf)
