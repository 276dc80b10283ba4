"""The fast search's numpy path (the tablet's: no numba), the twin of the compiled
candidate loop (:mod:`retrieval.search.cascade`): the same bounds, order and pruning, the
same answers.

For the seed's distance with exact sums (the usual case) every bound is computed for the
whole library at once (:func:`retrieval.dtw.library_bounds`) and each surviving
candidate's DP runs row by row as min-plus scans with early abandoning and a corridor
(:func:`retrieval.dtw.dtw_rows_numpy`): the same neighbours and distances bit for bit.
Otherwise (a band, the ``"runs"`` mode, sums that may round) per-candidate bounds and the
anti-diagonal DP of :mod:`retrieval.dtw.kernels`, without early abandoning or run-length
blocks; the ``"runs"`` mode's DPs run many candidates at once
(:func:`retrieval.dtw.runs_dtw_rows_batch_numpy`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from retrieval.dtw import (
    band_limits,
    dtw_cost_numpy,
    dtw_rows_numpy,
    library_bounds,
    monotone_cover_numpy,
    rle_is_exact,
    run_length_encode,
    runs_dtw_numpy,
    runs_dtw_rows_batch_numpy,
)
from retrieval.search.packed import PackedCodes
from retrieval.search.results import SearchResult, SearchStats

if TYPE_CHECKING:  # deferred: the searcher imports this module
    from retrieval.search.fast import FastSearcher


class NumpySearch:
    """The numpy path of one :class:`~retrieval.search.fast.FastSearcher`: its settings
    (mode, band, bounds) are read from the searcher at each search, the library's arrays
    in the layout the vectorised bounds take are built on the first search."""

    def __init__(self, searcher: "FastSearcher"):
        self.searcher = searcher
        self._np_lib: dict | None = None

    def _layout(self) -> dict:
        """What the tablet's vectorised bounds take (built on the first numpy search)."""
        s = self.searcher
        if self._np_lib is None:
            lib = s.library
            self._np_lib = {"dist_vidx": s.vocab_index(lib.dist_val).astype(np.int64),
                            "first": lib.codes[lib.code_off[:-1]], "last": lib.codes[lib.code_off[1:] - 1],
                            "lengths": lib.lengths, "codes_vidx": s.vocab_index(lib.codes).astype(np.int64),
                            "runs_vidx": s.vocab_index(lib.run_val).astype(np.int64)}
        return self._np_lib

    def search(self, packed: PackedCodes, k: int) -> SearchResult:
        """The tablet's path. For the seed's distance with exact sums (the usual case) every
        bound is computed for the whole library at once (:func:`retrieval.dtw.library_bounds`)
        and each surviving candidate's DP runs row by row as min-plus scans with early
        abandoning and a corridor (:func:`retrieval.dtw.dtw_rows_numpy`) — the same bounds,
        order and pruning as the compiled path, the same answers bit for bit. Otherwise
        (band, "runs" mode, inexact sums) :meth:`_search_plain`."""
        s = self.searcher
        longest = int(packed.lengths.max())
        if not (s.mode == "exact" and s.band is None and s.use_bounds
                and rle_is_exact(s.table.F, s.longest + longest)):
            return self._search_plain(packed, k)
        lib = s.library
        nl = self._layout()
        shrink = 1.0 - 1e-9  # bound sums in numpy's order: keep every comparison on the safe side
        out_idx = np.full((len(packed), k), -1, np.int64)
        out_dist = np.full((len(packed), k), np.inf)
        stats = SearchStats()
        for qi in range(len(packed)):
            a = packed.sequence(qi)
            nx = len(a)
            lbs, rowmin, colmin, a_didx, R = library_bounds(a, s.vocab, nl["dist_vidx"], lib.dist_cnt,
                                                            lib.dist_off, nl["first"], nl["last"], nl["lengths"],
                                                            s.table)
            lbs *= shrink
            Ra = R[a_didx]  # each query frame's table row over the vocabulary
            Rq_runs = R[packed.run_didx[packed.run_off[qi]:packed.run_off[qi + 1]]]  # and each query run's
            q_lens = packed.run_len[packed.run_off[qi]:packed.run_off[qi + 1]]
            order = np.argsort(lbs, kind="stable")
            best: list[tuple[float, int]] = []
            pruned = rejected = abandoned = 0
            # an upper bound of the k-th best distance before any DP: the cost of one real
            # warping path (the straight line from corner to corner, a monotone staircase
            # with steps of at most one row and one column) for the k + 2 best-bound
            # candidates; the k-th smallest of them is >= the k-th best distance
            cap = np.inf
            if len(order) >= k:
                ubs = []
                for c in order[:k + 2]:
                    b_v = nl["codes_vidx"][lib.code_off[c]:lib.code_off[c + 1]]
                    steps = np.arange(max(nx, len(b_v)))
                    span = max(len(steps) - 1, 1)
                    ubs.append(float(Ra[steps * (nx - 1) // span, b_v[steps * (len(b_v) - 1) // span]].sum())
                               / (nx + len(b_v)))
                cap = sorted(ubs)[k - 1]
            for pos, c in enumerate(order):
                thr = min(best[k - 1][0] if len(best) >= k else np.inf, cap)
                if lbs[c] > thr:
                    pruned = len(order) - pos
                    break
                b_v = nl["codes_vidx"][lib.code_off[c]:lib.code_off[c + 1]]
                norm = nx + len(b_v)
                if s.range_bound:
                    c_lens = lib.run_len[lib.run_off[c]:lib.run_off[c + 1]]
                    cost = Rq_runs[:, nl["runs_vidx"][lib.run_off[c]:lib.run_off[c + 1]]]
                    rb = max(monotone_cover_numpy(cost, q_lens), monotone_cover_numpy(cost.T, c_lens))
                    if rb * shrink / norm > thr:
                        rejected += 1
                        continue
                per_row = rowmin[a_didx, c]
                rest_row = (np.cumsum(per_row[::-1])[::-1] - per_row) * shrink
                per_col = colmin[b_v]
                rest_col = (np.cumsum(per_col[::-1])[::-1] - per_col) * shrink
                raw = dtw_rows_numpy(Ra[:, b_v], rest_row, rest_col, thr * norm * (1.0 + 1e-9))
                if raw == np.inf:
                    abandoned += 1
                    continue
                best = sorted(best + [(float(raw) / norm, int(c))])[:k]
            for t, (d, c) in enumerate(best):
                out_idx[qi, t], out_dist[qi, t] = c, d
            stats.candidates += len(lib)
            stats.pruned += pruned
            stats.abandoned += rejected + abandoned
            stats.range_rejected += rejected
            stats.completed += len(lib) - pruned - rejected - abandoned
        return SearchResult(out_idx, out_dist, stats)

    def _runs_batches(self, q_runs: np.ndarray, q_lens: np.ndarray, q_frames: int, lbs: np.ndarray,
                            order: np.ndarray, k: int) -> tuple[list[tuple[float, int]], int]:
        """The k nearest clips by the ``"runs"`` distance, on numpy, candidates taken in
        bound order in batches (8, then 16, 32, …): before each batch the k-th best
        distance so far prunes by bound (the order is sorted, so the rest go too), then the
        batch's DPs run together with early abandoning against that distance
        (:func:`runs_dtw_rows_batch_numpy`). A candidate in the final k best has a distance
        at most every threshold used on the way, so it is never pruned or abandoned; the
        answers are those of the one-by-one loop (sorted by distance, then index). Used
        when every sum is exact, so the batched row scans give the sequential DP's values
        bit for bit. Returns (best (distance, index) pairs, clips pruned by bound)."""
        s = self.searcher
        lib = s.library
        best: list[tuple[float, int]] = []
        pos, size = 0, 8
        while pos < len(order):
            thr = best[k - 1][0] if len(best) >= k else np.inf
            batch = order[pos:pos + size]
            keep = lbs[batch] <= thr
            cut = len(batch) if keep.all() else int(np.argmin(keep))  # sorted by bound: the rest from here are pruned
            if cut:
                batch = batch[:cut]
                runs = [(lib.run_val[lib.run_off[c]:lib.run_off[c + 1]], lib.run_len[lib.run_off[c]:lib.run_off[c + 1]])
                        for c in batch]
                frames = np.array([lib.code_off[c + 1] - lib.code_off[c] for c in batch], np.float64) + q_frames
                raw = runs_dtw_rows_batch_numpy(s.table, q_runs, q_lens, runs, thr * frames)
                best = sorted(best + [(float(r) / f, int(c)) for r, f, c in zip(raw, frames, batch)])[:k]
            pos += cut
            if cut < size:  # pruned by bound, or the end of the order
                return best, len(order) - pos
            size *= 2
        return best, 0

    def _search_plain(self, packed: PackedCodes, k: int) -> SearchResult:
        """The numpy path for a band, the \"runs\" mode or sums that may round: per-candidate
        bounds and the anti-diagonal DP of :mod:`retrieval.dtw.kernels`."""
        s = self.searcher

        lib = s.library
        # the range-cover bound (rows and columns, each a vectorised monotone-choice DP
        # per run) rejects most candidates that pass the envelope before their DP runs; it
        # needs the seed's unconstrained distance. Its sums may round differently from the
        # DP's: shrink it by a relative 1e-9 so the comparison stays safe.
        # The "runs" distance (block-corner DTW over runs) is a minimum over a subset of the
        # seed's warping paths, so it is >= the seed's distance and every bound of the seed's
        # distance bounds it too: the range-cover bound serves both modes.
        use_range = s.use_bounds and s.range_bound and s.band is None
        nl = self._layout() if s.use_bounds else None
        exact_sums = rle_is_exact(s.table.F, s.longest + int(packed.lengths.max()))
        rejected = 0
        out_idx = np.full((len(packed), k), -1, np.int64)
        out_dist = np.full((len(packed), k), np.inf)
        stats = SearchStats()
        for qi in range(len(packed)):
            a = packed.sequence(qi)
            if s.use_bounds:  # every clip's bound at once (numpy's summation order: shrunk to stay safe)
                lbs = library_bounds(a, s.vocab, nl["dist_vidx"], lib.dist_cnt, lib.dist_off, nl["first"],
                                     nl["last"], nl["lengths"], s.table)[0] * (1.0 - 1e-9)
            else:
                lbs = np.zeros(len(lib))
            order = np.argsort(lbs, kind="stable")
            best: list[tuple[float, int]] = []
            pruned = 0
            q_runs = packed.run_val[packed.run_off[qi]:packed.run_off[qi + 1]]
            q_lens = packed.run_len[packed.run_off[qi]:packed.run_off[qi + 1]]
            if s.mode == "runs" and exact_sums and s.band is None:
                # many candidates' run-length DPs at once (the per-candidate loop is bound by
                # the cost of its numpy calls): the same k answers, see _runs_batches
                best, pruned = self._runs_batches(q_runs, q_lens, len(a), lbs, order, k)
                order = order[:0]
            for pos, c in enumerate(order):
                thr = best[k - 1][0] if len(best) >= k else np.inf
                if lbs[c] > thr:
                    pruned = len(order) - pos
                    break
                b = lib.sequence(c)
                if use_range and thr < np.inf:
                    c_runs = lib.run_val[lib.run_off[c]:lib.run_off[c + 1]]
                    c_lens = lib.run_len[lib.run_off[c]:lib.run_off[c + 1]]
                    cost = s.table.lookup(q_runs[:, None], c_runs[None, :])
                    rb = max(monotone_cover_numpy(cost, q_lens), monotone_cover_numpy(cost.T, c_lens))
                    if rb * (1.0 - 1e-9) / (len(a) + len(b)) > thr:
                        rejected += 1
                        continue
                if s.mode == "runs":  # sums that may round (exact ones went by batches above)
                    av, al = run_length_encode(a)
                    bv, bl = run_length_encode(b)
                    raw = runs_dtw_numpy(s.table.lookup(av[:, None], bv[None, :]), al, bl)
                else:
                    lo, hi = band_limits(len(a), len(b), s.band)
                    raw = dtw_cost_numpy(s.table.lookup(a[:, None], b[None, :]), lo, hi)
                d = float(raw) / (len(a) + len(b))
                best = sorted(best + [(d, int(c))])[:k]
            for t, (d, c) in enumerate(best):
                out_idx[qi, t], out_dist[qi, t] = c, d
            stats.candidates += len(lib)
            stats.pruned += pruned
            stats.completed += len(lib) - pruned - rejected
            stats.abandoned += rejected
            stats.range_rejected += rejected
            rejected = 0
        return SearchResult(out_idx, out_dist, stats)
