"""The numpy-only path (Android: no numba): fast exact search (with and without the range-cover
bound) vs the seed's method, all on numpy, 3-fold 1-NN on a labelled folder (default: the bundled library at 30 fps).

    .venv/bin/python scripts/bench_numpy_retrieval.py [FOLDER] [FPS]
"""
from __future__ import annotations

import sys

from app.bench.retrieval import FastMatcher
from retrieval.library import load_dataset
from retrieval.experiment import evaluate, make_matcher


def main() -> None:
    folder = sys.argv[1] if len(sys.argv) > 1 else "assets/motions"
    fps = float(sys.argv[2]) if len(sys.argv) > 2 else 30.0
    clips = load_dataset(folder, fps=fps)

    def factory(name, **kw):
        if name.startswith("fast_numpy"):
            m = FastMatcher(name)
            fit = m.fit

            def fit_numpy(refs):
                fit(refs)
                m.searcher.backend = "numpy"
                m.searcher.range_bound = name == "fast_numpy"  # the ablation row runs without it
                return m
            m.fit = fit_numpy
            return m
        kw["backend"] = "numpy"
        return make_matcher(name, **kw)

    res = evaluate(clips, ["fast_numpy", "fast_numpy_no_range", "quantized"], 3, 6, 0,
                   matcher_factory=factory)
    print(f"{len(clips)} clips from {folder} at {fps:g} fps, numpy back-end for all")
    for name, r in res.items():
        print(f"{name:<20} search {r.search_seconds:8.3f} s   accuracy {100 * r.accuracy:6.2f} %")
    print(f"speed-up {res['quantized'].search_seconds / res['fast_numpy'].search_seconds:.1f}x")


if __name__ == "__main__":
    main()
