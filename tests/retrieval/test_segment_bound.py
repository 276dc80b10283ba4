"""Segment-cover bound (retrieval.search.segment_bound): below the seed's DTW on random and
real codes, equal to the row range-cover bound with one run per segment, compiled = numpy,
and the search that uses it as a filter still returns the seed's answers."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.codes import DiffTable, Quantizer, full_table
from retrieval.dtw import dtw_codes
from retrieval.dtw.range_bound import monotone_cover_numpy
from retrieval.dtw.runlength import run_length_decode, run_length_encode
from retrieval.search import FastSearcher, brute_force
from retrieval.search.segment_bound import segment_cover_numpy, segment_split, segment_split_adaptive


def _slow_codes(rng: np.random.Generator, max_runs: int = 30, max_run: int = 8) -> np.ndarray:
    k = int(rng.integers(1, max_runs))
    vals = rng.integers(0, 4096, k) if rng.random() < 0.4 else rng.integers(0, 24, k) * 37 % 4096
    return run_length_decode(vals, rng.integers(1, max_run + 1, k))


def _segment_costs(a: np.ndarray, b: np.ndarray, table: DiffTable, n_seg: int, adaptive: bool = False):
    """(C, segment heights, candidate run widths), straight from the definition; the
    query's runs cut evenly, or where its codes change (``adaptive``)."""
    av, al = run_length_encode(a)
    bv, bl = run_length_encode(b)
    cost = table.lookup(av[:, None], bv[None, :]).astype(np.float64)
    bounds = segment_split_adaptive(av, al, n_seg, table) if adaptive else segment_split(len(av), n_seg)
    C = np.array([cost[bounds[s]:bounds[s + 1]].min(axis=0) for s in range(len(bounds) - 1)])
    H = np.array([al[bounds[s]:bounds[s + 1]].sum() for s in range(len(bounds) - 1)])
    return C, H, bl, bounds, av, al


def _compiled_inputs(a: np.ndarray, b: np.ndarray, table: DiffTable, n_seg: int):
    """What the compiled kernels take, built with the compiled ``segment_rows``: (C, H, W of
    the definition, Rs, its heights, the candidate's runs as vocabulary indices, their
    widths)."""
    from retrieval.search.segment_bound import segment_rows
    C, H, W, bounds, av, al = _segment_costs(a, b, table, n_seg)
    vocab = np.unique(np.concatenate([a, b]))
    qd, q_rows = np.unique(av, return_inverse=True)
    R = table.lookup(qd[:, None], vocab[None, :]).astype(np.float32)
    Rs = np.empty((len(bounds) - 1, len(vocab)), np.float32)
    Hs = np.empty(len(bounds) - 1, np.int64)
    segment_rows(R, q_rows.astype(np.int64), al, bounds, Rs, Hs)
    bv, bl = run_length_encode(b)
    return C, H, W, Rs, Hs, np.searchsorted(vocab, bv).astype(np.int32), bl


@pytest.fixture(scope="module")
def tables():
    c = np.sort(np.random.default_rng(3).dirichlet(np.ones(17)))[::-1][:6]
    return full_table(c), DiffTable.from_ratios(c)


def test_segments_split_runs_evenly_and_cover_all():
    for n_runs in range(1, 40):
        for n_seg in range(1, 12):
            b = segment_split(n_runs, n_seg)
            assert b[0] == 0 and b[-1] == n_runs and len(b) == min(n_runs, n_seg) + 1
            assert np.all(np.diff(b) >= 1) and np.diff(b).max() - np.diff(b).min() <= 1


def test_compiled_segment_split_equals_numpy():
    pytest.importorskip("numba")
    from retrieval.search.segment_bound import segment_bounds_nb
    for n_runs in range(1, 70):
        for n_seg in range(1, n_runs + 1):
            assert np.array_equal(segment_bounds_nb(n_runs, n_seg), segment_split(n_runs, n_seg))


def test_segment_cover_is_below_the_dtw_and_equals_range_cover_with_one_run_each(tables):
    full, diff = tables
    rng = np.random.default_rng(21)
    positive = 0
    for _ in range(300):
        a, b = _slow_codes(rng), _slow_codes(rng)
        raw = dtw_codes(a, b, full, normalize=False)
        for n_seg in (1, 2, 3, 6, 100):
            C, H, W, _, av, al = _segment_costs(a, b, diff, n_seg)
            sb = segment_cover_numpy(C, H, W)
            assert sb <= raw
            positive += sb > 0
        C1, H1, W1, _, av, al = _segment_costs(a, b, diff, len(a))  # one run per segment
        cost = diff.lookup(av[:, None], run_length_encode(b)[0][None, :])
        assert segment_cover_numpy(C1, H1, W1) == max(monotone_cover_numpy(cost, al),
                                                      monotone_cover_numpy(cost.T, W1))
    assert positive > 100  # the inequality is not vacuous


