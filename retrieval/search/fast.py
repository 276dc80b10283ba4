"""Exact k-nearest-neighbour search over code sequences, fast.

Same answers as running the seed's look-up DTW (:func:`retrieval.dtw.kernels.dtw_codes`, full
table, no band, normalised by ``len(a) + len(b)``) against every reference and sorting —
same neighbours, same distances bit for bit, ties broken by the lower library index like
``np.argsort(kind="stable")`` — but:

1. **compact table** — the 20 KiB :class:`~retrieval.codes.tables.DiffTable` instead of
   the 64 MiB table (identical values);
2. **lower bounds** (:mod:`retrieval.dtw.lower_bounds`), cascaded cheapest first: LB_Kim
   and the columns' envelope (one load per distinct candidate code) for every candidate;
   the block-corner DTW of the k + 2 candidates with the least of those bounds (taken in
   one pass, not by sorting them all) caps the k-th best distance from above, and every
   candidate whose cheap bound exceeds the cap is *pruned*; the rows' envelope (one load
   per pair of query and candidate codes, read as contiguous transposed rows and folded
   into every query code's minimum at once) only for the candidates within the cap, which
   are then visited in order of the full bound (the cap recomputed from the best k + 2 of
   them), the loop stopping at the first bound above the k-th best. Searching a single
   query over all cores computes all three for every candidate in a ``prange`` and sorts
   by their maximum;
3. **range-cover bound** (:mod:`retrieval.dtw.range_bound`, run-length exact mode) — for a
   candidate that survives its envelope bound, an order-aware bound over runs,
   O(runs × runs): the candidate is rejected without a DTW when it exceeds the k-th best,
   and its backward pass gives the exact DTW a per-(row-run, column-run) "cost still to
   come" that is never below the envelope's (``range_bound=False`` switches it off);
   before it, the **segment-cover bound** (:mod:`retrieval.search.segment_bound`): the same
   bound with the query's runs merged into :data:`SEGMENTS` segments, S × runs cells instead
   of runs × runs, rejects most of those candidates more cheaply (counted as
   ``range_rejected`` too);
   the finer level's segments are cut where the query's codes change most, and a
   segment-cover DP stops once its rows' part alone is past the k-th best;
   **early abandoning** — a DTW stops as soon as its frontier minimum plus the bound of
   the rows still to come exceeds the k-th best;
4. **run-length DTW** (:mod:`retrieval.dtw.runlength`) — exact block DP over runs of equal
   codes, used when :func:`~retrieval.dtw.runlength.rle_is_exact` holds (plain DP otherwise);
5. **parallelism** — a batch of queries runs in a numba ``prange`` (one query per
   thread, each with the cascade); a single query computes its bounds in a ``prange``
   over candidates.

**Visiting order.** Without the segment filter (short queries) the candidates are verified
in envelope order. With it, the search is best-first over bounds refined lazily: the
candidates stream in envelope order; each enters a min-heap keyed by its coarse
segment-cover bound, and an entry popped from the heap is refined to the finer level (and
pushed again) or, once fully refined, verified (range cover, exact DP). A step takes the
stream's next candidate when its envelope bound is below the heap's least key, and the heap's
least otherwise; it stops when the least bound left exceeds the k-th best. Every key is a
lower bound of its candidate's distance (the largest of the bounds computed for it), so no
candidate within the k-th best is skipped, and the candidates are verified in order of their
finest bound, which ranks the nearest clips far better than the envelope does (on the
slowest query of 69 over 33 204 derived clips, the nearest clip is 546th by its envelope
bound and 5th by the finer segment bound). The k-th best distance then falls to its final
value after a few exact DPs, and every later range-cover bound and DP runs under it: on
that query the DPs went from 314 to 105 (the number whose range-cover bound is within the
final distance; docs/retrieval-speed.md).

``backend="numpy"`` (Android: no numba) runs the same bounds and pruning with the
vectorised anti-diagonal DP of :mod:`retrieval.dtw.kernels`: same neighbours and distances,
without early abandoning or run-length blocks.

An optional Sakoe–Chiba ``band`` (as in :func:`retrieval.dtw.kernels.band_limits`) changes the
distance (it is then the banded DTW, not the seed's); the bounds stay valid.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from retrieval.codes import DiffTable
from retrieval.dtw import (
    DTWError,
    band_limits,
    distinct_counts,
    dtw_cost_numpy,
    dtw_rows_numpy,
    library_bounds,
    monotone_cover_numpy,
    resolve_backend,
    rle_is_exact,
    run_length_encode,
)
from retrieval.dtw.jit import HAVE_NUMBA, numba

if HAVE_NUMBA:  # optional: numba (the kernels below exist only where it is installed)
    from retrieval.dtw.range_bound import range_cover_both
    from retrieval.dtw.runlength import diff_cost, rle_dtw_raw
    from retrieval.search.segment_bound import segment_cover_nb, segment_rows, segment_split_adaptive_nb

#: "exact": the seed's distance; "runs": the block-corner run-length approximation.
MODES = ("exact", "runs")
#: query segments of the segment-cover filter (:mod:`retrieval.search.segment_bound`); 0: off.
#: Tried 3, 6, 8, 12, 16, each side by side with the search without the filter on the derived
#: library: 6-12 gained most, 3 and 16 less (docs/retrieval-speed.md)
SEGMENTS = 8
#: a second, finer level of the segment-cover filter for long queries: query runs per
#: segment (0: off), used when it gives at least twice SEGMENTS segments. Measured on the
#: derived libraries, 69 queries, one core, same answers (docs/retrieval-speed.md):
#: 33 204 clips p95 214.8 -> 172.7 ms, total 4 980 -> 4 595 ms; 3 382 clips total 654 ->
#: 593 ms (3 runs per segment about the same, 4 and 6 less, 1 the same as 2). Its segments
#: are cut where the query's codes change most (``segment_split_adaptive``): 33 204 clips
#: p95 about 155 -> 128 ms with the same segment count; 3 runs per segment cut so: 160 ms
SEGMENTS_FINE = 2
#: the stages :meth:`FastSearcher.profile_stages` times, in order
STAGES = ("pack", "rows", "bounds", "loop")


if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True)
    def _pack_one(seq, size):
        """Runs (value, length), each run's index among the distinct codes, and the sorted
        distinct codes with their counts, of one sequence of codes in [0, size) — what
        run_length_encode, distinct_counts and a searchsorted give, in two passes. A code
        outside [0, size) gives empty arrays (the caller raises, naming the range)."""
        n = seq.shape[0]
        nr = 1
        for i in range(n):
            if seq[i] < 0 or seq[i] >= size:
                e = np.empty(0, np.int32)
                f = np.empty(0, np.int64)
                return e, f, f, e, f
            if i > 0 and seq[i] != seq[i - 1]:
                nr += 1
        run_val = np.empty(nr, np.int32)
        run_len = np.empty(nr, np.int64)
        r = 0
        start = 0
        for i in range(1, n + 1):
            if i == n or seq[i] != seq[i - 1]:
                run_val[r] = seq[i - 1]
                run_len[r] = i - start
                start = i
                r += 1
        cnt = np.zeros(size, np.int64)
        nd = 0
        for i in range(n):
            if cnt[seq[i]] == 0:
                nd += 1
            cnt[seq[i]] += 1
        dist_val = np.empty(nd, np.int32)
        dist_cnt = np.empty(nd, np.int64)
        k = 0
        for v in range(size):
            if cnt[v] > 0:
                dist_val[k] = v
                dist_cnt[k] = cnt[v]
                cnt[v] = k  # from here on: the code's index among the distinct codes
                k += 1
        run_didx = np.empty(nr, np.int64)
        for r in range(nr):
            run_didx[r] = cnt[run_val[r]]
        return run_val, run_len, run_didx, dist_val, dist_cnt


@dataclass
class PackedCodes:
    """Many code sequences packed into flat arrays (what the compiled kernels take):
    plain codes, runs (value, length) and distinct codes (value, count), each with
    per-sequence offsets."""

    codes: np.ndarray
    code_off: np.ndarray
    run_val: np.ndarray
    run_len: np.ndarray
    run_off: np.ndarray
    run_didx: np.ndarray  # index of each run's code within its sequence's distinct codes
    dist_val: np.ndarray
    dist_cnt: np.ndarray
    dist_off: np.ndarray

    @classmethod
    def from_sequences(cls, sequences: Sequence[np.ndarray], size: int | None = None) -> "PackedCodes":
        if len(sequences) == 0:
            raise DTWError("no code sequences to search")
        seqs = [np.ascontiguousarray(s, dtype=np.int32) for s in sequences]

        def out_of_range(i: int, s: np.ndarray) -> DTWError:
            return DTWError(f"sequence {i}: codes must lie in [0, {size}), got [{s.min()}, {s.max()}]")

        for i, s in enumerate(seqs):
            if s.ndim != 1 or s.size == 0:
                raise DTWError(f"sequence {i}: codes must be a non-empty 1-D array, got shape {s.shape}")
        if HAVE_NUMBA and size is not None:
            parts = [_pack_one(s, size) for s in seqs]  # one pass each instead of sort + searches; checks the range
            for i, (s, p) in enumerate(zip(seqs, parts)):
                if not len(p[0]):
                    raise out_of_range(i, s)
            if len(seqs) == 1:  # one query (the search's fixed cost): its arrays as they are, no concatenation
                rv, rl, rd, dv, dc = parts[0]
                return cls(seqs[0], np.array([0, len(seqs[0])], np.int64), rv, rl, np.array([0, len(rv)], np.int64),
                           rd, dv, dc, np.array([0, len(dv)], np.int64))
            runs = [(p[0], p[1]) for p in parts]
            didx = [p[2] for p in parts]
            dists = [(p[3], p[4]) for p in parts]
        else:
            for i, s in enumerate(seqs):
                if size is not None and (s.min() < 0 or s.max() >= size):
                    raise out_of_range(i, s)
            runs = [run_length_encode(s) for s in seqs]
            dists = [distinct_counts(s) for s in seqs]
            didx = [np.searchsorted(d[0], r[0]).astype(np.int64) for r, d in zip(runs, dists)]
        off = lambda parts: np.concatenate(([0], np.cumsum([len(p) for p in parts]))).astype(np.int64)  # noqa: E731
        return cls(
            np.concatenate(seqs), off(seqs),
            np.concatenate([r[0] for r in runs]), np.concatenate([r[1] for r in runs]), off([r[0] for r in runs]),
            np.concatenate(didx),
            np.concatenate([d[0] for d in dists]), np.concatenate([d[1] for d in dists]), off([d[0] for d in dists]),
        )

    def __len__(self) -> int:
        return len(self.code_off) - 1

    @property
    def lengths(self) -> np.ndarray:
        return np.diff(self.code_off)

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in (self.codes, self.code_off, self.run_val, self.run_len, self.run_off,
                                            self.run_didx, self.dist_val, self.dist_cnt, self.dist_off)))

    def sequence(self, i: int) -> np.ndarray:
        return self.codes[self.code_off[i]:self.code_off[i + 1]]

    def arrays(self) -> tuple:
        return (self.codes, self.code_off, self.run_val, self.run_len, self.run_off, self.run_didx,
                self.dist_val, self.dist_cnt, self.dist_off)


@dataclass
class SearchStats:
    """How much work the bounds saved: candidates pruned by their bound, DTWs abandoned
    early, DTWs run to the end."""

    candidates: int = 0
    pruned: int = 0
    abandoned: int = 0
    completed: int = 0
    range_rejected: int = 0  # of the abandoned: rejected by the segment- or range-cover bound before the exact DTW

    @property
    def pruned_fraction(self) -> float:
        return self.pruned / self.candidates if self.candidates else 0.0

    @property
    def abandoned_fraction(self) -> float:
        return self.abandoned / self.candidates if self.candidates else 0.0

    def add(self, arr: np.ndarray) -> None:
        self.candidates += int(arr[0])
        self.pruned += int(arr[1])
        self.abandoned += int(arr[2])
        self.completed += int(arr[3])
        if len(arr) > 4:
            self.range_rejected += int(arr[4])

    def as_dict(self) -> dict:
        return {"candidates": self.candidates, "pruned": self.pruned, "abandoned": self.abandoned,
                "completed": self.completed, "range_rejected": self.range_rejected,
                "pruned_fraction": self.pruned_fraction,
                "abandoned_fraction": self.abandoned_fraction}


# --------------------------------------------------------------------------- compiled kernels
if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True)
    def _query_rows(q_dv, vocab, F, absdiff, shift, mask):
        """R[u, t] = D[q_dv[u], vocab[t]] for every code of the library's vocabulary (float32,
        exact: the table's values are float32), and per vocabulary code its cheapest query
        code, colmin[t] = min_u R[u, t]. Columns are vocabulary indices (the library's
        arrays used with R hold them), so a row is as wide as the codes the library uses
        (about a quarter of the 4ⁿ) and stays in cache. After this one pass per query every
        bound costs one load per cell, and a candidate's column envelope costs one load per
        distinct candidate code."""
        nv = vocab.shape[0]
        R = np.empty((q_dv.shape[0], nv), np.float32)
        colmin = np.full(nv, np.inf)
        for u in range(q_dv.shape[0]):
            Ru = R[u]
            ulo = q_dv[u] & mask
            uhi = q_dv[u] >> shift
            for t in range(nv):
                v = vocab[t]
                x = F[np.int64(absdiff[ulo, v & mask]) | (np.int64(absdiff[uhi, v >> shift]) << shift)]
                Ru[t] = x
                d = np.float64(x)
                if d < colmin[t]:
                    colmin[t] = d
        return R, colmin

    @numba.njit(cache=True, nogil=True)
    def _envelope_rows(q_dc, c_dv, RT, row_out):
        """Raw envelope bound of the rows: every query code's cheapest candidate code
        (``row_out[u]``, float32, exact: the table's values are float32) times its count,
        summed in query-code order. ``RT`` (the query's table rows transposed, ``RT[t, u]
        = R[u, t]``) gives one contiguous row per candidate code, folded into the minima
        of every query code at once (a vector minimum)."""
        nq = q_dc.shape[0]
        for u in range(nq):
            row_out[u] = np.float32(np.inf)
        for v in range(c_dv.shape[0]):
            r = RT[c_dv[v]]
            for u in range(nq):
                row_out[u] = min(row_out[u], r[u])
        rows = 0.0
        for u in range(nq):
            rows += np.float64(row_out[u]) * q_dc[u]
        return rows

    @numba.njit(cache=True, nogil=True)
    def _lb_cheap(nx, q_first, q_last, c_dv, c_dc, ny, c_first, c_last, F, absdiff, shift, mask, colmin):
        """Raw max(LB_Kim, envelope columns): one load per distinct candidate code."""
        cols = 0.0
        for v in range(c_dv.shape[0]):
            cols += colmin[c_dv[v]] * c_dc[v]
        kim = diff_cost(q_first, c_first, F, absdiff, shift, mask)
        if nx > 1 or ny > 1:
            kim += diff_cost(q_last, c_last, F, absdiff, shift, mask)
        return cols if cols > kim else kim

    @numba.njit(cache=True, nogil=True)
    def _lb_pair(q_dc, nx, q_first, q_last, c_dv, c_dc, ny, c_first, c_last,
                 F, absdiff, shift, mask, colmin, RT, row_out):
        """Normalised max(LB_Kim, envelope rows, envelope columns): :func:`_envelope_rows`
        (``row_out``: each query code's cheapest candidate code, which the exact search's
        envelopes reuse) and :func:`_lb_cheap`."""
        rows = _envelope_rows(q_dc, c_dv, RT, row_out)
        cheap = _lb_cheap(nx, q_first, q_last, c_dv, c_dc, ny, c_first, c_last, F, absdiff, shift, mask, colmin)
        best = rows if rows > cheap else cheap
        return best / (nx + ny)

    @numba.njit(cache=True, nogil=True)
    def _plain_dtw_raw(a_row, b, R, lo, hi, rest_row, rest_col, limit, norm, prev, cur):
        """Row-by-row look-up DTW with band limits, early abandoning and a pruned corridor
        (cells whose value plus the bound of the rows/columns still to come exceeds the
        limit are dead; a row stops where nothing live can feed it): the numbers of
        :func:`retrieval.dtw.kernels._nb_dtw_table` with the difference table whenever the result
        is within the limit, inf otherwise. ``a_row[i]`` is query frame i's row of ``R``
        (:func:`_query_rows`), so a cell costs one look-up, as in the seed's full table."""
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

    @numba.njit(cache=True, nogil=True)
    def _runs_dtw_raw(a_val, a_len, b_val, b_len, F, absdiff, shift, mask, rest_run, limit, norm, prev, cur):
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

    @numba.njit(cache=True, nogil=True)
    def _band_limits_nb(nx, ny, band, lo, hi):
        """:func:`retrieval.dtw.kernels.band_limits` (band >= 0; band < 0 means none)."""
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

    @numba.njit(cache=True, nogil=True)
    def _lbs_cheap(qi, Q, L, F, absdiff, shift, mask, colmin, out):
        """Normalised :func:`_lb_cheap` of every candidate (the lazy cascade's first stage)."""
        (qc, qco, qrv, qrl, qro, qrd, qdv, qdc, qdo) = Q
        (lc, lco, lrv, lrl, lro, lrd, ldv, ldc, ldo) = L
        a0, a1 = qco[qi], qco[qi + 1]
        for c in range(lco.shape[0] - 1):
            b0, b1 = lco[c], lco[c + 1]
            out[c] = _lb_cheap(a1 - a0, qc[a0], qc[a1 - 1], ldv[ldo[c]:ldo[c + 1]], ldc[ldo[c]:ldo[c + 1]], b1 - b0,
                               lc[b0], lc[b1 - 1], F, absdiff, shift, mask, colmin) / (a1 - a0 + b1 - b0)

    @numba.njit(cache=True, nogil=True, parallel=True)
    def _lbs_parallel(qi, Q, L, F, absdiff, shift, mask, RT, colmin, out, rowmins):
        (qc, qco, qrv, qrl, qro, qrd, qdv, qdc, qdo) = Q
        (lc, lco, lrv, lrl, lro, lrd, ldv, ldc, ldo) = L
        a0, a1 = qco[qi], qco[qi + 1]
        for c in numba.prange(lco.shape[0] - 1):
            b0, b1 = lco[c], lco[c + 1]
            out[c] = _lb_pair(qdc[qdo[qi]:qdo[qi + 1]], a1 - a0, qc[a0], qc[a1 - 1],
                              ldv[ldo[c]:ldo[c + 1]], ldc[ldo[c]:ldo[c + 1]], b1 - b0, lc[b0], lc[b1 - 1],
                              F, absdiff, shift, mask, colmin, RT, rowmins[c])

    @numba.njit(cache=True, nogil=True)
    def _segment_bounds(nruns, nseg):
        """Run boundaries of ``nseg`` segments of near-equal run counts (the compiled
        :func:`retrieval.search.segment_bound.segment_split`, ``nseg <= nruns``)."""
        b = np.empty(nseg + 1, np.int64)
        for s in range(nseg + 1):
            b[s] = (s * nruns + nseg // 2) // nseg
        return b

    @numba.njit(cache=True, nogil=True)
    def _block_corner_cap(cands, k, q_val, q_len, nx, L, F, absdiff, shift, mask, row_prev, row_next):
        """The k-th smallest normalised block-corner DTW of the first ``k + 2`` of ``cands``
        (at least ``k`` of them): each is an upper bound of that candidate's exact distance
        (exact mode, exact arithmetic), so this bounds the k-th best distance from above."""
        (lc, lco, lrv, lrl, lro, lrd, ldv, ldc, ldo) = L
        m_ub = k + 2 if k + 2 < cands.shape[0] else cands.shape[0]
        ubs = np.empty(m_ub)
        for pos in range(m_ub):
            c = cands[pos]
            ubs[pos] = _runs_dtw_raw(q_val, q_len, lrv[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]], F, absdiff, shift,
                                     mask, np.zeros(q_val.shape[0]), np.inf, 1.0,
                                     row_prev, row_next) / float(nx + lco[c + 1] - lco[c])
        ubs.sort()
        return ubs[k - 1]

    @numba.njit(cache=True, nogil=True)
    def _heap_less(hk, hp, i, j):
        """Heap order: the smaller key, ties to the earlier position (deterministic)."""
        return hk[i] < hk[j] or (hk[i] == hk[j] and hp[i] < hp[j])

    @numba.njit(cache=True, nogil=True)
    def _heap_swap(hk, hp, hl, i, j):
        hk[i], hk[j] = hk[j], hk[i]
        hp[i], hp[j] = hp[j], hp[i]
        hl[i], hl[j] = hl[j], hl[i]

    @numba.njit(cache=True, nogil=True)
    def _heap_push(hk, hp, hl, n, key, p, lvl):
        """Add (key, position, level) to the binary min-heap of ``n`` entries; returns n + 1."""
        hk[n], hp[n], hl[n] = key, p, lvl
        i = n
        while i > 0:
            up = (i - 1) >> 1
            if not _heap_less(hk, hp, i, up):
                break
            _heap_swap(hk, hp, hl, i, up)
            i = up
        return n + 1

    @numba.njit(cache=True, nogil=True)
    def _heap_pop(hk, hp, hl, n):
        """Drop the least entry of the heap of ``n`` entries; returns n − 1."""
        n -= 1
        if n > 0:
            hk[0], hp[0], hl[0] = hk[n], hp[n], hl[n]
            i = 0
            while True:
                lft = 2 * i + 1
                if lft >= n:
                    break
                m = lft
                if lft + 1 < n and _heap_less(hk, hp, lft + 1, lft):
                    m = lft + 1
                if not _heap_less(hk, hp, m, i):
                    break
                _heap_swap(hk, hp, hl, i, m)
                i = m
        return n

    @numba.njit(cache=True, nogil=True)
    def _least_first(values, m):
        """Indices of the ``m`` least ``values`` (all of them if fewer), in increasing order
        of (value, index) — the first ``m`` of a stable argsort, in one pass."""
        n = values.shape[0]
        m = m if m < n else n
        out = np.empty(m, np.int64)
        got = 0
        for i in range(n):
            v = values[i]
            if got == m and not v < values[out[m - 1]]:
                continue
            j = got if got < m else m - 1  # where it goes: shift the larger ones right
            while j > 0 and v < values[out[j - 1]]:
                out[j] = out[j - 1]
                j -= 1
            out[j] = i
            if got < m:
                got += 1
        return out

    @numba.njit(cache=True, nogil=True)
    def _segment_key(Rs, H, c, L, lrv_v, nx, thr, floor, mx_buf, my_buf):
        """Candidate ``c``'s heap key at a segment level: its normalised segment-cover bound
        (the DP stops past ``thr``), raised to ``floor`` (a bound already known for it: the
        larger of two lower bounds is one)."""
        lco, lrl, lro = L[1], L[3], L[4]
        norm = float(nx + lco[c + 1] - lco[c])
        sb = segment_cover_nb(Rs, H, lrv_v[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]], mx_buf, my_buf,
                              thr * norm) / norm
        return sb if sb > floor else floor

    @numba.njit(cache=True, nogil=True)
    def _refine(qi, Q, L, LV, F, absdiff, shift, mask, R, RT, lbs, rowmins, colmin, k, use_rle, band, out_idx,
                out_dist, stats, abandon, range_bound, lazy):
        """Candidates in bound order (best-first over refined bounds when the segment filter
        is in use, module docstring): prune, DTW with early abandoning, keep the k best
        (distance, then index). Writes out_idx/out_dist (k) and stats (5). ``LV``: the
        library's codes and run values as vocabulary indices (columns of ``R``)."""
        (qc, qco, qrv, qrl, qro, qrd, qdv, qdc, qdo) = Q
        (lc, lco, lrv, lrl, lro, lrd, ldv, ldc, ldo) = L
        (lc_v, lrv_v) = LV
        inf = np.inf
        ncand = lco.shape[0] - 1
        a0, a1 = qco[qi], qco[qi + 1]
        nx = a1 - a0
        r0, r1 = qro[qi], qro[qi + 1]
        nruns = r1 - r0
        for t in range(k):
            out_idx[t] = -1
            out_dist[t] = inf
        # the lazy cascade needs only the k + 2 least cheap bounds in order (for the first
        # cap), not all of them sorted: sorting 3 382 bounds took about a sixth of a median query
        order = _least_first(lbs, k + 2) if lazy else np.argsort(lbs, kind="mergesort")
        maxlen = 1
        for c in range(ncand):
            if lco[c + 1] - lco[c] > maxlen:
                maxlen = lco[c + 1] - lco[c]
        big = maxlen
        if nx > big:
            big = nx
        row_prev = np.empty(big + 2)
        row_next = np.empty(big + 2)
        left = np.empty(big + 2)
        right = np.empty(big + 2)
        buf_a = np.empty(big + 2)
        buf_b = np.empty(big + 2)
        dq = np.empty(big + 2, np.int64)
        lo = np.empty(nx, np.int64)
        hi = np.empty(nx, np.int64)
        rest_run = np.empty(nruns)
        rest_row = np.empty(nx)
        row_didx = np.empty(nx, np.int64)  # query frame -> its distinct-code row of R
        i = 0
        for p in range(nruns):
            for t in range(qrl[r0 + p]):
                row_didx[i] = qrd[r0 + p]
                i += 1
        rest_col = np.empty(big + 2)
        # without exact arithmetic the bound sums may round differently from the DP: shrink them
        safety = 1.0 if use_rle >= 1 else 1.0 - 1e-9
        pruned = 0
        abandoned = 0
        completed = 0
        range_rejected = 0
        # range-cover bound (retrieval.range_bound): work arrays
        use_range = range_bound and use_rle == 1 and band < 0
        maxruns = 1
        for c in range(ncand):
            if lro[c + 1] - lro[c] > maxruns:
                maxruns = lro[c + 1] - lro[c]
        wide = maxruns if maxruns > nruns else nruns
        rest2_buf = np.empty(nruns * maxruns)
        before = np.empty(nruns)
        mx_buf = np.empty(wide)  # range_cover_both's work rows
        my_buf = np.empty(wide)
        cp_buf = np.empty(wide)
        # segment-cover filter (retrieval.search.segment_bound): the query's runs in a few segments
        nseg = SEGMENTS if SEGMENTS < nruns else nruns
        use_seg = use_range and SEGMENTS > 0 and nseg < nruns
        seg_b = _segment_bounds(nruns, nseg)  # cut evenly: cutting where the codes change gained nothing here
        Rs = np.empty((nseg, R.shape[1]), np.float32)
        seg_h = np.empty(nseg, np.int64)
        if use_seg:
            segment_rows(R, qrd[r0:r1], qrl[r0:r1], seg_b, Rs, seg_h)
        # the second, finer level for long queries: SEGMENTS_FINE runs per segment, cut
        # where the query's codes change most (retrieval.search.segment_bound, "Where to cut")
        nseg2 = nruns // SEGMENTS_FINE if SEGMENTS_FINE > 0 else 0
        use_seg2 = use_seg and nseg2 >= 2 * nseg and nseg2 <= nruns
        if not use_seg2:
            nseg2 = 1
        seg_b2 = _segment_bounds(nruns, nseg2) if not use_seg2 else segment_split_adaptive_nb(
            qrv[r0:r1], qrl[r0:r1], nseg2, F, absdiff, shift, mask)
        Rs2 = np.empty((nseg2, R.shape[1]), np.float32)
        seg_h2 = np.empty(nseg2, np.int64)
        if use_seg2:
            segment_rows(R, qrd[r0:r1], qrl[r0:r1], seg_b2, Rs2, seg_h2)
        # Exact mode with exact arithmetic: the block-corner DTW of a few best-bound
        # candidates is an upper bound of their exact distance, so its k-th smallest value
        # bounds the k-th best distance from above before any exact DTW has run.
        cap = inf
        if use_rle == 1 and band < 0 and ncand >= k:
            cap = _block_corner_cap(order, k, qrv[r0:r1], qrl[r0:r1], nx, L, F, absdiff, shift, mask, row_prev, row_next)
        if not abandon:
            cap = inf
        n_loop = ncand
        loop_order = order
        loop_lb = np.empty(0)
        sel_rm = np.empty((0, 0), np.float32)
        if lazy:
            # the cascade's second stage: lbs holds max(LB_Kim, columns); the rows' envelope
            # only for the candidates whose cheap bound is within the cap (the others
            # cannot enter the k best), then those in order of the full bound
            nqd = qdo[qi + 1] - qdo[qi]
            within = np.nonzero(lbs <= cap)[0]  # in index order
            n_loop = within.shape[0]
            pruned += ncand - n_loop
            full = np.empty(n_loop)
            rows_sel = np.empty((n_loop, nqd), np.float32)
            for s in range(n_loop):
                c = within[s]
                r = _envelope_rows(qdc[qdo[qi]:qdo[qi + 1]], ldv[ldo[c]:ldo[c + 1]], RT, rows_sel[s])
                r /= float(nx + lco[c + 1] - lco[c])
                full[s] = r if r > lbs[c] else lbs[c]
            sub = np.argsort(full, kind="mergesort")
            loop_order = within[sub]
            loop_lb = full[sub]
            sel_rm = rows_sel[sub]
            # the cap again from the best candidates by the full bound (usually nearer)
            if cap < inf and n_loop >= k:
                cap = min(cap, _block_corner_cap(loop_order, k, qrv[r0:r1], qrl[r0:r1], nx, L, F, absdiff, shift,
                                                 mask, row_prev, row_next))
        # Best-first over bounds refined lazily (module docstring, "Visiting order"): a
        # candidate enters a heap keyed by its segment-cover bound (coarse, then fine)
        # when the next envelope bound in the stream is no lower than the heap's least
        # key; the heap's least is verified (range cover, exact DP) once it is fully
        # refined. Without the segment filter: envelope order, as before.
        best_first = use_seg and abandon
        hk = np.empty(n_loop + 1 if best_first else 1)  # heap: key (a raw bound / norm)
        hp = np.empty(hk.shape[0], np.int64)  # position in loop_order
        hl = np.empty(hk.shape[0], np.int64)  # level of the key: 1 coarse, 2 fine
        nh = 0
        pos = 0
        while True:
            thr = out_dist[k - 1]
            if cap < thr:
                thr = cap
            if not abandon:
                thr = inf  # brute force: every DTW runs to the end
            nxt_lb = inf
            if pos < n_loop:
                nxt_lb = loop_lb[pos] if lazy else lbs[loop_order[pos]]
            if nh == 0 or nxt_lb < hk[0]:
                # the stream's next candidate
                if pos >= n_loop:
                    break
                if nxt_lb > thr:
                    pruned += n_loop - pos
                    pos = n_loop
                    if nh == 0:
                        break
                    continue
                vpos = pos
                pos += 1
                c = loop_order[vpos]
                level = 1 if best_first else 0  # 0: verify now (envelope order)
                floor = nxt_lb
            else:
                # the heap's least bound
                floor, vpos, lvl = hk[0], hp[0], hl[0]
                if floor > thr:  # so is every other bound left: all rejected
                    abandoned += nh
                    range_rejected += nh
                    pruned += n_loop - pos
                    break
                nh = _heap_pop(hk, hp, hl, nh)
                c = loop_order[vpos]
                level = 2 if (lvl == 1 and use_seg2) else 0  # 0: fully refined, verify
            if level > 0:  # refine: the segment-cover bound of this level, back into the heap
                sb = _segment_key(Rs if level == 1 else Rs2, seg_h if level == 1 else seg_h2, c, L, lrv_v, nx, thr,
                                  floor, mx_buf, my_buf)
                if sb > thr:
                    abandoned += 1
                    range_rejected += 1
                else:
                    nh = _heap_push(hk, hp, hl, nh, sb, vpos, level)
                continue
            # verify candidate c: range-cover bound, then the exact DP
            b0, b1 = lco[c], lco[c + 1]
            ny = b1 - b0
            norm = float(nx + ny)
            # per distinct query code: its cheapest code in this candidate
            rm = sel_rm[vpos] if lazy else rowmins[c]
            if not use_range:  # the envelope of the rows still to come, per run
                acc = 0.0
                for p in range(nruns - 1, -1, -1):
                    rest_run[p] = acc * safety
                    acc += rm[qrd[r0 + p]] * qrl[r0 + p]
            kyc = lro[c + 1] - lro[c]
            rest2 = rest2_buf[:nruns * kyc].reshape((nruns, kyc))
            if use_range:
                # order-aware bounds and "cost still to come" (retrieval.range_bound)
                acc = 0.0
                for p in range(nruns):
                    before[p] = acc
                    acc += rm[qrd[r0 + p]] * qrl[r0 + p]
                lb_raw = range_cover_both(R, qrd[r0:r1], qrl[r0:r1], lrv_v[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]],
                                          before, thr, norm, rest2, mx_buf, my_buf, cp_buf)
                if lb_raw == inf or lb_raw / norm > thr:
                    abandoned += 1
                    range_rejected += 1
                    continue
            else:
                for p in range(nruns):
                    for q in range(kyc):
                        rest2[p, q] = rest_run[p]
            if not (use_rle == 2 and band < 0):
                # the envelope of the columns still to come, per frame (for the frame-level
                # corridors; only survivors need it)
                acc = 0.0
                j = ny - 1
                for p in range(lro[c + 1] - lro[c] - 1, -1, -1):
                    per = colmin[lrv_v[lro[c] + p]]  # the run's cheapest query code
                    for s in range(lrl[lro[c] + p]):
                        rest_col[j] = acc * safety
                        acc += per
                        j -= 1
            if use_rle == 2 and band < 0:
                raw = _runs_dtw_raw(qrv[r0:r1], qrl[r0:r1], lrv[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]],
                                    F, absdiff, shift, mask, rest_run, thr, norm, row_prev, row_next)
            elif use_rle == 1 and band < 0:
                raw = rle_dtw_raw(qrv[r0:r1], qrl[r0:r1], lrv[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]],
                                  F, absdiff, shift, mask, rest2, rest_col, thr, norm,
                                  row_prev, row_next, left, right, buf_a, buf_b, dq)
            else:
                i = nx - 1
                for p in range(nruns - 1, -1, -1):
                    per = rm[qrd[r0 + p]]
                    acc = rest_run[p]
                    for s in range(qrl[r0 + p]):
                        rest_row[i] = acc * safety
                        acc += per
                        i -= 1
                _band_limits_nb(nx, ny, band, lo, hi)
                raw = _plain_dtw_raw(row_didx, lc_v[b0:b1], R, lo, hi, rest_row, rest_col, thr, norm,
                                     row_prev, row_next)
            if raw == inf:
                abandoned += 1
                continue
            completed += 1
            d = raw / norm
            kth = out_dist[k - 1]
            if d < kth or (d == kth and c < out_idx[k - 1]):
                t = k - 1
                while t > 0 and (out_dist[t - 1] > d or (out_dist[t - 1] == d and out_idx[t - 1] > c)):
                    out_dist[t] = out_dist[t - 1]
                    out_idx[t] = out_idx[t - 1]
                    t -= 1
                out_dist[t] = d
                out_idx[t] = c
        stats[0] = ncand
        stats[1] = pruned
        stats[2] = abandoned
        stats[3] = completed
        stats[4] = range_rejected

    @numba.njit(cache=True, nogil=True)
    def _search_query(qi, Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats,
                      range_bound):
        """Every stage for query ``qi``: its table rows, every candidate's bounds, the
        candidate loop (writes row ``qi`` of the outputs)."""
        ncand = L[1].shape[0] - 1
        lbs = np.empty(ncand)
        R, colmin = _query_rows(Q[6][Q[8][qi]:Q[8][qi + 1]], vocab, F, absdiff, shift, mask)
        _lbs_cheap(qi, Q, L, F, absdiff, shift, mask, colmin, lbs)
        _refine(qi, Q, L, LV, F, absdiff, shift, mask, R, np.ascontiguousarray(R.T), lbs,
                np.empty((0, 0), np.float32), colmin, k, use_rle, band, out_idx[qi], out_dist[qi], stats[qi], True,
                range_bound, True)

    @numba.njit(cache=True, nogil=True, parallel=True)
    def _search_batch(Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats, range_bound):
        for qi in numba.prange(Q[1].shape[0] - 1):
            _search_query(qi, Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats,
                          range_bound)

    @numba.njit(cache=True, nogil=True)
    def _search_serial(Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats, range_bound):
        """:func:`_search_batch` on one thread: every stage of every query in one compiled
        call (a single query's search crosses into compiled code once, not three times —
        each crossing unpacks some thirty arrays)."""
        for qi in range(Q[1].shape[0] - 1):
            _search_query(qi, Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats,
                          range_bound)


