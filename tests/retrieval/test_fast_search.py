"""Fast exact retrieval: compact tables, lower bounds, run-length DTW, pruned k-NN search.

Every test compares against the seed's own pieces (full table, :func:`retrieval.dtw.kernels.dtw_codes`)
computed independently, so a wrong optimisation fails here.
"""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.codes import DiffTable, component_lookup, component_table, difference_table, table_bytes
from retrieval.dtw import dtw_codes
from retrieval.errors import StoryBeamError
from retrieval.search import STAGES, FastSearcher, PackedCodes, brute_force, brute_force_runs
from retrieval.dtw import envelope_sums, lb_kim, lower_bound
from retrieval.codes import Quantizer, full_table
from retrieval.dtw.range_bound import monotone_cover_numpy, range_cover_both, range_cover_numpy, range_lower_bound
from retrieval.dtw.runlength import rle_dtw_numpy, rle_dtw_raw, rle_is_exact, run_length_decode, run_length_encode


def _ratios(n: int, seed: int) -> np.ndarray:
    return np.sort(np.random.default_rng(seed).dirichlet(np.ones(17)))[::-1][:n]


def _slow_codes(rng: np.random.Generator, max_runs: int = 25, alphabet: int = 4096, max_run: int = 6) -> np.ndarray:
    """Codes that change slowly (runs), from a small or the full alphabet."""
    k = int(rng.integers(1, max_runs))
    vals = rng.integers(0, alphabet, k) if rng.random() < 0.4 else rng.integers(0, 24, k) * 37 % alphabet
    return run_length_decode(vals, rng.integers(1, max_run + 1, k))


@pytest.fixture(scope="module")
def tables():
    c = _ratios(6, 3)
    return c, full_table(c), DiffTable.from_ratios(c)


# ------------------------------------------------------------------ compact tables
def test_difference_table_equals_the_full_table_exactly_at_n6(tables):
    c, full, diff = tables
    codes = np.arange(4**6)
    for start in range(0, 4**6, 512):  # every one of the 16.7 M pairs, bit for bit
        block = diff.lookup(codes[start:start + 512, None], codes[None, :])
        assert np.array_equal(block, full[start:start + 512].astype(np.float64))
    assert diff.nbytes <= 64 * 1024
    assert diff.nbytes == table_bytes("diff", 6) == 20480


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 7])
def test_compact_layouts_equal_the_full_table_for_other_n(n):
    c = _ratios(n, n)
    diff = DiffTable.from_ratios(c)
    rng = np.random.default_rng(n)
    a = rng.integers(0, 4**n, 4000)
    b = rng.integers(0, 4**n, 4000)
    if n <= 5:
        full = full_table(c)
        ref = full[a, b].astype(np.float64)
        assert np.array_equal(difference_table(c), full[0])
    else:  # 4^7 square is 1 GiB: check against the seed's defining sum, rounded like full_table
        g = lambda x: (x[:, None] >> (2 * np.arange(n))) & 3  # noqa: E731
        w = np.array([0.0, 1.0, 4.0, 16.0])[np.abs(g(a) - g(b))]
        acc = np.zeros(len(a))
        for i in range(n):
            acc = c[i] * w[:, i] + acc
        ref = acc.astype(np.float32).astype(np.float64)
    assert np.array_equal(diff.lookup(a, b), ref)
    assert np.array_equal(component_lookup(component_table(c), a, b), ref)


# ------------------------------------------------------------------ lower bounds
def test_lower_bounds_never_exceed_the_normalised_dtw(tables):
    _, full, diff = tables
    rng = np.random.default_rng(11)
    gaps = []
    for _ in range(250):
        a, b = _slow_codes(rng), _slow_codes(rng)
        d = dtw_codes(a, b, full)
        for lb in (lb_kim(a, b, diff), lower_bound(a, b, diff)):
            assert lb <= d, (a, b, lb, d)
        rows, cols = envelope_sums(a, b, diff)
        assert max(rows, cols) <= dtw_codes(a, b, full, normalize=False)
        gaps.append(d - lower_bound(a, b, diff))
    assert max(gaps) > 0  # the bound is not trivially the distance itself
    assert np.mean([g == 0 for g in gaps]) < 0.5


