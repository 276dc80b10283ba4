"""The numpy-only path (Android: no numba), ``storybeam bench numpy-retrieval [FOLDER] [FPS]``.

Method: stratified 3-fold 1-NN (n = 6, seed 0) on a labelled folder (default: the
bundled library at 30 fps) through :func:`lab.experiment.evaluate`, every method on
the numpy back-end: the fast exact search with the range-cover bound (``fast_numpy``),
the same without it (``fast_numpy_no_range``, the ablation) and the seed's method
(``quantized``, full table, no pruning). Search seconds are summed over the folds and
include turning each query into codes; the speed-up is the seed's time over the fast
search's.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from lab.bench.retrieval import BUNDLED_LIBRARY
from app.progress import progress_bar
from retrieval.errors import StoryBeamError
from lab.experiment import FastMatcher, evaluate, make_matcher
from retrieval.library import Clip, load_dataset

#: the methods compared, in table order
METHODS = ("fast_numpy", "fast_numpy_no_range", "quantized")


class NumpyFastMatcher(FastMatcher):
    """:class:`~lab.experiment.FastMatcher` on the numpy back-end, with the
    range-cover bound on or off."""

    def __init__(self, name: str, range_bound: bool = True, dims: int = 6):
        super().__init__(name, dims, backend="numpy")
        self.range_bound = range_bound

    def fit(self, references: Sequence[Clip]) -> "NumpyFastMatcher":
        super().fit(references)
        self.searcher.range_bound = self.range_bound
        return self


def _factory(name: str, **kw) -> object:
    """The evaluation's matcher factory: the fast variants here, the rest on numpy."""
    if name == "fast_numpy":
        return NumpyFastMatcher(name, range_bound=True, dims=kw.get("dims", 6))
    if name == "fast_numpy_no_range":
        return NumpyFastMatcher(name, range_bound=False, dims=kw.get("dims", 6))
    kw["backend"] = "numpy"
    return make_matcher(name, **kw)


def run_numpy_retrieval_bench(folder: str | Path = BUNDLED_LIBRARY, fps: float = 30.0, folds: int = 3,
                              progress: bool = True) -> dict:
    """Run the protocol of the module docstring; returns ``{"folder", "fps", "clips",
    "methods": {name: {"seconds", "accuracy"}}, "speedup_vs_seed_method"}``."""
    folder = Path(folder)
    if not (folder / "labels.csv").is_file():
        raise StoryBeamError(f"{folder} has no labels.csv: FOLDER must be a labelled motion folder")
    if not fps > 0:
        raise StoryBeamError(f"FPS must be positive, got {fps:g}")
    clips = load_dataset(folder, fps=fps, progress=progress_bar(f"loading {folder.name}", "clip", progress))
    if len(clips) < folds:
        raise StoryBeamError(f"{folder} has {len(clips)} clips; the {folds}-fold protocol needs at least {folds}")
    res = evaluate(clips, list(METHODS), folds, 6, 0, matcher_factory=_factory)
    methods = {name: {"seconds": r.search_seconds, "accuracy": r.accuracy} for name, r in res.items()}
    fast = methods["fast_numpy"]["seconds"]
    return {"folder": str(folder), "fps": fps, "clips": len(clips), "folds": folds, "methods": methods,
            "speedup_vs_seed_method": methods["quantized"]["seconds"] / fast if fast > 0 else float("inf")}


def format_table(result: dict) -> str:
    """A line per method (search seconds, accuracy) and the speed-up."""
    lines = [f"{result['clips']} clips from {result['folder']} at {result['fps']:g} fps, numpy back-end for all"]
    for name, r in result["methods"].items():
        lines.append(f"{name:<20} search {r['seconds']:8.3f} s   accuracy {100 * r['accuracy']:6.2f} %")
    lines.append(f"speed-up {result['speedup_vs_seed_method']:.1f}x")
    return "\n".join(lines)