# --------------------------------------------------------------------------- public API
@dataclass
class SearchResult:
    """k nearest library indices and their normalised DTW distances per query."""

    indices: np.ndarray  # (queries, k) int64, -1 where the library has fewer than k clips
    distances: np.ndarray  # (queries, k) float64
    stats: SearchStats = field(default_factory=SearchStats)


class FastSearcher:
    """Exact k-NN look-up-DTW search over a library of code sequences.

    ``table`` is the :class:`~retrieval.codes.tables.DiffTable` of the quantiser's
    contribution ratios; ``band=None`` gives the seed's (unconstrained) distance.
    ``run_length=False``, ``use_bounds=False`` and ``range_bound=False`` switch those ideas
    off (ablations; without bounds there is no pruning and no early abandoning either:
    brute force over the difference table; the range-cover bound needs the exact
    run-length DP, so it is used only with ``run_length`` and no band).
    """

    def __init__(self, library: Sequence[np.ndarray], table: DiffTable, band: int | None = None,
                 backend: str = "auto", run_length: bool = True, use_bounds: bool = True,
                 mode: str = "exact", range_bound: bool = True):
        if band is not None and band < 0:
            raise DTWError(f"band must be >= 0, got {band}")
        if mode not in MODES:
            raise DTWError(f"unknown search mode {mode!r} (choose from {', '.join(MODES)})")
        if mode == "runs" and band is not None:
            raise DTWError("the run-length approximation ('runs' mode) has no band")
        self.mode = mode
        self.range_bound = bool(range_bound)
        self.table = table
        self.band = band
        self.backend = resolve_backend(backend)
        self.library = PackedCodes.from_sequences(library, table.size)
        lib = self.library
        self._vocab = np.unique(lib.dist_val)  # the codes the library uses

        # what the kernels take: the distinct codes as vocabulary indices (the columns of
        # the query's table rows), plus the run values likewise (LV); the codes as indices
        # only once a search needs the frame-level DP (band, or sums that are not exact)
        arrays = lib.arrays()
        self._L = arrays[:6] + (self._vocab_index(lib.dist_val),) + arrays[7:]
        self._LV = (np.zeros(0, np.int32), self._vocab_index(lib.run_val))
        self.use_bounds = use_bounds
        longest = int(self.library.lengths.max())
        self._longest = longest
        self.run_length = run_length
        self._np_lib: dict | None = None
        self._shift = 2 * table.low_dims
        self._mask = (1 << self._shift) - 1

    def __len__(self) -> int:
        return len(self.library)

    def _vocab_index(self, codes: np.ndarray) -> np.ndarray:
        return np.searchsorted(self._vocab, codes).astype(np.int32)

    @property
    def table_bytes(self) -> int:
        return self.table.nbytes

    @property
    def index_bytes_per_clip(self) -> float:
        extra = sum(a.nbytes for a in self._LV) + self._L[6].nbytes + self._vocab.nbytes
        return (self.library.nbytes + extra) / len(self.library)

    def _kernel(self, longest_query: int) -> int:
        """0: plain DP, 1: exact run-length block DP, 2: block-corner approximation."""
        if self.mode == "runs":
            return 2
        return int(self.run_length and rle_is_exact(self.table.F, self._longest + longest_query))

    def _plan(self, packed: PackedCodes) -> tuple[int, int]:
        """(kernel of :meth:`_kernel`, band or -1) for a batch of queries; the library's codes
        are indexed into the vocabulary once a search first needs the frame-level DP."""
        use_rle = self._kernel(int(packed.lengths.max()))
        band = -1 if self.band is None else int(self.band)
        if (use_rle != 1 or band >= 0) and len(self._LV[0]) == 0:
            self._LV = (self._vocab_index(self.library.codes), self._LV[1])
        return use_rle, band

    def search(self, queries: Sequence[np.ndarray], k: int = 1, parallel: bool = True) -> SearchResult:
        """k nearest library clips for each query code sequence (a batch)."""
        if k < 1:
            raise DTWError(f"k must be >= 1, got {k}")
        packed = PackedCodes.from_sequences(queries, self.table.size)
        if self.backend == "numpy":
            return self._search_numpy(packed, k)
        nq = len(packed)
        out_idx = np.full((nq, k), -1, np.int64)
        out_dist = np.full((nq, k), np.inf)
        stats = np.zeros((nq, 5), np.int64)
        use_rle, band = self._plan(packed)
        Q, L, LV = packed.arrays(), self._L, self._LV
        t = self.table
        if not parallel and self.use_bounds:  # one thread: all stages in one compiled call
            _search_serial(Q, L, LV, self._vocab, t.F, t.absdiff, self._shift, self._mask, k, use_rle, band, out_idx,
                           out_dist, stats, self.range_bound)
        elif nq == 1 or not parallel:
            for qi in range(nq):
                self._search_one(packed, Q, qi, k, use_rle, band, out_idx[qi], out_dist[qi], stats[qi], parallel)
        else:
            if not self.use_bounds:
                raise DTWError("use_bounds=False is only supported for serial searches")
            _search_batch(Q, L, LV, self._vocab, t.F, t.absdiff, self._shift, self._mask, k, use_rle, band, out_idx, out_dist, stats,
                          self.range_bound)
        res = SearchResult(out_idx, out_dist)
        for row in stats:
            res.stats.add(row)
        return res

    def _search_one(self, packed: PackedCodes, Q: tuple, qi: int, k: int, use_rle: int, band: int,
                    out_idx: np.ndarray, out_dist: np.ndarray, stats: np.ndarray, parallel: bool,
                    times: dict[str, float] | None = None) -> None:
        """One query through the compiled kernels: its table rows, the bounds (on one
        thread the cascade's cheap bounds of every candidate; over all cores all three in
        a ``prange``), then the candidate loop (bound order or best-first, segment- and
        range-cover rejection, early-abandoning DP). With ``times``, each stage's seconds
        are added to it under :data:`STAGES` (``rows``, ``bounds``, ``loop``)."""
        t = self.table
        clock = time.perf_counter
        t0 = clock()
        R, colmin = _query_rows(packed.dist_val[packed.dist_off[qi]:packed.dist_off[qi + 1]], self._vocab,
                                t.F, t.absdiff, self._shift, self._mask)
        t1 = clock()
        lbs = np.empty(len(self.library))
        RT = np.ascontiguousarray(R.T)
        lazy = self.use_bounds and not parallel  # one thread: the lazy cascade, as the serial search
        nqd = packed.dist_off[qi + 1] - packed.dist_off[qi]
        rowmins = np.empty((0 if lazy else len(self.library), nqd), np.float32)
        if not self.use_bounds:
            lbs[:] = 0.0
            rowmins[:] = 0.0  # no limit, so nothing is cut: the envelopes' values do not matter
        elif lazy:
            _lbs_cheap(qi, Q, self._L, t.F, t.absdiff, self._shift, self._mask, colmin, lbs)
        else:
            _lbs_parallel(qi, Q, self._L, t.F, t.absdiff, self._shift, self._mask, RT, colmin, lbs, rowmins)
        t2 = clock()
        _refine(qi, Q, self._L, self._LV, t.F, t.absdiff, self._shift, self._mask, R, RT, lbs, rowmins, colmin, k,
                use_rle, band, out_idx, out_dist, stats, self.use_bounds, self.range_bound, lazy)
        if times is not None:
            t3 = clock()
            for key, dt in (("rows", t1 - t0), ("bounds", t2 - t1), ("loop", t3 - t2)):
                times[key] = times.get(key, 0.0) + dt

    def profile_stages(self, query: np.ndarray, k: int = 1) -> tuple[SearchResult, dict[str, float]]:
        """Search one query serially on the compiled path with each stage timed:
        ``(result, {"pack", "rows", "bounds", "loop"} seconds)`` -- packing the query, its
        table rows, the cheap bounds of every candidate (LB_Kim and the columns' envelope),
        the candidate loop (with the rows' envelope of the candidates within the cap,
        module docstring). The answer is the same as :meth:`search`'s. Needs the numba
        back-end (the numpy path has other stages)."""
        if self.backend != "numba":
            raise DTWError("profile_stages times the compiled kernels: it needs the numba back-end")
        if k < 1:
            raise DTWError(f"k must be >= 1, got {k}")
        t0 = time.perf_counter()
        packed = PackedCodes.from_sequences([query], self.table.size)
        times = {"pack": time.perf_counter() - t0}
        out_idx = np.full((1, k), -1, np.int64)
        out_dist = np.full((1, k), np.inf)
        stats = np.zeros((1, 5), np.int64)
        use_rle, band = self._plan(packed)
        self._search_one(packed, packed.arrays(), 0, k, use_rle, band, out_idx[0], out_dist[0], stats[0], False, times)
        res = SearchResult(out_idx, out_dist)
        res.stats.add(stats[0])
        return res, times

    # ------------------------------------------------------------------ numpy path
    def _numpy_library(self) -> dict:
        """What the tablet's vectorised bounds take (built on the first numpy search)."""
        if self._np_lib is None:
            lib = self.library
            self._np_lib = {"dist_vidx": self._vocab_index(lib.dist_val).astype(np.int64),
                            "first": lib.codes[lib.code_off[:-1]], "last": lib.codes[lib.code_off[1:] - 1],
                            "lengths": lib.lengths, "codes_vidx": self._vocab_index(lib.codes).astype(np.int64),
                            "runs_vidx": self._vocab_index(lib.run_val).astype(np.int64)}
        return self._np_lib

    def _search_numpy(self, packed: PackedCodes, k: int) -> SearchResult:
        """The tablet's path. For the seed's distance with exact sums (the usual case) every
        bound is computed for the whole library at once (:func:`retrieval.dtw.library_bounds`)
        and each surviving candidate's DP runs row by row as min-plus scans with early
        abandoning and a corridor (:func:`retrieval.dtw.dtw_rows_numpy`) — the same bounds,
        order and pruning as the compiled path, the same answers bit for bit. Otherwise
        (band, "runs" mode, inexact sums) :meth:`_search_numpy_plain`."""
        longest = int(packed.lengths.max())
        if not (self.mode == "exact" and self.band is None and self.use_bounds
                and rle_is_exact(self.table.F, self._longest + longest)):
            return self._search_numpy_plain(packed, k)
        lib = self.library
        nl = self._numpy_library()
        shrink = 1.0 - 1e-9  # bound sums in numpy's order: keep every comparison on the safe side
        out_idx = np.full((len(packed), k), -1, np.int64)
        out_dist = np.full((len(packed), k), np.inf)
        stats = SearchStats()
        for qi in range(len(packed)):
            a = packed.sequence(qi)
            nx = len(a)
            lbs, rowmin, colmin, a_didx, R = library_bounds(a, self._vocab, nl["dist_vidx"], lib.dist_cnt,
                                                            lib.dist_off, nl["first"], nl["last"], nl["lengths"],
                                                            self.table)
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
                if self.range_bound:
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

    def _runs_batches_numpy(self, q_runs: np.ndarray, q_lens: np.ndarray, q_frames: int, lbs: np.ndarray,
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
        lib = self.library
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
                raw = runs_dtw_rows_batch_numpy(self.table, q_runs, q_lens, runs, thr * frames)
                best = sorted(best + [(float(r) / f, int(c)) for r, f, c in zip(raw, frames, batch)])[:k]
            pos += cut
            if cut < size:  # pruned by bound, or the end of the order
                return best, len(order) - pos
            size *= 2
        return best, 0

    def _search_numpy_plain(self, packed: PackedCodes, k: int) -> SearchResult:
        """The numpy path for a band, the \"runs\" mode or sums that may round: per-candidate
        bounds and the anti-diagonal DP of :mod:`retrieval.dtw.kernels`."""

        lib = self.library
        # the range-cover bound (rows and columns, each a vectorised monotone-choice DP
        # per run) rejects most candidates that pass the envelope before their DP runs; it
        # needs the seed's unconstrained distance. Its sums may round differently from the
        # DP's: shrink it by a relative 1e-9 so the comparison stays safe.
        # The "runs" distance (block-corner DTW over runs) is a minimum over a subset of the
        # seed's warping paths, so it is >= the seed's distance and every bound of the seed's
        # distance bounds it too: the range-cover bound serves both modes.
        use_range = self.use_bounds and self.range_bound and self.band is None
        nl = self._numpy_library() if self.use_bounds else None
        exact_sums = rle_is_exact(self.table.F, self._longest + int(packed.lengths.max()))
        rejected = 0
        out_idx = np.full((len(packed), k), -1, np.int64)
        out_dist = np.full((len(packed), k), np.inf)
        stats = SearchStats()
        for qi in range(len(packed)):
            a = packed.sequence(qi)
            if self.use_bounds:  # every clip's bound at once (numpy's summation order: shrunk to stay safe)
                lbs = library_bounds(a, self._vocab, nl["dist_vidx"], lib.dist_cnt, lib.dist_off, nl["first"],
                                     nl["last"], nl["lengths"], self.table)[0] * (1.0 - 1e-9)
            else:
                lbs = np.zeros(len(lib))
            order = np.argsort(lbs, kind="stable")
            best: list[tuple[float, int]] = []
            pruned = 0
            q_runs = packed.run_val[packed.run_off[qi]:packed.run_off[qi + 1]]
            q_lens = packed.run_len[packed.run_off[qi]:packed.run_off[qi + 1]]
            if self.mode == "runs" and exact_sums and self.band is None:
                # many candidates' run-length DPs at once (the per-candidate loop is bound by
                # the cost of its numpy calls): the same k answers, see _runs_batches_numpy
                best, pruned = self._runs_batches_numpy(q_runs, q_lens, len(a), lbs, order, k)
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
                    cost = self.table.lookup(q_runs[:, None], c_runs[None, :])
                    rb = max(monotone_cover_numpy(cost, q_lens), monotone_cover_numpy(cost.T, c_lens))
                    if rb * (1.0 - 1e-9) / (len(a) + len(b)) > thr:
                        rejected += 1
                        continue
                if self.mode == "runs":  # sums that may round (exact ones went by batches above)
                    av, al = run_length_encode(a)
                    bv, bl = run_length_encode(b)
                    raw = runs_dtw_numpy(self.table.lookup(av[:, None], bv[None, :]), al, bl)
                else:
                    lo, hi = band_limits(len(a), len(b), self.band)
                    raw = dtw_cost_numpy(self.table.lookup(a[:, None], b[None, :]), lo, hi)
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


def runs_dtw_numpy(cost: np.ndarray, a_len: np.ndarray, b_len: np.ndarray) -> float:
    """The ``"runs"`` block-corner DTW (see ``_runs_dtw_raw``) over a (runs × runs) block
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


def runs_dtw_rows_batch_numpy(table, q_runs: np.ndarray, q_lens: np.ndarray,
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
    """The ``"runs"`` block-corner DTW (``_runs_dtw_raw``) one query run (row) at a time,
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


def warm_up() -> None:
    """Compile/load every fast-search kernel once, outside any timing."""
    rng = np.random.default_rng(0)
    table = DiffTable.from_ratios(np.array([0.4, 0.2, 0.1, 0.05, 0.03, 0.02]))
    lib = [np.repeat(rng.integers(0, 4096, 6), 3).astype(np.int32) for _ in range(4)]
    for mode in ("exact", "runs"):
        for rl in (True, False):
            s = FastSearcher(lib, table, mode=mode, run_length=rl)
            s.search(lib[:1], parallel=False)
            FastSearcher(lib, table, mode=mode, run_length=rl, range_bound=False).search(lib[:1], parallel=False)
            s.search(lib[:1], parallel=True)
            s.search(lib[:2], parallel=True)
    FastSearcher(lib, table, band=2).search(lib[:1], parallel=False)
