"""DTW kernels: against a brute-force reference, numba == numpy, band, normalisation."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from retrieval.dtw import DTWError, band_limits, dtw_codes, dtw_features
from retrieval.codes import code_table, full_table

TABLE = full_table(np.array([0.4, 0.25, 0.15]))  # 64 codes


def brute_force(cost: np.ndarray, allowed=None) -> float:
    """Cheapest monotone path (0,0)->(x-1,y-1) with steps (1,0),(0,1),(1,1), by plain
    recursion over every predecessor (no rolling arrays), optionally within ``allowed``."""
    nx, ny = cost.shape

    @functools.lru_cache(maxsize=None)
    def d(i: int, j: int) -> float:
        if allowed is not None and not allowed[i, j]:
            return np.inf
        if i == 0 and j == 0:
            return float(cost[0, 0])
        prev = [d(a, b) for a, b in ((i - 1, j), (i, j - 1), (i - 1, j - 1)) if a >= 0 and b >= 0]
        return float(cost[i, j]) + min(prev)

    return d(nx - 1, ny - 1)


def enumerate_paths(cost: np.ndarray) -> float:
    """Minimum over every warping path, enumerated explicitly (tiny cases only)."""
    nx, ny = cost.shape
    best = np.inf

    def walk(i, j, acc):
        nonlocal best
        acc += cost[i, j]
        if (i, j) == (nx - 1, ny - 1):
            best = min(best, acc)
            return
        for di, dj in ((1, 0), (0, 1), (1, 1)):
            if i + di < nx and j + dj < ny:
                walk(i + di, j + dj, acc)

    walk(0, 0, 0.0)
    return best


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_codes_match_path_enumeration_on_tiny_cases(backend):
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = rng.integers(0, 64, rng.integers(1, 6))
        b = rng.integers(0, 64, rng.integers(1, 6))
        cost = TABLE[a[:, None], b[None, :]].astype(np.float64)
        ref = enumerate_paths(cost)
        got = dtw_codes(a, b, TABLE, backend=backend, normalize=False)
        assert got == pytest.approx(ref, rel=1e-12)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_features_match_brute_force_recursion(backend):
    rng = np.random.default_rng(1)
    for _ in range(10):
        x = rng.normal(size=(rng.integers(1, 25), 4))
        y = rng.normal(size=(rng.integers(1, 25), 4))
        cost = np.linalg.norm(x[:, None] - y[None], axis=2)
        got = dtw_features(x, y, backend=backend, normalize=False)
        assert got == pytest.approx(brute_force(cost), rel=1e-12)


def test_known_small_value():
    # identical except one frame repeated: warping absorbs it, distance 0
    a = np.array([1, 5, 5, 9])
    b = np.array([1, 5, 9])
    assert dtw_codes(a, b, TABLE) == 0.0
    x = np.array([[0.0], [1.0], [2.0]])
    y = np.array([[0.0], [2.0]])
    # best path: (0,0)=0, (1,0) or (1,1)=1, (2,1)=0 -> 1; normalised by 3+2
    assert dtw_features(x, y, normalize=False) == pytest.approx(1.0)
    assert dtw_features(x, y) == pytest.approx(1.0 / 5)


def test_numba_and_numpy_give_the_same_numbers_with_and_without_band():
    rng = np.random.default_rng(2)
    split = code_table(np.array([0.3, 0.2, 0.15, 0.1, 0.08]), max_full_dims=2)
    full5 = full_table(np.array([0.3, 0.2, 0.15, 0.1, 0.08]))
    for trial in range(30):
        nx, ny = rng.integers(1, 80, 2)
        band = [None, 0, 1, 3, 10][trial % 5]
        a, b = rng.integers(0, 64, nx), rng.integers(0, 64, ny)
        assert dtw_codes(a, b, TABLE, band, "numba") == dtw_codes(a, b, TABLE, band, "numpy")
        a5, b5 = rng.integers(0, 4**5, nx), rng.integers(0, 4**5, ny)
        s_nb = dtw_codes(a5, b5, split, band, "numba")
        assert s_nb == dtw_codes(a5, b5, split, band, "numpy")
        assert s_nb == pytest.approx(dtw_codes(a5, b5, full5, band, "numba"), rel=1e-6)
        x, y = rng.normal(size=(nx, 17)), rng.normal(size=(ny, 17))
        assert dtw_features(x, y, band, "numba") == pytest.approx(dtw_features(x, y, band, "numpy"), rel=1e-12)


def test_band_matches_brute_force_inside_the_same_window_and_never_beats_full():
    rng = np.random.default_rng(3)
    for band in (0, 1, 2, 5):
        a, b = rng.integers(0, 64, 17), rng.integers(0, 64, 29)
        lo, hi = band_limits(17, 29, band)
        cols = np.arange(29)
        allowed = (cols[None] >= lo[:, None]) & (cols[None] <= hi[:, None])
        cost = TABLE[a[:, None], b[None, :]].astype(np.float64)
        banded = dtw_codes(a, b, TABLE, band, normalize=False)
        assert banded == pytest.approx(brute_force(cost, allowed), rel=1e-12)
        assert banded >= dtw_codes(a, b, TABLE, None, normalize=False)
        assert np.isfinite(banded)


def test_bad_input_raises_dtw_error():
    with pytest.raises(DTWError):
        dtw_codes(np.array([], dtype=int), np.array([1]), TABLE)
    with pytest.raises(DTWError):
        dtw_codes(np.array([64]), np.array([1]), TABLE)
    with pytest.raises(DTWError):
        dtw_codes(np.array([1]), np.array([1]), TABLE, backend="cuda")
    with pytest.raises(DTWError):
        dtw_features(np.zeros((3, 2)), np.zeros((3, 3)))


def test_kernel_cache_folder_follows_every_kernel_source(tmp_path):
    """numba keys its cache on one source file; the kernels call across files, so the cache
    folder is keyed on all of them: any edit moves it, identical sources share it, and a
    child process (which inherits NUMBA_CACHE_DIR) resolves to the same folder."""
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    import retrieval
    from retrieval.dtw import KERNEL_MODULES, kernel_cache_dir

    src = Path(retrieval.__file__).resolve().parent
    copy = tmp_path / "src"
    copy.mkdir()
    for name in KERNEL_MODULES:
        (copy / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(src / name, copy / name)
    root = tmp_path / "cache"
    first = kernel_cache_dir(root, copy)
    assert first.parent == root and first == kernel_cache_dir(root, copy) == kernel_cache_dir(root, src)
    for name in KERNEL_MODULES:
        (copy / name).write_text((src / name).read_text() + "\n# edited\n")
        assert kernel_cache_dir(root, copy) != first, name
        shutil.copy(src / name, copy / name)
    # this process and a child started with its environment agree on the folder
    here = os.environ["NUMBA_CACHE_DIR"]
    child = subprocess.run([sys.executable, "-c", "import os, retrieval.dtw; print(os.environ['NUMBA_CACHE_DIR'])"],
                           capture_output=True, text=True, env=dict(os.environ), check=True)
    assert child.stdout.strip() == here


def test_every_module_with_compiled_kernels_keys_the_cache():
    """A module that compiles kernels but is missing from KERNEL_MODULES would keep its
    callers' cached code stale after an edit (the cache folder would not move)."""
    from pathlib import Path

    import retrieval
    from retrieval.dtw import KERNEL_MODULES

    src = Path(retrieval.__file__).resolve().parent
    compiling = {str(p.relative_to(src)) for p in src.rglob("*.py") if "numba.njit(" in p.read_text()}
    assert compiling == set(KERNEL_MODULES)