def test_lower_bounds_stay_valid_under_a_band(tables):
    _, full, diff = tables
    rng = np.random.default_rng(12)
    for _ in range(200):
        a, b = _slow_codes(rng), _slow_codes(rng)
        assert lower_bound(a, b, diff) <= dtw_codes(a, b, full, band=int(rng.integers(0, 6)))


# ------------------------------------------------------------------ run-length DTW
def _work(nx: int, ny: int):
    m = max(nx, ny) + 2
    return (np.empty(ny + 1), np.empty(ny + 1), np.empty(m), np.empty(m), np.empty(m), np.empty(m),
            np.empty(m, np.int64))


def test_run_length_block_dtw_is_bit_identical_to_the_seed_dtw(tables):
    _, full, diff = tables
    assert rle_is_exact(diff.F, 100_000)
    rng = np.random.default_rng(5)
    for _ in range(400):
        a, b = _slow_codes(rng, max_run=int(rng.choice([1, 3, 20]))), _slow_codes(rng)
        av, al = run_length_encode(a)
        bv, bl = run_length_encode(b)
        raw = rle_dtw_raw(av, al, bv, bl, diff.F, diff.absdiff, 6, 63, np.zeros((len(av), len(bv))), np.zeros(len(b)),
                          np.inf, 1.0, *_work(len(a), len(b)))
        ref = dtw_codes(a, b, full, normalize=False, backend="numba")
        assert raw == ref
        assert rle_dtw_numpy(av, al, bv, bl, diff.lookup(av[:, None], bv[None, :])) == ref


# ------------------------------------------------------------------ range-cover bound
def _range_parts(a, b, diff):
    av, al = run_length_encode(a)
    bv, bl = run_length_encode(b)
    return diff.lookup(av[:, None], bv[None, :]), al, bl


def _fused(a, b, diff, before=None, limit=np.inf, norm=1.0):
    """range_cover_both of two code sequences (what the search runs): (raw value, rest2)."""
    av, al = run_length_encode(a)
    bv, bl = run_length_encode(b)
    distinct, row_of = np.unique(av, return_inverse=True)
    R = diff.lookup(distinct[:, None], np.arange(diff.size)[None, :]).astype(np.float32)  # vocabulary = all codes
    rest2 = np.empty((len(al), len(bl)))
    before = np.zeros(len(al)) if before is None else before
    value = range_cover_both(R, row_of.astype(np.int64), al, bv, bl, before, limit, norm, rest2,
                             *(np.empty(len(bl)) for _ in range(3)))
    return value, rest2


def _rows_suffix_numpy(cost: np.ndarray, al: np.ndarray) -> np.ndarray:
    """The rows-only monotone-choice cost-to-go: out[p, e] = min over choices for the runs
    after p that start at candidate run >= e (0 after the last run)."""
    out = np.zeros(cost.shape)
    B = np.zeros(cost.shape[1])
    for p in range(cost.shape[0] - 1, -1, -1):
        out[p] = B
        B = np.minimum.accumulate((al[p] * cost[p] + B)[::-1])[::-1]
    return out


def test_range_bound_never_exceeds_the_dtw_and_is_tighter_than_the_envelope(tables):
    _, full, diff = tables
    rng = np.random.default_rng(41)
    tighter = 0
    for _ in range(300):
        a, b = _slow_codes(rng, max_runs=int(rng.choice([3, 25, 40]))), _slow_codes(rng)
        d = dtw_codes(a, b, full)
        lb = range_lower_bound(a, b, diff)
        assert lb <= d, (a, b, lb, d)
        assert lb >= max(envelope_sums(a, b, diff)) / (len(a) + len(b))  # never looser than the envelope
        tighter += lb > lower_bound(a, b, diff)
        # the compiled search kernel is never below the plain row and column bounds
        cost, al, bl = _range_parts(a, b, diff)
        assert _fused(a, b, diff)[0] >= max(range_cover_numpy(cost, al), range_cover_numpy(cost.T, bl)) - 1e-12
    assert tighter > 100  # it does see the order: often strictly above the envelope bound


