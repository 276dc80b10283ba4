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
