"""The DTW core's argument checks and small helpers, through the public API: each bad
argument is a DTWError/QuantizerError whose message says what was wrong (these branches
were only reachable once `pragma: no cover` came off the kernels and scripts/coverage.sh
measured them, issue 17)."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.codes import tables
from retrieval.codes.quantizer import PCA, Quantizer
from retrieval.codes.tables import ComponentTable, DiffTable, SplitTable, code_table, make_table
from retrieval.dtw import (
    HAVE_NUMBA,
    DTWError,
    band_limits,
    dtw_codes,
    dtw_codes_to_many,
    dtw_features,
    dtw_features_to_many,
    find_subsequence,
    rle_is_exact,
)
from retrieval.errors import QuantizerError
from retrieval.search.subsequence import SubsequenceSearcher

RATIOS = np.array([0.5, 0.3, 0.2])


def test_band_limits_checks_and_the_one_row_case():
    with pytest.raises(DTWError, match=r"^band must be >= 0, got -1$"):
        band_limits(4, 6, -1)
    lo, hi = band_limits(1, 6, 2)  # one query frame: every column is reachable
    assert lo.tolist() == [0] and hi.tolist() == [5]


def test_dtw_argument_checks():
    table = make_table(RATIOS, "full")
    with pytest.raises(DTWError, match=r"^table must be square, got \(64, 32\)$"):
        dtw_codes(np.array([1, 2]), np.array([1, 2]), table[:, :32])
    with pytest.raises(DTWError, match=r"^first features must be a non-empty \(frames, dims\) array, got \(0, 3\)$"):
        dtw_features(np.zeros((0, 3)), np.zeros((4, 3)))
    with pytest.raises(DTWError, match=r"features must be a non-empty \(frames, dims\) array, got \(2, 2, 2\)$"):
        dtw_features(np.zeros((4, 3)), np.zeros((2, 2, 2)))


def test_to_many_equals_one_by_one():
    rng = np.random.default_rng(0)
    table = make_table(RATIOS, "full")
    q = rng.integers(0, 64, 9)
    refs = [rng.integers(0, 64, n) for n in (5, 9, 14)]
    np.testing.assert_array_equal(dtw_codes_to_many(q, refs, table), [dtw_codes(q, r, table) for r in refs])
    x = rng.normal(size=(7, 2))
    ys = [rng.normal(size=(n, 2)) for n in (3, 8)]
    np.testing.assert_array_equal(dtw_features_to_many(x, ys, band=2),
                                  [dtw_features(x, y, band=2) for y in ys])
    # 1-D features are one feature per frame
    assert dtw_features(np.arange(5.0), np.arange(5.0)) == 0.0


def test_quantiser_and_table_argument_checks():
    with pytest.raises(QuantizerError, match=r"^PCA needs a \(frames, dims\) array with at least 2 frames, got \(1, 3\)$"):
        PCA.fit(np.zeros((1, 3)))
    with pytest.raises(QuantizerError, match=r"^reference frames must be \(frames, dims\), got \(5,\)$"):
        Quantizer.fit(np.zeros(5), 2)
    with pytest.raises(QuantizerError, match=rf"^number of dimensions must be 1\.\.{tables.MAX_DIMS}, got 0$"):
        code_table(np.array([]))
    with pytest.raises(QuantizerError, match=rf"^number of dimensions must be 1\.\.{tables.MAX_DIMS}, got 0$"):
        tables.difference_table(np.array([]))
    with pytest.raises(QuantizerError, match=r"^unknown table layout 'huge' \(choose from "):
        tables.table_bytes("huge", 3)
    np.testing.assert_array_equal(tables.reference_table(RATIOS), tables.full_table(RATIOS))


def test_table_sizes_are_what_they_hold():
    split = code_table(np.full(tables.MAX_FULL_DIMS + 1, 0.1))
    assert isinstance(split, SplitTable) and split.nbytes == split.low.nbytes + split.high.nbytes
    comp = ComponentTable.from_ratios(RATIOS)
    assert comp.n == 3
    diff = DiffTable.from_ratios(RATIOS)
    assert diff.nbytes > 0


def test_subsequence_argument_checks():
    table = DiffTable.from_ratios(RATIOS)
    with pytest.raises(DTWError, match=r"^query codes must be a non-empty 1-D array, got shape \(0,\)$"):
        find_subsequence(np.array([], dtype=np.int32), np.array([1, 2], dtype=np.int32), table)
    with pytest.raises(DTWError, match=r"^no code sequences to search$"):
        SubsequenceSearcher([], table)
    searcher = SubsequenceSearcher([np.array([1, 2, 3], dtype=np.int32)], table)
    assert len(searcher) == 1
    with pytest.raises(DTWError, match=r"^k must be >= 1, got 0$"):
        searcher.search(np.array([1, 2]), k=0)
    with pytest.raises(DTWError, match=r"^query codes must be a non-empty 1-D array, got shape \(0,\)$"):
        searcher.search(np.array([], dtype=np.int32))


@pytest.mark.skipif(not HAVE_NUMBA, reason="compares with the numba kernel")
def test_numpy_subsequence_keeps_the_kernels_numbers_when_sums_round():
    """A table whose float sums are not exact takes the numpy path's sequential loop
    (not the cumsum scan): it must give the compiled kernel's answer bit for bit."""
    table = DiffTable.from_ratios(np.array([0.9, 0.1, 1e-7]))  # costs from 1e-7 to ~16: sums round
    assert not rle_is_exact(table.F, 60)
    rng = np.random.default_rng(4)
    for _ in range(20):
        q = rng.integers(0, 64, rng.integers(2, 12)).astype(np.int32)
        t = rng.integers(0, 64, rng.integers(5, 40)).astype(np.int32)
        numpy_match = find_subsequence(q, t, table, backend="numpy")
        assert numpy_match == find_subsequence(q, t, table, backend="numba")
    assert numpy_match.as_dict() == {"start": numpy_match.start, "end": numpy_match.end,
                                     "distance": numpy_match.distance, "raw": numpy_match.raw}


