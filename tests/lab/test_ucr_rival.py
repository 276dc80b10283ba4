"""The benchmark's UCR-suite-style rival (lab/bench/ucr_rival.py) is exact and really prunes:
its answers equal the seed's brute force (same clip, same distance bit for bit, ties to
the lower index), its bounds never exceed the seed's DTW, on random codes, on quantised
smooth walks and on real CMU clips."""
from __future__ import annotations

import numpy as np
import pytest

from lab.bench.ucr_rival import RivalError, UCRRival
from retrieval.codes import DiffTable, Quantizer, full_table
from retrieval.dtw import HAVE_NUMBA, dtw_codes, run_length_decode
from retrieval.search import FastSearcher, brute_force

pytestmark = pytest.mark.skipif(not HAVE_NUMBA, reason="the rival is compiled with numba")


def _slow_codes(rng: np.random.Generator, max_runs: int = 25, max_run: int = 6) -> np.ndarray:
    k = int(rng.integers(1, max_runs))
    vals = rng.integers(0, 4096, k) if rng.random() < 0.4 else rng.integers(0, 24, k) * 37 % 4096
    return run_length_decode(vals, rng.integers(1, max_run + 1, k))


@pytest.fixture(scope="module")
def tables():
    c = np.sort(np.random.default_rng(3).dirichlet(np.ones(17)))[::-1][:6]
    return full_table(c), DiffTable.from_ratios(c)


@pytest.mark.parametrize("strategy", ["cascade", "sorted"])
def test_rival_equals_brute_force_on_random_codes_with_ties(tables, strategy):
    full, diff = tables
    rng = np.random.default_rng(7)
    for trial in range(6):
        lib = [_slow_codes(rng) for _ in range(40)]
        lib[9] = lib[4].copy()  # an exact tie: the lower index must win
        lib[11] = lib[11][:1]  # a one-frame clip
        qs = [_slow_codes(rng) for _ in range(8)] + [lib[4], lib[11]]
        idx, dist = brute_force(qs, lib, full, k=1)
        rival = UCRRival(lib, diff, strategy)
        for q, i, d in zip(qs, idx[:, 0], dist[:, 0]):
            r = rival.search(q)
            assert (r.index, r.distance) == (i, d)
            assert r.pruned + r.abandoned + r.completed == r.candidates == len(lib)


def test_rival_bounds_never_exceed_the_seed_dtw(tables):
    full, diff = tables
    rng = np.random.default_rng(8)
    lib = [_slow_codes(rng) for _ in range(60)]
    rival = UCRRival(lib, diff)
    for _ in range(10):
        q = _slow_codes(rng)
        lbs = rival.bounds(q)
        d = np.array([dtw_codes(q, b, full) for b in lib])
        assert np.all(lbs <= d)
        assert np.any(lbs > 0)


@pytest.mark.parametrize("strategy", ["cascade", "sorted"])
def test_rival_prunes_and_agrees_with_the_fast_search_on_quantised_walks(strategy):
    rng = np.random.default_rng(4)
    walk = np.cumsum(rng.normal(size=(6000, 17)), axis=0) * 0.1
    q = Quantizer.fit(walk, 6)
    diff, full = DiffTable.from_ratios(q.ratios), q.table()
    codes = [q.encode(walk[s:s + int(rng.integers(20, 120))]) for s in rng.integers(0, 5800, 150)]
    queries, lib = codes[:10], codes[10:]
    idx, dist = brute_force(queries, lib, full, k=1)
    rival = UCRRival(lib, diff, strategy)
    fast = FastSearcher(lib, diff).search(queries, k=1, parallel=False)
    pruned = abandoned = 0
    for qi, a in enumerate(queries):
        r = rival.search(a)
        assert (r.index, r.distance) == (idx[qi, 0], dist[qi, 0]) == (fast.indices[qi, 0], fast.distances[qi, 0])
        pruned += r.pruned
        abandoned += r.abandoned
    # a rival that does not prune and abandon is no rival
    assert pruned > 0.3 * len(queries) * len(lib) and abandoned > 0


@pytest.mark.parametrize("strategy", ["cascade", "sorted"])
def test_rival_on_real_cmu_clips(cmu_dir, strategy):
    from lab.experiment import stack_frames, stratified_subset
    from retrieval.library import load_dataset, read_labels

    clips = stratified_subset(load_dataset(cmu_dir, fps=30, rows=read_labels(cmu_dir)), 30, seed=5)
    q = Quantizer.fit(stack_frames([c.features for c in clips[8:]]), 6)
    diff, full = DiffTable.from_ratios(q.ratios), q.table()
    codes = [q.encode(c.features) for c in clips]
    queries, lib = codes[:8], codes[8:]
    idx, dist = brute_force(queries, lib, full, k=1)
    rival = UCRRival(lib, diff, strategy)
    for qi, a in enumerate(queries):
        assert np.all(rival.bounds(a) <= np.array([dtw_codes(a, b, full) for b in lib]))
        r = rival.search(a)
        assert (r.index, r.distance) == (idx[qi, 0], dist[qi, 0])


def test_bad_input_is_a_rival_error(tables):
    _, diff = tables
    with pytest.raises(RivalError, match="at least one"):
        UCRRival([], diff)
    with pytest.raises(RivalError, match="library clip 1"):
        UCRRival([np.array([1, 2]), np.array([5000])], diff)
    with pytest.raises(RivalError, match="query codes"):
        UCRRival([np.array([1, 2])], diff).search(np.array([], np.int64))
    with pytest.raises(RivalError, match="strategy 'fastest'"):
        UCRRival([np.array([1, 2])], diff, "fastest")


def test_float_rival_bounds_and_answers_equal_brute_force():
    """The float-feature rival of the bench (dtaidistance, Euclidean inner distance, pruned,
    UCR order): its LB_Kim / bounding-box LB_Keogh never exceed the project's float DTW,
    and its nearest clip and distance are brute force's."""
    pytest.importorskip("dtaidistance")
    from lab.bench.retrieval import DtaidistancePruned
    from retrieval.dtw import dtw_features

    rng = np.random.default_rng(6)
    walk = np.cumsum(rng.normal(size=(5000, 17)), axis=0) * 0.1
    lib = [walk[s:s + int(rng.integers(5, 90))] for s in rng.integers(0, 4900, 60)]
    rival = DtaidistancePruned(lib)
    for s in rng.integers(0, 4900, 8):
        x = walk[s:s + int(rng.integers(5, 90))]
        d = np.array([dtw_features(x, r) for r in lib])
        assert np.all(rival.bounds(x) <= d)
        i, dist = rival(x)
        assert i == int(np.argmin(d)) and dist == pytest.approx(d[i], rel=1e-12)