def test_range_bound_on_quantised_real_features(tables):
    """Codes from a real quantiser (smooth 17-D walk, long runs like motion at 120 fps)."""
    rng = np.random.default_rng(43)
    walk = np.cumsum(rng.normal(size=(6000, 17)), axis=0) * 0.05
    q = Quantizer.fit(walk, 6)
    diff, full = DiffTable.from_ratios(q.ratios), q.table()
    for _ in range(60):
        s1, s2 = rng.integers(0, 5800, 2)
        a = q.encode(walk[s1:s1 + int(rng.integers(40, 200))])
        b = q.encode(walk[s2:s2 + int(rng.integers(40, 200))])
        assert range_lower_bound(a, b, diff) <= dtw_codes(a, b, full)


def test_range_cost_to_go_is_never_below_the_envelope_suffix(tables):
    _, _, diff = tables
    rng = np.random.default_rng(47)
    for _ in range(60):
        a, b = _slow_codes(rng, max_runs=10), _slow_codes(rng, max_runs=10)
        cost, al, bl = _range_parts(a, b, diff)
        rest2 = _fused(a, b, diff)[1]
        env = cost.min(axis=1) * al
        suffix = np.concatenate((np.cumsum(env[::-1])[::-1][1:], [0.0]))
        assert np.all(rest2 >= suffix[:, None])


def test_monotone_choice_dp_equals_the_range_cover_definition():
    """The O(P·Q) monotone-choice DP is the range-cover bound of the definition (O(P·Q²))."""
    rng = np.random.default_rng(53)
    for _ in range(400):
        P, Q = rng.integers(1, 9, 2)
        cost = rng.integers(0, 6, (P, Q)) * rng.random()
        h = rng.integers(1, 6, P)
        assert monotone_cover_numpy(cost, h) == pytest.approx(range_cover_numpy(cost, h), abs=1e-12)
        rest = _rows_suffix_numpy(cost, h)  # and its cost-to-go is the definition's on what is left
        p, e = rng.integers(0, P), rng.integers(0, Q)
        want = range_cover_numpy(cost[p + 1:, e:], h[p + 1:]) if p + 1 < P else 0.0
        assert rest[p, e] == pytest.approx(want, abs=1e-12)


def _cost_after_cells(cost: np.ndarray, al: np.ndarray, bl: np.ndarray) -> np.ndarray:
    """Per block (p, q): the least exact cost of what follows any of its cells on a path
    to the end (the cell itself excluded), by brute force on the expanded grid."""
    full = np.repeat(np.repeat(cost, al, axis=0), bl, axis=1)
    nx, ny = full.shape
    back = np.full((nx + 1, ny + 1), np.inf)
    back[nx - 1, ny - 1] = full[nx - 1, ny - 1]
    for i in range(nx - 1, -1, -1):
        for j in range(ny - 1, -1, -1):
            if (i, j) != (nx - 1, ny - 1):
                back[i, j] = full[i, j] + min(back[i + 1, j], back[i, j + 1], back[i + 1, j + 1])
    after = back[:nx, :ny] - full
    rows, cols = np.repeat(np.arange(len(al)), al), np.repeat(np.arange(len(bl)), bl)
    out = np.full((len(al), len(bl)), np.inf)
    np.minimum.at(out, (rows[:, None], cols[None, :]), after)
    return out


