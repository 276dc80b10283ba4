"""The tablet's search (no numba): the row-scan DP and the library-wide bounds in numpy equal
the compiled path and the seed's brute force, and ``storybeam search --json`` run with numba
and llvmlite made unimportable (as on python-for-android) answers exactly as on the desktop."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from retrieval.codes import DiffTable, Quantizer, full_table
from retrieval.dtw import (
    HAVE_NUMBA,
    distinct_counts,
    dtw_codes,
    dtw_rows_numpy,
    library_bounds,
    lower_bound,
    rle_is_exact,
    run_length_decode,
)
from retrieval.search import FastSearcher, PackedCodes, brute_force

REPO = Path(__file__).resolve().parents[2]

#: run ``storybeam search`` with only the tablet's packages importable: the tablet-profile
#: tests' blocker (tests/support/tablet_profile.py: numba, llvmlite and every third-party
#: module python-for-android does not install), else numba and llvmlite alone. The search
#: command is registered on its own: app.cli loads every command, and the desktop ones
#: import tqdm (app/progress.py), which the tablet does not have.
TABLET_SEARCH = """
import argparse, sys
try:
    from tests.support.tablet_profile import Blocker
    blocker = Blocker()
except ImportError:
    class _Block:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in ("numba", "llvmlite"):
                raise ModuleNotFoundError("blocked for the tablet profile: " + name, name=name)
            return None
    blocker = _Block()
