"""Nanoseconds per DTW cell for StoryBeam's kernels, with dtaidistance's C code as a peer.

Usage: .venv/bin/python scripts/bench_dtw_kernels.py [--frames 1000] [--repeat 5]

Kernels (after a warm-up call, median of --repeat runs, one pair of --frames-long clips):
code look-up DTW (numba, 4096² table, slowly varying codes as real clips give), the same
with the n = 7 split table, the numpy anti-diagonal path (on a shorter pair: it is slow),
17-D Euclidean DTW (numba), and dtaidistance's C ``dtw_ndim.distance`` on the same 17-D
data. dtaidistance's metric differs (square root of the summed *squared* frame distances),
so it is a speed peer only, not an accuracy one.
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from retrieval.dtw import dtw_codes, dtw_features
from retrieval.codes import Quantizer


def timed(fn, repeat: int) -> float:
    fn()  # warm-up (numba compile or cache load)
    runs = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - t)
    return statistics.median(runs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    n = args.frames
    # smooth random walks in 17-D, like feature trajectories
    x = np.cumsum(rng.normal(size=(n, 17)) * 0.05, axis=0)
    y = np.cumsum(rng.normal(size=(n, 17)) * 0.05, axis=0)
    q6 = Quantizer.fit(np.vstack([x, y]), 6)
    q7 = Quantizer.fit(np.vstack([x, y]), 7)
    t6, t7 = q6.table(), q7.table()
    a6, b6 = q6.encode(x), q6.encode(y)
    a7, b7 = q7.encode(x), q7.encode(y)
    cells = n * n
    rows = [
        ("codes, numba, 4096² table (n=6)", timed(lambda: dtw_codes(a6, b6, t6, backend="numba"), args.repeat), cells),
        ("codes, numba, split table (n=7)", timed(lambda: dtw_codes(a7, b7, t7, backend="numba"), args.repeat), cells),
        ("features 17-D, numba", timed(lambda: dtw_features(x, y, backend="numba"), args.repeat), cells),
    ]
    m = min(n, 300)
    rows.append(("codes, numpy anti-diagonal (n=6)",
                 timed(lambda: dtw_codes(a6[:m], b6[:m], t6, backend="numpy"), args.repeat), m * m))
    try:
        from dtaidistance import dtw_ndim

        rows.append(("dtaidistance C, 17-D (peer)",
                     timed(lambda: dtw_ndim.distance(x, y, use_c=True), args.repeat), cells))
    except ImportError:
        pass
    print(f"{'kernel':<36} {'ns/cell':>8}   ({n}x{n} frames, median of {args.repeat})")
    for name, sec, c in rows:
        print(f"{name:<36} {1e9 * sec / c:>8.2f}")


if __name__ == "__main__":
    main()