def test_fused_range_bounds_match_the_references_and_bound_what_follows(tables):
    """range_cover_both (what the search runs): its value lies between the larger of the
    plain row and column bounds and the DTW, and its "still to come" per block never exceeds
    the true cost after any of the block's cells — so the exact DP's corridor never cuts a
    path within the limit."""
    _, full, diff = tables
    rng = np.random.default_rng(55)
    sharper = 0
    higher = 0
    abandoned = 0
    for n in range(200):
        # lengths alike and very different (where the two sides' parts matter most)
        a, b = _slow_codes(rng, max_runs=8), _slow_codes(rng, max_runs=3 if n % 3 == 0 else 8)
        av, al = run_length_encode(a)
        bv, bl = run_length_encode(b)
        cost = diff.lookup(av[:, None], bv[None, :])
        distinct, row_of = np.unique(av, return_inverse=True)
        R = diff.lookup(distinct[:, None], np.arange(diff.size)[None, :]).astype(np.float32)
        rest2 = np.empty((len(al), len(bl)))
        work = tuple(np.empty(len(bl)) for _ in range(3))
        q_rows = row_of.astype(np.int64)
        both = range_cover_both(R, q_rows, al, bv, bl, np.zeros(len(al)), np.inf, 1.0, rest2, *work)
        plain = max(range_cover_numpy(cost, al), range_cover_numpy(cost.T, bl))
        norm = float(len(a) + len(b))
        exact = dtw_codes(a, b, full)
        assert both >= plain - 1e-12
        assert both <= exact * norm * (1 + 1e-12)
        higher += both > plain
        # abandoning with the envelope of the rows before each run: never when the DTW is
        # within the limit; often when the limit is well below the bound
        before = np.concatenate(([0.0], np.cumsum(cost.min(axis=1) * al)[:-1]))
        scratch = np.empty_like(rest2)
        within = range_cover_both(R, q_rows, al, bv, bl, before, exact, norm, scratch, *work)
        assert within != np.inf and within / norm <= exact
        below = range_cover_both(R, q_rows, al, bv, bl, before, 0.5 * plain / norm, norm, scratch, *work)
        abandoned += below == np.inf
        truth = _cost_after_cells(cost, al, bl)
        assert np.all(rest2 <= truth + 1e-9), (a, b)
        rows_only = _rows_suffix_numpy(cost, al)
        assert np.all(rest2 >= rows_only - 1e-12)
        sharper += np.any(rest2 > rows_only)
    assert sharper > 20  # the columns' part does tighten the corridor
    assert higher > 5  # and each side's part sharpens the other's bound
    assert abandoned > 100  # a limit below the bound is noticed (the bound is rarely 0)


def test_range_bound_abandons_only_above_the_limit(tables):
    _, full, diff = tables
    rng = np.random.default_rng(49)
    for _ in range(200):
        a, b = _slow_codes(rng), _slow_codes(rng)
        cost, al, bl = _range_parts(a, b, diff)
        norm = float(len(a) + len(b))
        exact = dtw_codes(a, b, full)
        before = np.concatenate(([0.0], np.cumsum(cost.min(axis=1) * al)[:-1]))
        for limit in (exact, exact * 0.9, exact * 1.1):
            r = _fused(a, b, diff, before, limit, norm)[0]
            if limit >= exact:  # the exact DTW is within the limit: never abandoned, never above it
                assert r != np.inf and r / norm <= limit


def test_search_with_and_without_the_range_bound_equals_brute_force(tables):
    _, full, diff = tables
    rng = np.random.default_rng(51)
    lib = [_slow_codes(rng, max_runs=40, max_run=12) for _ in range(80)]
    lib[9] = lib[2].copy()  # a tie
    qs = [_slow_codes(rng, max_runs=40, max_run=12) for _ in range(12)] + [lib[2], lib[40][3:-3]]
    rejected = 0
    for k in (1, 3):
        idx, dist = brute_force(qs, lib, full, k=k)
        for rb in (True, False):
            res = FastSearcher(lib, diff, range_bound=rb).search(qs, k=k, parallel=False)
            assert np.array_equal(res.indices, idx) and np.array_equal(res.distances, dist)
            if rb:
                rejected += res.stats.range_rejected
            else:
                assert res.stats.range_rejected == 0
        batch = FastSearcher(lib, diff).search(qs, k=k, parallel=True)
        assert np.array_equal(batch.indices, idx) and np.array_equal(batch.distances, dist)
    assert rejected > 0  # the bound did work here (the equalities above are not vacuous)


