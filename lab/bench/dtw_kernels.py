"""Nanoseconds per DTW cell for StoryBeam's kernels, with dtaidistance's C code as a peer
(``storybeam bench dtw-kernels [--frames 1000] [--repeat 5]``).

Method: two smooth 17-D random walks of ``frames`` frames (seeded), quantised at n = 6
and n = 7; each kernel is called once to warm up (numba compile or cache load), then
timed ``repeat`` times and the median taken; ns/cell is that median over the cells of
the DP. Kernels: code look-up DTW (numba, 4096² table), the same with the n = 7 split
table, 17-D Euclidean DTW (numba), the numpy anti-diagonal path (on the first 300 frames
of each clip: it is slow), and dtaidistance's C ``dtw_ndim.distance`` on the same 17-D
data when dtaidistance is installed. dtaidistance's metric differs (square root of the
summed *squared* frame distances), so it is a speed peer only, not an accuracy one.
"""
from __future__ import annotations

import statistics
import time
from typing import Callable

import numpy as np

from retrieval.codes import Quantizer
from retrieval.dtw import HAVE_NUMBA, dtw_codes, dtw_features
from retrieval.errors import StoryBeamError

try:  # optional: dtaidistance (a speed peer only, not a dependency)
    from dtaidistance import dtw_ndim
except ImportError:  # the peer row is left out
    dtw_ndim = None

#: frames of the numpy anti-diagonal path's pair (the numpy path is slow)
NUMPY_FRAMES = 300


def timed(fn: Callable[[], object], repeat: int) -> float:
    """Median seconds of ``repeat`` calls of ``fn`` after one warm-up call."""
    fn()  # warm-up (numba compile or cache load)
    runs = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - t)
    return statistics.median(runs)


def run_dtw_kernels_bench(frames: int = 1000, repeat: int = 5, seed: int = 0) -> dict:
    """Time every kernel of the module docstring; returns ``{"frames", "repeat",
    "kernels": [{"kernel", "seconds", "cells", "ns_per_cell"}, ...]}``."""
    if frames < 2:
        raise StoryBeamError(f"--frames must be at least 2, got {frames}")
    if repeat < 1:
        raise StoryBeamError(f"--repeat must be at least 1, got {repeat}")
    if not HAVE_NUMBA:
        raise StoryBeamError("the DTW kernel benchmark needs numba (it times the compiled kernels)")
    rng = np.random.default_rng(seed)
    n = frames
    # smooth random walks in 17-D, like feature trajectories
    x = np.cumsum(rng.normal(size=(n, 17)) * 0.05, axis=0)
    y = np.cumsum(rng.normal(size=(n, 17)) * 0.05, axis=0)
    q6 = Quantizer.fit(np.vstack([x, y]), 6)
    q7 = Quantizer.fit(np.vstack([x, y]), 7)
    t6, t7 = q6.table(), q7.table()
    a6, b6 = q6.encode(x), q6.encode(y)
    a7, b7 = q7.encode(x), q7.encode(y)
    m = min(n, NUMPY_FRAMES)
    cases: list[tuple[str, Callable[[], object], int]] = [
        ("codes, numba, 4096² table (n=6)", lambda: dtw_codes(a6, b6, t6, backend="numba"), n * n),
        ("codes, numba, split table (n=7)", lambda: dtw_codes(a7, b7, t7, backend="numba"), n * n),
        ("features 17-D, numba", lambda: dtw_features(x, y, backend="numba"), n * n),
        ("codes, numpy anti-diagonal (n=6)", lambda: dtw_codes(a6[:m], b6[:m], t6, backend="numpy"), m * m),
    ]
    if dtw_ndim is not None:
        cases.append(("dtaidistance C, 17-D (peer)", lambda: dtw_ndim.distance(x, y, use_c=True), n * n))
    kernels = []
    for name, fn, cells in cases:
        sec = timed(fn, repeat)
        kernels.append({"kernel": name, "seconds": sec, "cells": cells, "ns_per_cell": 1e9 * sec / cells})
    return {"frames": n, "repeat": repeat, "seed": seed, "kernels": kernels}


def format_table(result: dict) -> str:
    """One line per kernel: its name and ns/cell."""
    n = result["frames"]
    lines = [f"{'kernel':<36} {'ns/cell':>8}   ({n}x{n} frames, median of {result['repeat']})"]
    lines += [f"{k['kernel']:<36} {k['ns_per_cell']:>8.2f}" for k in result["kernels"]]
    return "\n".join(lines)