sys.meta_path.insert(0, blocker)
from app.commands import search_cmd
parser = argparse.ArgumentParser(prog="storybeam")
search_cmd.register(parser.add_subparsers(dest="command"))
args = parser.parse_args(["search", *sys.argv[1:]])
sys.exit(args.func(args))
"""


def _slow_codes(rng: np.random.Generator, max_runs: int = 25, max_run: int = 6) -> np.ndarray:
    k = int(rng.integers(1, max_runs))
    vals = rng.integers(0, 4096, k) if rng.random() < 0.4 else rng.integers(0, 24, k) * 37 % 4096
    return run_length_decode(vals, rng.integers(1, max_run + 1, k))


@pytest.fixture(scope="module")
def tables():
    c = np.sort(np.random.default_rng(3).dirichlet(np.ones(17)))[::-1][:6]
    assert rle_is_exact(full_table(c)[0], 1000)
    return full_table(c), DiffTable.from_ratios(c)


def _rests(a: np.ndarray, b: np.ndarray, diff: DiffTable) -> tuple[np.ndarray, np.ndarray]:
    cost = diff.lookup(a[:, None], b[None, :]).astype(np.float64)
    per_row, per_col = cost.min(axis=1), cost.min(axis=0)
    return np.cumsum(per_row[::-1])[::-1] - per_row, np.cumsum(per_col[::-1])[::-1] - per_col


def test_row_scan_dtw_is_bit_identical_to_the_seed_dtw(tables):
    full, diff = tables
    rng = np.random.default_rng(11)
    for _ in range(300):
        a, b = _slow_codes(rng), _slow_codes(rng)
        ref = dtw_codes(a, b, full, backend="numpy", normalize=False)
        cost = diff.lookup(a[:, None], b[None, :]).astype(np.float64)
        assert dtw_rows_numpy(cost) == ref
        if HAVE_NUMBA:
            assert ref == dtw_codes(a, b, full, backend="numba", normalize=False)


def test_row_scan_abandons_only_above_the_limit(tables):
    full, diff = tables
    rng = np.random.default_rng(12)
    seen_abandon = seen_keep = 0
    for _ in range(300):
        a, b = _slow_codes(rng), _slow_codes(rng)
        ref = dtw_codes(a, b, full, normalize=False)
        cost = diff.lookup(a[:, None], b[None, :]).astype(np.float64)
        rr, rc = _rests(a, b, diff)
        limit = ref * float(rng.uniform(0.5, 1.5))
        got = dtw_rows_numpy(cost, rr, rc, limit)
        if ref <= limit:
            assert got == ref
            seen_keep += 1
        else:
            assert got == np.inf
            seen_abandon += 1
        assert dtw_rows_numpy(cost, rr, rc, ref) == ref  # exactly at the limit: kept
    assert seen_abandon > 50 and seen_keep > 50


def _library_bounds(a: np.ndarray, lib: list[np.ndarray], diff: DiffTable) -> tuple:
    packed = PackedCodes.from_sequences(lib, diff.size)
    vocab = np.unique(packed.dist_val)
    return library_bounds(a, vocab, np.searchsorted(vocab, packed.dist_val), packed.dist_cnt, packed.dist_off,
                          packed.codes[packed.code_off[:-1]], packed.codes[packed.code_off[1:] - 1], packed.lengths,
                          diff)


def test_library_bounds_equal_the_per_clip_bounds_and_never_exceed_the_dtw(tables):
    full, diff = tables
    rng = np.random.default_rng(13)
    lib = [_slow_codes(rng) for _ in range(40)] + [np.array([5], np.int32)]
    for _ in range(8):
        a = _slow_codes(rng)
        lbs, rowmin, colmin, a_didx, R = _library_bounds(a, lib, diff)
        assert lbs.tolist() == [lower_bound(a, b, diff) for b in lib]  # exact sums: same values
        assert np.all(lbs <= np.array([dtw_codes(a, b, full) for b in lib]))
        ua, _ = distinct_counts(a)
        for c, b in enumerate(lib):  # rowmin: each query code's cheapest code in the clip
            assert np.array_equal(rowmin[:, c], diff.lookup(ua[:, None], b[None, :]).min(axis=1))
        assert np.array_equal(ua[a_didx], a)


@pytest.mark.skipif(not HAVE_NUMBA, reason="compares with the compiled path")
def test_library_bounds_equal_the_compiled_bounds(tables):
    from lab.bench.ucr_rival import UCRRival

    _, diff = tables
    rng = np.random.default_rng(14)
    lib = [_slow_codes(rng) for _ in range(50)]
    rival = UCRRival(lib, diff)  # compiled LB_Kim + LB_Keogh both ways, the same three bounds
    for _ in range(8):
        a = _slow_codes(rng)
        assert _library_bounds(a, lib, diff)[0].tolist() == rival.bounds(a).tolist()


@pytest.mark.parametrize("k", [1, 3, 5])
def test_numpy_search_equals_the_compiled_search_and_brute_force(tables, k):
    full, diff = tables
    rng = np.random.default_rng(20 + k)
    lib = [_slow_codes(rng, max_runs=40, max_run=8) for _ in range(60)]
    lib[8] = lib[2].copy()
    qs = [_slow_codes(rng, max_runs=40, max_run=8) for _ in range(8)] + [lib[2]]
    idx, dist = brute_force(qs, lib, full, k=k)
    got = FastSearcher(lib, diff, backend="numpy").search(qs, k=k)
    assert np.array_equal(got.indices, idx) and np.array_equal(got.distances, dist)
    assert got.stats.pruned + got.stats.abandoned + got.stats.completed == got.stats.candidates
    if HAVE_NUMBA:
        nb = FastSearcher(lib, diff, backend="numba").search(qs, k=k, parallel=False)
        assert np.array_equal(nb.indices, idx) and np.array_equal(nb.distances, dist)


def test_numpy_search_on_real_cmu_clips(cmu_dir):
    from lab.experiment import stack_frames, stratified_subset
    from retrieval.library import load_dataset, read_labels

    clips = stratified_subset(load_dataset(cmu_dir, fps=30, rows=read_labels(cmu_dir)), 40, seed=3)
    q = Quantizer.fit(stack_frames([c.features for c in clips[8:]]), 6)
    diff, full = DiffTable.from_ratios(q.ratios), q.table()
    codes = [q.encode(c.features) for c in clips]
    queries = [c[len(c) // 4: len(c) // 4 + 120] for c in codes[:8]]
    idx, dist = brute_force(queries, codes[8:], full, k=5)
    got = FastSearcher(codes[8:], diff, backend="numpy").search(queries, k=5)
    assert np.array_equal(got.indices, idx) and np.array_equal(got.distances, dist)
    lbs = _library_bounds(queries[0], codes[8:], diff)[0]
    assert np.all(lbs <= np.array([dtw_codes(queries[0], b, full) for b in codes[8:]]))


def _search_json(argv: list[str], tablet: bool) -> dict:
    cmd = [sys.executable, "-c", TABLET_SEARCH] if tablet else [sys.executable, "-m", "app.cli", "search"]
    proc = subprocess.run(cmd + [*argv, "--json", "-"], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return json.loads(proc.stdout)


def _query_bvh(src_folder: Path, tmp_path: Path) -> Path:
    from retrieval.library import read_labels
    from retrieval.motion.formats import load_motion
    from retrieval.motion.formats.bvh import save_bvh

    row = read_labels(src_folder)[-1]  # a clip of the library: the distances are then exactly comparable
    motion = load_motion(row.file, row.skeleton) if row.skeleton else load_motion(row.file)
    part = motion.slice(0, min(motion.n_frames, int(4 * motion.fps)))
    return save_bvh(part, tmp_path / "query.bvh")


@pytest.mark.parametrize("where", ["bundled", "cmu"])
@pytest.mark.slow  # the search command in child interpreters
def test_tablet_profile_search_answers_as_the_desktop(where, tmp_path, request):
    """``storybeam search --json`` with numba and llvmlite unimportable runs the numpy path
    and returns the same clips at the same distances as the compiled path."""
    from app.paths import MOTIONS_DIR

    folder = MOTIONS_DIR if where == "bundled" else request.getfixturevalue("cmu_dir")
    query = _query_bvh(folder, tmp_path)
    argv = ["--query", str(query), "-k", "5"]
    desktop = _search_json(argv + ["--data", str(folder), "--save-index", str(tmp_path / "idx")], tablet=False)
    tablet = _search_json(argv + ["--data", str(tmp_path / "idx")], tablet=True)
    assert tablet["backend"] == "numpy"
    assert desktop["backend"] == ("numba" if HAVE_NUMBA else "numpy")
    assert tablet["results"] == desktop["results"] and len(tablet["results"]) == 5
    assert tablet["search_ms"] > 0


def test_runs_row_scans_in_batches_equal_one_by_one_and_the_compiled_search(tables):
    """The numpy "runs" search takes candidates in batches (``runs_dtw_rows_batch_numpy``:
    padded to the most runs, abandoning per candidate): each raw distance equals the
    one-by-one row scan bit for bit, inf only above that candidate's limit; and the numpy
    search (batches of 8, 16, …, pruning between them) answers as the compiled one for k
    of 1 to 12, on libraries larger than a batch."""
    from retrieval.dtw import run_length_encode
    from retrieval.dtw import runs_dtw_rows_batch_numpy, runs_dtw_rows_numpy

    _full, diff = tables
    rng = np.random.default_rng(33)
    for _ in range(40):
        q = _slow_codes(rng, max_runs=30)
        qv, ql = run_length_encode(q)
        cands = [run_length_encode(_slow_codes(rng, max_runs=int(rng.integers(2, 40)))) for _ in range(int(rng.integers(1, 12)))]
        refs = np.array([runs_dtw_rows_numpy(diff.lookup(qv[:, None], v[None, :]), ql, ln) for v, ln in cands])
        assert np.array_equal(runs_dtw_rows_batch_numpy(diff, qv, ql, cands, np.full(len(cands), np.inf)), refs)
        limits = refs * rng.uniform(0.5, 1.5, len(refs))
        got = runs_dtw_rows_batch_numpy(diff, qv, ql, cands, limits)
        assert all(g == r if r <= lim else g in (np.inf, r) for g, r, lim in zip(got, refs, limits))
    lib = [_slow_codes(rng, max_runs=30) for _ in range(90)]
    queries = [_slow_codes(rng, max_runs=30) for _ in range(6)] + [lib[5]]
    for k in (1, 5, 12):
        numpy_runs = FastSearcher(lib, diff, mode="runs", backend="numpy").search(queries, k=k)
        if HAVE_NUMBA:
            compiled = FastSearcher(lib, diff, mode="runs", backend="numba").search(queries, k=k, parallel=False)
            assert np.array_equal(numpy_runs.indices, compiled.indices)
            assert np.array_equal(numpy_runs.distances, compiled.distances)
        assert numpy_runs.indices[-1, 0] == 5 and numpy_runs.distances[-1, 0] == 0.0


def test_runs_row_scan_equals_the_runs_dp_and_abandons_only_above_the_limit(tables):
    """The "runs" mode's numpy DP by row scans (``runs_dtw_rows_numpy``, what the tablet's
    storybeam shortlist runs) equals the anti-diagonal one bit for bit under exact sums,
    and returns inf only when the distance is above the limit; with numba, the compiled
    "runs" search and the numpy one answer alike."""
    from retrieval.dtw import run_length_encode
    from retrieval.dtw import runs_dtw_numpy, runs_dtw_rows_numpy

    _full, diff = tables
    rng = np.random.default_rng(21)
    kept = abandoned = 0
    for _ in range(300):
        a, b = _slow_codes(rng), _slow_codes(rng)
        av, al = run_length_encode(a)
        bv, bl = run_length_encode(b)
        assert rle_is_exact(diff.F, len(a) + len(b))
        block = diff.lookup(av[:, None], bv[None, :])
        ref = runs_dtw_numpy(block, al, bl)
        assert runs_dtw_rows_numpy(block, al, bl) == ref
        limit = ref * float(rng.uniform(0.5, 1.5))
        got = runs_dtw_rows_numpy(block, al, bl, limit)
        if ref <= limit:
            assert got == ref
            kept += 1
        else:
            assert got in (np.inf, ref)
            abandoned += got == np.inf
    assert kept > 50 and abandoned > 50
    lib = [_slow_codes(rng) for _ in range(60)]
    queries = [_slow_codes(rng) for _ in range(8)]
    numpy_runs = FastSearcher(lib, diff, mode="runs", backend="numpy").search(queries, k=3)
    if HAVE_NUMBA:
        compiled = FastSearcher(lib, diff, mode="runs", backend="numba").search(queries, k=3)
        assert np.array_equal(numpy_runs.indices, compiled.indices)
        assert np.array_equal(numpy_runs.distances, compiled.distances)