def test_profiled_search_gives_the_search_answer_and_times_every_stage(tables):
    pytest.importorskip("numba")
    _, full, diff = tables
    rng = np.random.default_rng(52)
    lib = [_slow_codes(rng, max_runs=40, max_run=12) for _ in range(60)]
    searcher = FastSearcher(lib, diff, backend="numba")
    for q in [_slow_codes(rng, max_runs=40, max_run=12) for _ in range(5)]:
        want = searcher.search([q], k=3, parallel=False)
        got, times = searcher.profile_stages(q, k=3)
        assert np.array_equal(got.indices, want.indices) and np.array_equal(got.distances, want.distances)
        assert got.stats.candidates == want.stats.candidates == len(lib)
        assert set(times) == set(STAGES) and all(t >= 0.0 for t in times.values())
    with pytest.raises(StoryBeamError, match="numba"):
        FastSearcher(lib, diff, backend="numpy").profile_stages(lib[0])


def test_range_bound_and_search_on_real_cmu_clips(cmu_dir):
    """Real motion codes (shared CMU clips, 30 fps): the bound stays below the seed's DTW
    for every pair, and the search with it returns the seed's neighbours and distances."""
    from retrieval.library import load_dataset, read_labels
    from lab.experiment import stratified_subset
    from lab.experiment import stack_frames

    clips = stratified_subset(load_dataset(cmu_dir, fps=30, rows=read_labels(cmu_dir)), 24, seed=2)
    q = Quantizer.fit(stack_frames([c.features for c in clips[6:]]), 6)
    diff, full = DiffTable.from_ratios(q.ratios), q.table()
    codes = [q.encode(c.features)[:400] for c in clips]
    queries, lib = codes[:6], codes[6:]
    for a in queries:
        for b in lib:
            assert range_lower_bound(a, b, diff) <= dtw_codes(a, b, full)
    idx, dist = brute_force(queries, lib, full, k=2)
    res = FastSearcher(lib, diff).search(queries, k=2, parallel=False)
    assert np.array_equal(res.indices, idx) and np.array_equal(res.distances, dist)


def test_run_length_encoding_round_trips():
    c = np.array([5, 5, 5, 2, 2, 7, 5, 5], dtype=np.int32)
    v, n = run_length_encode(c)
    assert v.tolist() == [5, 2, 7, 5] and n.tolist() == [3, 2, 1, 2]
    assert np.array_equal(run_length_decode(v, n), c)


def test_exactness_condition_detects_tiny_costs():
    assert not rle_is_exact(np.array([0.0, 1e-30, 16.0], dtype=np.float32), 1000)
    assert rle_is_exact(np.array([0.0, 0.02, 16.0], dtype=np.float32), 100_000)


def test_run_length_approximation_is_an_upper_bound_equal_without_runs(tables):
    _, full, diff = tables
    rng = np.random.default_rng(8)
    lib = [_slow_codes(rng) for _ in range(30)]
    qs = [_slow_codes(rng) for _ in range(8)]
    _, approx = brute_force_runs(qs, lib, diff, k=1)
    _, exact = brute_force(qs, lib, full, k=1)
    assert np.all(approx >= exact)
    # sequences without repeated codes: the approximation is the exact DTW
    a = np.array([1, 2, 3, 4, 9], np.int32)
    b = np.array([4, 3, 2, 8], np.int32)
    assert brute_force_runs([a], [b], diff)[1][0, 0] == dtw_codes(a, b, full)


# ------------------------------------------------------------------ pruned search
@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("k,band", [(1, None), (3, None), (1, 4), (2, 2)])
def test_pruned_search_equals_brute_force(tables, backend, k, band):
    _, full, diff = tables
    rng = np.random.default_rng(100 + k + (band or 0))
    lib = [_slow_codes(rng) for _ in range(50 if backend == "numba" else 30)]
    lib[7] = lib[3].copy()  # an exact tie: the lower index must win, like argsort(stable)
    qs = [_slow_codes(rng) for _ in range(10)] + [lib[3]]
    idx, dist = brute_force(qs, lib, full, k=k, band=band)
    searcher = FastSearcher(lib, diff, band=band, backend=backend)
    for parallel in (False, True):
        res = searcher.search(qs, k=k, parallel=parallel)
        assert np.array_equal(res.indices, idx)
        assert np.array_equal(res.distances, dist)
    assert res.stats.candidates == len(qs) * len(lib)
    if backend == "numba":  # the ablation variants answer alike
        for kw in (dict(run_length=False), dict(run_length=False, use_bounds=False), dict(use_bounds=False)):
            alt = FastSearcher(lib, diff, band=band, **kw).search(qs, k=k, parallel=False)
            assert np.array_equal(alt.indices, idx) and np.array_equal(alt.distances, dist)
    assert res.stats.pruned + res.stats.abandoned + res.stats.completed == res.stats.candidates