def test_fast_searcher_refuses_bad_modes_k_and_unbounded_batches():
    """The fast search's argument checks say what was wrong."""
    from retrieval.search import FastSearcher

    table = DiffTable.from_ratios(RATIOS)
    rng = np.random.default_rng(5)
    lib = [rng.integers(0, table.size, int(rng.integers(3, 12))).astype(np.int32) for _ in range(6)]
    with pytest.raises(DTWError, match="unknown search mode 'bogus'"):
        FastSearcher(lib, table, mode="bogus")
    with pytest.raises(DTWError, match="'runs' mode\\) has no band"):
        FastSearcher(lib, table, mode="runs", band=2)
    searcher = FastSearcher(lib, table)
    assert searcher.table_bytes == table.nbytes
    with pytest.raises(DTWError, match="k must be >= 1, got 0"):
        searcher.search(lib[:1], k=0)
    if HAVE_NUMBA:
        unbounded = FastSearcher(lib, table, use_bounds=False, backend="numba")
        with pytest.raises(DTWError, match="use_bounds=False is only supported for serial searches"):
            unbounded.search(lib[:2], k=1, parallel=True)


def test_numpy_plain_path_without_bounds_and_with_inexact_sums_answers_as_brute_force():
    """The numpy path's plain branch: no bounds at all (every clip's DP runs), and the
    "runs" mode with a table whose sums may round (the anti-diagonal DP, not row scans)."""
    from retrieval.dtw import run_length_encode
    from retrieval.search import FastSearcher
    from retrieval.dtw import runs_dtw_numpy

    table = DiffTable.from_ratios(RATIOS)
    rng = np.random.default_rng(6)
    lib = [rng.integers(0, table.size, int(rng.integers(3, 12))).astype(np.int32) for _ in range(8)]
    q = lib[3]
    got = FastSearcher(lib, table, use_bounds=False, backend="numpy").search([q], k=2)
    ref = FastSearcher(lib, table, backend="numpy").search([q], k=2)
    assert np.array_equal(got.indices, ref.indices) and np.array_equal(got.distances, ref.distances)
    # a table whose costs are not multiples of one unit over these lengths: sums may round
    rough = DiffTable.from_ratios(RATIOS)
    rough.F[1] = np.float32(1e-6)  # a tiny cost beside large ones: float64 sums can round
    long_lib = [np.repeat(s, 400) for s in lib]
    assert not rle_is_exact(rough.F, 2 * max(len(s) for s in long_lib))
    res = FastSearcher(long_lib, rough, mode="runs", backend="numpy").search([long_lib[3]], k=1)
    av, al = run_length_encode(long_lib[3])
    raws = []
    for c in long_lib:
        bv, bl = run_length_encode(c)
        raws.append(runs_dtw_numpy(rough.lookup(av[:, None], bv[None, :]), al, bl) / (len(long_lib[3]) + len(c)))
    assert res.distances[0, 0] == min(raws)


def test_run_length_and_exactness_edge_cases():
    from retrieval.dtw import run_length_encode

    vals, lens = run_length_encode(np.zeros(0, np.int32))
    assert vals.size == 0 and lens.size == 0 and vals.dtype == np.int32 and lens.dtype == np.int64
    assert rle_is_exact(np.zeros(5, np.float32), 10**9)  # all-zero costs: every sum is exact


def test_lb_kim_counts_one_corner_when_both_sequences_are_one_frame():
    from retrieval.dtw import lb_kim

    table = DiffTable.from_ratios(RATIOS)
    a, b = np.array([1], np.int32), np.array([7], np.int32)
    assert lb_kim(a, b, table) == pytest.approx(float(table.lookup(1, 7)) / 2)
    a2, b2 = np.array([1, 2], np.int32), np.array([7, 3], np.int32)
    assert lb_kim(a2, b2, table) == pytest.approx((float(table.lookup(1, 7)) + float(table.lookup(2, 3))) / 4)
