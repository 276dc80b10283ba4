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
final distance; docs/notebook/retrieval-speed.md).

``backend="numpy"`` (Android: no numba) runs the same bounds and pruning with the
vectorised anti-diagonal DP of :mod:`retrieval.dtw.kernels`: same neighbours and distances,
without early abandoning or run-length blocks.

**Where the parts are.** Each compiled kernel sits beside its numpy twin in a module of its
own: the packed library (:mod:`~retrieval.search.packed`), the bounds
(:mod:`~retrieval.search.bounds`; twin :func:`retrieval.dtw.library_bounds`), the visiting
order (:mod:`~retrieval.search.order`), the segment-cover bound
(:mod:`~retrieval.search.segment_bound`), the candidate loop (:mod:`~retrieval.search.cascade`;
twin :mod:`~retrieval.search.numpy_path`), and in :mod:`retrieval.dtw` the DPs it runs (the
exact run-length DP, the block-corner DTW, the row-scan DP, the range-cover bound). This
module is the API on top: :class:`FastSearcher`.
"""
from __future__ import annotations

import time
from typing import Sequence

import numpy as np

from retrieval.codes import DiffTable
from retrieval.dtw import DTWError, resolve_backend, rle_is_exact
from retrieval.dtw.jit import HAVE_NUMBA
from retrieval.search.cascade import SEGMENTS, SEGMENTS_FINE
from retrieval.search.numpy_path import NumpySearch
from retrieval.search.packed import PackedCodes
from retrieval.search.results import SearchResult, SearchStats

if HAVE_NUMBA:  # optional: numba (the kernels exist only where it is installed)
    from retrieval.search.bounds import lbs_cheap, lbs_parallel, query_rows
    from retrieval.search.cascade import refine, search_batch, search_serial

#: "exact": the seed's distance; "runs": the block-corner run-length approximation.
MODES = ("exact", "runs")
#: the stages :meth:`FastSearcher.profile_stages` times, in order
STAGES = ("pack", "rows", "bounds", "loop")
__all__ = ["MODES", "STAGES", "SEGMENTS", "SEGMENTS_FINE", "FastSearcher", "PackedCodes", "SearchResult",
           "SearchStats", "warm_up"]


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
        self.vocab = np.unique(lib.dist_val)  # the codes the library uses

        # what the kernels take: the distinct codes as vocabulary indices (the columns of
        # the query's table rows), plus the run values likewise (LV); the codes as indices
        # only once a search needs the frame-level DP (band, or sums that are not exact)
        arrays = lib.arrays()
        self._L = arrays[:6] + (self.vocab_index(lib.dist_val),) + arrays[7:]
        self._LV = (np.zeros(0, np.int32), self.vocab_index(lib.run_val))
        self.use_bounds = use_bounds
        self.longest = int(self.library.lengths.max())  # frames of the longest clip
        self.run_length = run_length
        self._numpy: NumpySearch | None = None  # the numpy path, made on its first search
        self._shift = 2 * table.low_dims
        self._mask = (1 << self._shift) - 1

    def __len__(self) -> int:
        return len(self.library)

    def vocab_index(self, codes: np.ndarray) -> np.ndarray:
        """Each code's index in :attr:`vocab` (the codes must be the library's)."""
        return np.searchsorted(self.vocab, codes).astype(np.int32)

    @property
    def table_bytes(self) -> int:
        return self.table.nbytes

    @property
    def index_bytes_per_clip(self) -> float:
        extra = sum(a.nbytes for a in self._LV) + self._L[6].nbytes + self.vocab.nbytes
        return (self.library.nbytes + extra) / len(self.library)

    def _kernel(self, longest_query: int) -> int:
        """0: plain DP, 1: exact run-length block DP, 2: block-corner approximation."""
        if self.mode == "runs":
            return 2
        return int(self.run_length and rle_is_exact(self.table.F, self.longest + longest_query))

    def _plan(self, packed: PackedCodes) -> tuple[int, int]:
        """(kernel of :meth:`_kernel`, band or -1) for a batch of queries; the library's codes
        are indexed into the vocabulary once a search first needs the frame-level DP."""
        use_rle = self._kernel(int(packed.lengths.max()))
        band = -1 if self.band is None else int(self.band)
        if (use_rle != 1 or band >= 0) and len(self._LV[0]) == 0:
            self._LV = (self.vocab_index(self.library.codes), self._LV[1])
        return use_rle, band

    def search(self, queries: Sequence[np.ndarray], k: int = 1, parallel: bool = True) -> SearchResult:
        """k nearest library clips for each query code sequence (a batch)."""
        if k < 1:
            raise DTWError(f"k must be >= 1, got {k}")
        packed = PackedCodes.from_sequences(queries, self.table.size)
        if self.backend == "numpy":
            if self._numpy is None:
                self._numpy = NumpySearch(self)
            return self._numpy.search(packed, k)
        nq = len(packed)
        out_idx = np.full((nq, k), -1, np.int64)
        out_dist = np.full((nq, k), np.inf)
        stats = np.zeros((nq, 5), np.int64)
        use_rle, band = self._plan(packed)
        Q, L, LV = packed.arrays(), self._L, self._LV
        t = self.table
        if not parallel and self.use_bounds:  # one thread: all stages in one compiled call
            search_serial(Q, L, LV, self.vocab, t.F, t.absdiff, self._shift, self._mask, k, use_rle, band, out_idx,
                          out_dist, stats, self.range_bound)
        elif nq == 1 or not parallel:
            for qi in range(nq):
                self._search_one(packed, Q, qi, k, use_rle, band, out_idx[qi], out_dist[qi], stats[qi], parallel)
        else:
            if not self.use_bounds:
                raise DTWError("use_bounds=False is only supported for serial searches")
            search_batch(Q, L, LV, self.vocab, t.F, t.absdiff, self._shift, self._mask, k, use_rle, band, out_idx, out_dist, stats,
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
        R, colmin = query_rows(packed.dist_val[packed.dist_off[qi]:packed.dist_off[qi + 1]], self.vocab,
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
            lbs_cheap(qi, Q, self._L, t.F, t.absdiff, self._shift, self._mask, colmin, lbs)
        else:
            lbs_parallel(qi, Q, self._L, t.F, t.absdiff, self._shift, self._mask, RT, colmin, lbs, rowmins)
        t2 = clock()
        refine(qi, Q, self._L, self._LV, t.F, t.absdiff, self._shift, self._mask, R, RT, lbs, rowmins, colmin, k,
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