def test_search_prunes_on_real_like_data_and_finds_planted_copies(tables):
    _, full, diff = tables
    rng = np.random.default_rng(21)
    lib = [_slow_codes(rng, max_runs=60) for _ in range(120)]
    qs = [lib[i][2:-2] if len(lib[i]) > 6 else lib[i] for i in (5, 50, 99)]
    res = FastSearcher(lib, diff).search(qs, k=1)
    assert np.array_equal(res.indices, brute_force(qs, lib, full)[0])
    assert res.stats.pruned_fraction > 0.3


def test_runs_mode_search_matches_its_brute_force(tables):
    _, _, diff = tables
    rng = np.random.default_rng(31)
    lib = [_slow_codes(rng) for _ in range(40)]
    qs = [_slow_codes(rng) for _ in range(6)]
    idx, dist = brute_force_runs(qs, lib, diff, k=2)
    for backend in ("numba", "numpy"):
        res = FastSearcher(lib, diff, mode="runs", backend=backend).search(qs, k=2)
        assert np.array_equal(res.indices, idx) and np.array_equal(res.distances, dist)


def test_numpy_and_numba_paths_agree_on_quantised_real_features(tables):
    rng = np.random.default_rng(4)
    # smooth 17-D "features" -> real quantiser -> codes with realistic runs
    walk = np.cumsum(rng.normal(size=(3000, 17)), axis=0) * 0.1
    q = Quantizer.fit(walk, 6)
    diff = DiffTable.from_ratios(q.ratios)
    codes = [q.encode(walk[s:s + int(rng.integers(20, 80))]) for s in rng.integers(0, 2900, 40)]
    a = FastSearcher(codes[5:], diff, backend="numba").search(codes[:5], k=2)
    b = FastSearcher(codes[5:], diff, backend="numpy").search(codes[:5], k=2)
    assert np.array_equal(a.indices, b.indices) and np.array_equal(a.distances, b.distances)
    assert np.array_equal(a.indices, brute_force(codes[:5], codes[5:], q.table(), k=2)[0])


def test_numpy_path_rejects_with_the_range_bound_and_still_equals_brute_force(tables):
    """The numpy path (no numba) checks the row/column range-cover bound before each DP:
    same neighbours and distances as brute force, with and without it, and it does work."""
    _, full, diff = tables
    rng = np.random.default_rng(59)
    lib = [_slow_codes(rng, max_runs=30, max_run=10) for _ in range(60)]
    qs = [_slow_codes(rng, max_runs=30, max_run=10) for _ in range(10)] + [lib[7][2:]]
    idx, dist = brute_force(qs, lib, full, k=2)
    on = FastSearcher(lib, diff, backend="numpy").search(qs, k=2)
    off = FastSearcher(lib, diff, backend="numpy", range_bound=False).search(qs, k=2)
    for res in (on, off):
        assert np.array_equal(res.indices, idx) and np.array_equal(res.distances, dist)
    assert on.stats.range_rejected > 0 and off.stats.range_rejected == 0
    started = lambda st: st.completed + st.abandoned - st.range_rejected  # noqa: E731 - DPs begun
    assert started(on.stats) < started(off.stats)