def test_compiled_segment_cover_equals_numpy(tables):
    pytest.importorskip("numba")
    from retrieval.search.segment_bound import segment_cover_nb
    _, diff = tables
    rng = np.random.default_rng(22)
    for _ in range(200):
        a, b = _slow_codes(rng), _slow_codes(rng)
        C, H, W, Rs, Hs, cv, bl = _compiled_inputs(a, b, diff, int(rng.integers(1, 9)))
        work = np.empty(len(bl) + 2)
        got = segment_cover_nb(Rs, Hs, cv, bl, work, np.empty_like(work))
        assert np.array_equal(Hs, H)
        assert got == segment_cover_numpy(C, H, W)


def test_search_with_the_segment_filter_equals_brute_force_on_long_queries(tables):
    full, diff = tables
    rng = np.random.default_rng(23)
    lib = [_slow_codes(rng, max_runs=60, max_run=10) for _ in range(90)]
    lib[7] = lib[3].copy()  # a tie
    qs = [_slow_codes(rng, max_runs=60, max_run=10) for _ in range(10)] + [lib[3], lib[50][2:-2]]
    # queries long enough for the finer second level (SEGMENTS_FINE runs per segment)
    from retrieval.search.fast import SEGMENTS, SEGMENTS_FINE
    assert sum(len(run_length_encode(q)[0]) // SEGMENTS_FINE >= 2 * SEGMENTS for q in qs) >= 3
    for k in (1, 3):
        idx, dist = brute_force(qs, lib, full, k=k)
        res = FastSearcher(lib, diff).search(qs, k=k, parallel=False)
        assert np.array_equal(res.indices, idx) and np.array_equal(res.distances, dist)


def test_segment_cover_and_search_on_real_cmu_clips(cmu_dir):
    from lab.experiment import stack_frames, stratified_subset
    from retrieval.library import load_dataset, read_labels

    clips = stratified_subset(load_dataset(cmu_dir, fps=30, rows=read_labels(cmu_dir)), 24, seed=4)
    q = Quantizer.fit(stack_frames([c.features for c in clips[6:]]), 6)
    diff, full = DiffTable.from_ratios(q.ratios), q.table()
    codes = [q.encode(c.features)[:400] for c in clips]
    queries, lib = codes[:6], codes[6:]
    for a in queries:
        for b in lib:
            raw = dtw_codes(a, b, full, normalize=False)
            for n_seg in (2, 8):
                C, H, W, *_ = _segment_costs(a, b, diff, n_seg)
                assert segment_cover_numpy(C, H, W) <= raw
    idx, dist = brute_force(queries, lib, full, k=2)
    res = FastSearcher(lib, diff).search(queries, k=2, parallel=False)
    assert np.array_equal(res.indices, idx) and np.array_equal(res.distances, dist)


# --------------------------------------------------------------------- where to cut, early exit
def test_adaptive_split_covers_every_run_with_the_asked_number_of_segments(tables):
    _, diff = tables
    rng = np.random.default_rng(31)
    for _ in range(60):
        av, al = run_length_encode(_slow_codes(rng, max_runs=50))
        for n_seg in (1, 2, 5, 8, 40, 200):
            b = segment_split_adaptive(av, al, n_seg, diff)
            assert b[0] == 0 and b[-1] == len(av) and len(b) == min(len(av), n_seg) + 1
            assert np.all(np.diff(b) >= 1)


def test_adaptive_split_cuts_where_the_codes_change(tables):
    """Two stretches of near-equal codes (one component one level apart) far from each
    other: two segments split them where they meet, whatever their lengths."""
    _, diff = tables
    near_a = [0, 1, 0, 1, 0]  # codes 0 and 1 differ in one component by one level
    far_b = [4095, 4094, 4095]
    av = np.array(near_a + far_b)
    for heights in (np.ones(8, np.int64), np.array([9, 1, 1, 1, 1, 1, 1, 9])):
        assert list(segment_split_adaptive(av, heights, 2, diff)) == [0, 5, 8]
    assert list(segment_split(8, 2)) == [0, 4, 8]  # the even split cuts inside the first stretch


def test_compiled_adaptive_split_equals_numpy(tables):
    pytest.importorskip("numba")
    from retrieval.search.segment_bound import segment_split_adaptive_nb
    _, diff = tables
    shift = 2 * diff.low_dims
    rng = np.random.default_rng(32)
    for _ in range(150):
        av, al = run_length_encode(_slow_codes(rng, max_runs=60))
        if rng.random() < 0.3:
            av = av % 7  # few distinct codes: many equal merge costs, ties to the leftmost pair
        for n_seg in (1, 3, 8, max(1, len(av) // 2)):
            got = segment_split_adaptive_nb(av.astype(np.int32), al.astype(np.int64), n_seg, diff.F, diff.absdiff,
                                            shift, (1 << shift) - 1)
            assert np.array_equal(got, segment_split_adaptive(av, al, n_seg, diff))


def test_adaptive_segments_give_a_bound_below_the_dtw_and_usually_tighter(tables):
    full, diff = tables
    rng = np.random.default_rng(33)
    even_sum = adaptive_sum = 0.0
    for _ in range(200):
        a, b = _slow_codes(rng, max_runs=40), _slow_codes(rng)
        raw = dtw_codes(a, b, full, normalize=False)
        n_seg = max(1, len(run_length_encode(a)[0]) // 3)
        even = segment_cover_numpy(*_segment_costs(a, b, diff, n_seg)[:3])
        adaptive = segment_cover_numpy(*_segment_costs(a, b, diff, n_seg, adaptive=True)[:3])
        assert even <= raw and adaptive <= raw
        even_sum += even
        adaptive_sum += adaptive
    assert adaptive_sum > even_sum


def test_segment_cover_early_exit_returns_a_lower_bound_above_the_limit(tables):
    pytest.importorskip("numba")
    from retrieval.search.segment_bound import segment_cover_nb
    _, diff = tables
    rng = np.random.default_rng(34)
    exits = 0
    for _ in range(200):
        a, b = _slow_codes(rng), _slow_codes(rng)
        C, H, W, Rs, Hs, cv, bl = _compiled_inputs(a, b, diff, int(rng.integers(1, 12)))
        work = np.empty(len(bl) + 2), np.empty(len(bl) + 2)
        whole = segment_cover_nb(Rs, Hs, cv, bl, *work)
        assert whole == segment_cover_numpy(C, H, W)
        limit = whole * rng.uniform(0.0, 1.2)
        got = segment_cover_nb(Rs, Hs, cv, bl, *work, limit)
        if limit >= whole:
            assert got == whole  # no exit: the whole bound
        else:
            assert got <= whole  # a lower bound all the same
            if got != whole:
                assert got > limit  # it exits only once past the limit
                exits += 1
    assert exits > 20  # the early exit is exercised


def test_best_first_order_verifies_the_nearest_clip_before_its_look_alikes(tables):
    """Clips with the query's codes, first and last frames in a shuffled order have the
    same envelope bound as the query's own clip (zero), which sorts last among them; the
    segment-cover bounds tell them apart, so the search verifies the query's clip first and
    rejects every look-alike by its bound: one exact DP (module docstring of
    retrieval.search.fast, "Visiting order"). In envelope order every look-alike before it
    would reach the range-cover bound, and some the DP."""
    full, diff = tables
    rng = np.random.default_rng(35)
    vals = rng.choice(4096, 40, replace=False)
    query = run_length_decode(vals, rng.integers(2, 5, 40))
    lib = []
    for _ in range(60):
        mid = vals[1:-1].copy()
        rng.shuffle(mid)
        lib.append(run_length_decode(np.concatenate([vals[:1], mid, vals[-1:]]), rng.integers(2, 5, 40)))
    lib.append(run_length_decode(vals, rng.integers(2, 5, 40)))  # the same motion, other timing
    res = FastSearcher(lib, diff).search([query], k=1, parallel=False)
    idx, dist = brute_force([query], lib, full, k=1)
    assert np.array_equal(res.indices, idx) and np.array_equal(res.distances, dist)
    assert res.indices[0, 0] == len(lib) - 1
    st = res.stats
    exact_dps = st.completed + st.abandoned - st.range_rejected
    assert st.pruned == 0 and exact_dps == 1
