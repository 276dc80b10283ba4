"""The fast search's compiled kernels against their numpy twins, module by module
(issue 30: each compiled kernel sits beside its twin). The searches' end-to-end equality
with the brute force is in test_fast_search.py and test_tablet_search.py; these pin the
kernels themselves."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.codes import DiffTable, full_table
from retrieval.dtw import band_limits, dtw_cost_numpy, dtw_rows_numpy, library_bounds
from retrieval.search import PackedCodes

pytest.importorskip("numba")

RATIOS = np.array([0.4, 0.2, 0.1, 0.05, 0.03, 0.02])


def _codes(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.repeat(rng.integers(0, 4096, n), rng.integers(1, 4, n)).astype(np.int32)


def test_compiled_band_limits_equal_band_limits():
    from retrieval.dtw.kernels import band_limits_nb

    for nx in range(1, 25):
        for ny in range(1, 25):
            for band in (None, 0, 1, 3, 10):
                lo, hi = np.empty(nx, np.int64), np.empty(nx, np.int64)
                band_limits_nb(nx, ny, -1 if band is None else band, lo, hi)
                want = band_limits(nx, ny, band)
                assert np.array_equal(lo, want[0]) and np.array_equal(hi, want[1]), (nx, ny, band)


def test_corridor_dp_equals_the_numpy_dps():
    """plain_dtw_raw (the frame-level DP of the fast search) is the anti-diagonal DP within
    a band and, with bounds of what is still to come, the row-scan DP: the same value within
    the limit, inf once the limit is certainly exceeded."""
    from retrieval.dtw.rowscan import plain_dtw_raw

    table = DiffTable.from_ratios(RATIOS)
    rng = np.random.default_rng(30)
    for _ in range(60):
        a, b = _codes(rng, int(rng.integers(1, 12))), _codes(rng, int(rng.integers(1, 12)))
        vocab = np.unique(b)
        R = table.lookup(a[:, None], vocab[None, :]).astype(np.float32)  # row i: frame i of a
        cost = table.lookup(a[:, None], b[None, :])
        b_v = np.searchsorted(vocab, b)
        rows = np.arange(len(a))
        work = np.empty(len(b) + 2), np.empty(len(b) + 2)
        for band in (None, 2):
            lo, hi = band_limits(len(a), len(b), band)
            zr, zc = np.zeros(len(a)), np.zeros(len(b))
            got = plain_dtw_raw(rows, b_v, R, lo, hi, zr, zc, np.inf, 1.0, *work)
            assert got == dtw_cost_numpy(cost, lo, hi)
        # the envelopes of the rows and columns still to come (exact sums here), a limit
        per_row, per_col = cost.min(axis=1), cost.min(axis=0)
        rest_row = np.cumsum(per_row[::-1])[::-1] - per_row
        rest_col = np.cumsum(per_col[::-1])[::-1] - per_col
        full = dtw_cost_numpy(cost, *band_limits(len(a), len(b), None))
        lo, hi = band_limits(len(a), len(b), None)
        for f in (0.5, 0.9, 1.0, 1.5):
            limit = f * full / (len(a) + len(b))
            got = plain_dtw_raw(rows, b_v, R, lo, hi, rest_row, rest_col, limit, float(len(a) + len(b)), *work)
            scan = dtw_rows_numpy(cost, rest_row, rest_col, limit * (len(a) + len(b)) * (1 + 1e-9))
            if f >= 1.0:
                assert got == full == scan
            else:
                assert got == np.inf or got == full


def test_compiled_bounds_equal_library_bounds():
    """query_rows + lb_pair (the compiled bounds) are library_bounds' numbers, candidate by
    candidate, and envelope_rows gives its rows' minima."""
    from retrieval.search.bounds import lb_pair, query_rows

    table = DiffTable.from_ratios(RATIOS)
    rng = np.random.default_rng(31)
    lib = PackedCodes.from_sequences([_codes(rng, int(rng.integers(1, 15))) for _ in range(40)], table.size)
    vocab = np.unique(lib.dist_val)
    dist_vidx = np.searchsorted(vocab, lib.dist_val)
    shift = 2 * table.low_dims
    mask = (1 << shift) - 1
    for _ in range(10):
        q = PackedCodes.from_sequences([_codes(rng, int(rng.integers(1, 15)))], table.size)
        a = q.sequence(0)
        want, rowmin, _, _, _ = library_bounds(a, vocab, dist_vidx, lib.dist_cnt, lib.dist_off,
                                               lib.codes[lib.code_off[:-1]], lib.codes[lib.code_off[1:] - 1],
                                               lib.lengths, table)
        R, colmin = query_rows(q.dist_val, vocab, table.F, table.absdiff, shift, mask)
        RT = np.ascontiguousarray(R.T)
        row_out = np.empty(len(q.dist_val), np.float32)
        for c in range(len(lib)):
            d0, d1 = lib.dist_off[c], lib.dist_off[c + 1]
            b = lib.sequence(c)
            got = lb_pair(q.dist_cnt, len(a), a[0], a[-1], dist_vidx[d0:d1], lib.dist_cnt[d0:d1], len(b), b[0], b[-1],
                          table.F, table.absdiff, shift, mask, colmin, RT, row_out)
            assert got == pytest.approx(want[c], rel=1e-12, abs=0)
            assert np.array_equal(row_out.astype(np.float64), rowmin[:, c])


@pytest.mark.parametrize("k", [1, 4])
def test_candidate_loop_and_its_numpy_twin_answer_alike(k):
    """The compiled candidate loop (:mod:`retrieval.search.cascade`, every stage in one
    call) and its numpy twin (:class:`retrieval.search.numpy_path.NumpySearch`) over the
    same packed queries: the same clips and distances as the brute force, and the same
    bookkeeping in :class:`retrieval.search.results.SearchStats` (each candidate pruned,
    abandoned or completed exactly once)."""
    from retrieval.search import FastSearcher, brute_force
    from retrieval.search.cascade import search_serial
    from retrieval.search.numpy_path import NumpySearch
    from retrieval.search.results import SearchResult, SearchStats

    table = DiffTable.from_ratios(RATIOS)
    rng = np.random.default_rng(32 + k)
    lib = [_codes(rng, int(rng.integers(2, 30))) for _ in range(50)]
    lib[7] = lib[3].copy()  # a tie the order must break alike
    queries = [_codes(rng, int(rng.integers(2, 30))) for _ in range(6)] + [lib[3]]
    want_idx, want_dist = brute_force(queries, lib, full_table(RATIOS), k=k)
    searcher = FastSearcher(lib, table, backend="numba")
    packed = PackedCodes.from_sequences(queries, table.size)

    twin = NumpySearch(searcher).search(packed, k)
    assert isinstance(twin, SearchResult) and isinstance(twin.stats, SearchStats)
    assert np.array_equal(twin.indices, want_idx) and np.array_equal(twin.distances, want_dist)

    out_idx, out_dist = np.full((len(packed), k), -1, np.int64), np.full((len(packed), k), np.inf)
    stats = np.zeros((len(packed), 5), np.int64)
    use_rle, band = searcher._plan(packed)
    search_serial(packed.arrays(), searcher._L, searcher._LV, searcher.vocab, table.F, table.absdiff,
                  searcher._shift, searcher._mask, k, use_rle, band, out_idx, out_dist, stats, searcher.range_bound)
    assert np.array_equal(out_idx, want_idx) and np.array_equal(out_dist, want_dist)
    compiled = SearchStats()
    for row in stats:
        compiled.add(row)
    for s in (compiled, twin.stats):
        assert s.pruned + s.abandoned + s.completed == s.candidates