def test_bad_input_raises_storybeam_errors(tables):
    _, _, diff = tables
    with pytest.raises(StoryBeamError):
        FastSearcher([np.array([], np.int32)], diff)
    with pytest.raises(StoryBeamError):
        FastSearcher([np.array([5000], np.int32)], diff)
    with pytest.raises(StoryBeamError):
        FastSearcher([np.array([1, 2], np.int32)], diff, mode="fastest")
    with pytest.raises(StoryBeamError):
        FastSearcher([np.array([1, 2], np.int32)], diff).search([np.array([1])], k=0)
    with pytest.raises(StoryBeamError):
        PackedCodes.from_sequences([])


def test_compiled_packing_equals_the_numpy_packing():
    """With the alphabet size known, sequences are packed by one compiled pass; without it,
    by run_length_encode + np.unique + searchsorted. Both must give the same arrays."""
    rng = np.random.default_rng(57)
    seqs = [_slow_codes(rng, max_runs=30) for _ in range(40)] + [np.array([7], np.int32), np.array([0, 4095], np.int32)]
    fast, ref = PackedCodes.from_sequences(seqs, 4096), PackedCodes.from_sequences(seqs)
    for a, b in zip(fast.arrays(), ref.arrays()):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    # one sequence (a query) is packed without concatenation and checked while packed
    for seq in seqs:
        one, ref1 = PackedCodes.from_sequences([seq], 4096), PackedCodes.from_sequences([seq])
        for a, b in zip(one.arrays(), ref1.arrays()):
            assert a.dtype == b.dtype and np.array_equal(a, b)
    for bad in (np.array([3, 4096, 2], np.int32), np.array([-1], np.int32)):
        with pytest.raises(StoryBeamError, match=r"must lie in \[0, 4096\)"):
            PackedCodes.from_sequences([bad], 4096)
        with pytest.raises(StoryBeamError, match=r"must lie in \[0, 4096\)"):
            PackedCodes.from_sequences([np.array([1], np.int32), bad], 4096)


def test_least_first_is_the_head_of_a_stable_sort():
    """The lazy cascade takes the k + 2 least cheap bounds in one pass instead of sorting
    them all: the same indices in the same order as a stable argsort's first ones, ties
    (many here) to the lower index."""
    pytest.importorskip("numba")
    from retrieval.search.order import least_first
    rng = np.random.default_rng(58)
    for _ in range(300):
        n = int(rng.integers(1, 60))
        v = rng.integers(0, 6, n).astype(np.float64) / 4 if rng.random() < 0.5 else rng.random(n)
        if rng.random() < 0.2:
            v[rng.integers(0, n)] = np.inf
        for m in (1, 3, 7, n, n + 4):
            assert np.array_equal(least_first(v, m), np.argsort(v, kind="mergesort")[:m])


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_motion_index_answers_equal_the_brute_force_reference(backend):
    """MotionIndex.query / similar_to go through the fast search and return exactly what the
    seed's DTW against every clip returns (same clips, same distances, same order)."""
    from retrieval.codes import full_table
    from retrieval.library import Clip, MotionIndex
    from retrieval.search import brute_force

    rng = np.random.default_rng(9)
    walk = np.cumsum(rng.normal(size=(4000, 17)), axis=0) * 0.1
    clips = [Clip(f"t{i}", "abc"[i % 3], walk[s:s + int(rng.integers(30, 90))], None, 30.0)
             for i, s in enumerate(rng.integers(0, 3900, 40))]
    index = MotionIndex.from_clips(clips, dims=6, backend=backend)
    assert index.backend == backend
    seed_table = full_table(index.quantizer.ratios)
    for q in (walk[100:160], walk[2000:2040], clips[4].features):
        idx, dist = brute_force([index.encode(q)], index.codes, seed_table, k=5)
        got = index.query(q, k=5)
        assert [m.trial for m in got] == [index.trials[i] for i in idx[0]]
        assert [m.distance for m in got] == dist[0].tolist()
    idx, dist = brute_force([index.codes[7]], index.codes, seed_table, k=6)
    expect = [(index.trials[i], d) for i, d in zip(idx[0], dist[0]) if i != 7][:5]
    assert [(m.trial, m.distance) for m in index.similar_to("t7", k=5)] == expect
