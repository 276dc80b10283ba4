"""Where the fast exact search spends its time, and what the range-cover bound buys
(``storybeam bench fast-search-profile [FPS] [--data FOLDER]``).

Method: the paper protocol's folds (stratified 3-fold, seed 0, n = 6; the shared CMU
clips, else the bundled library, at FPS, default 120). Every query of each fold is
searched (k = 1, one numba thread, serial) with the range-cover bound on and off, the
variants interleaved query by query (alternating which goes first) so a busy neighbour
slows both alike; the answers must be identical. Then one pass times the stages of the
default search -- packing the query, the query's table rows, the envelope bounds, the
candidate loop -- with :meth:`retrieval.search.FastSearcher.profile_stages`, which runs
the same serial compiled search with a clock between the stages.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lab.bench.retrieval import load_clips, set_threads
from retrieval.codes import DiffTable, Quantizer
from retrieval.errors import StoryBeamError
from lab.experiment import stack_frames, stratified_folds
from retrieval.search import STAGES, FastSearcher, SearchStats, warm_up

#: the two variants compared: name -> FastSearcher keyword arguments
VARIANTS: dict[str, dict] = {"range bound on (default)": {}, "range bound off": {"range_bound": False}}


def fold_codes(data: str | Path | None, fps: float, folds: int = 3, progress: bool = True) -> tuple[list[dict], str,
                                                                                                   str | None]:
    """Per fold: the difference table, the reference codes and the query codes (a
    quantiser fitted on the fold's references); also the data folder and a note when the
    bundled library stood in for the shared set."""
    if not fps > 0:
        raise StoryBeamError(f"FPS must be positive, got {fps:g}")
    clips, source, note = load_clips(data, fps, progress=progress)
    if len(clips) < folds:
        raise StoryBeamError(f"{source} has {len(clips)} clips; the {folds}-fold protocol needs at least {folds}")
    out = []
    for qidx in stratified_folds([c.label for c in clips], folds, 0):
        ridx = np.setdiff1d(np.arange(len(clips)), qidx)
        qz = Quantizer.fit(stack_frames([clips[i].features for i in ridx]), 6)
        out.append({"table": DiffTable.from_ratios(qz.ratios), "refs": [qz.encode(clips[i].features) for i in ridx],
                    "queries": [qz.encode(clips[i].features) for i in qidx]})
    return out, source, note


def compare(folds: list[dict]) -> dict:
    """Search every query with each of :data:`VARIANTS`, interleaved; returns
    ``{"identical_answers", "variants": {name: {"seconds", "stats"}}, "speedup"}``."""
    secs = {v: 0.0 for v in VARIANTS}
    stats = {v: SearchStats() for v in VARIANTS}
    answers: dict[str, list[tuple[int, float]]] = {v: [] for v in VARIANTS}
    names = list(VARIANTS)
    for fd in folds:
        searchers = {v: FastSearcher(fd["refs"], fd["table"], **kw) for v, kw in VARIANTS.items()}
        for qn, q in enumerate(fd["queries"]):
            for v in names[qn % 2:] + names[:qn % 2]:
                t = time.perf_counter()
                r = searchers[v].search([q], k=1, parallel=False)
                secs[v] += time.perf_counter() - t
                answers[v].append((int(r.indices[0, 0]), float(r.distances[0, 0])))
                s = r.stats
                stats[v].add(np.array([s.candidates, s.pruned, s.abandoned, s.completed, s.range_rejected]))
    on, off = (secs[v] for v in names)
    return {"identical_answers": answers[names[0]] == answers[names[1]],
            "variants": {v: {"seconds": secs[v], "stats": stats[v].as_dict()} for v in names},
            "speedup": off / on if on > 0 else float("inf")}


def stages(folds: list[dict]) -> dict[str, float]:
    """Seconds spent in each of :data:`retrieval.search.STAGES` by the default (serial)
    search, summed over every query of every fold."""
    t = dict.fromkeys(STAGES, 0.0)
    for fd in folds:
        searcher = FastSearcher(fd["refs"], fd["table"])
        for q in fd["queries"]:
            _, times = searcher.profile_stages(q, k=1)
            for key, dt in times.items():
                t[key] += dt
    return t


def run_fast_search_profile(data: str | Path | None = None, fps: float = 120.0, progress: bool = True) -> dict:
    """The whole profile of the module docstring; returns ``{"data", "fps", "queries",
    "note", "compare", "stages_seconds"}``. Runs on one numba thread (restored after)."""
    all_threads = set_threads(None)
    set_threads(1)
    try:
        warm_up()
        folds, source, note = fold_codes(data, fps, progress=progress)
        return {"data": source, "fps": fps, "queries": sum(len(f["queries"]) for f in folds), "note": note,
                "compare": compare(folds), "stages_seconds": stages(folds)}
    finally:
        set_threads(all_threads)


def format_report(result: dict) -> str:
    """The comparison (time, pruning counts, speed-up) and the stage shares."""
    lines = [result["note"]] if result["note"] else []
    lines.append(f"{result['queries']} queries from {result['data']}, {result['fps']:g} fps")
    cmp = result["compare"]
    lines.append(f"identical answers: {cmp['identical_answers']}")
    for v, r in cmp["variants"].items():
        s = r["stats"]
        lines.append(f"{v:<26} {r['seconds']:7.3f} s  pruned {s['pruned']}  abandoned {s['abandoned']} "
                     f"(of which rejected by the range bound {s['range_rejected']})  completed {s['completed']}"
                     f"  / {s['candidates']}")
    lines.append(f"speed-up of the range bound: {cmp['speedup']:.2f}x")
    t = result["stages_seconds"]
    total = sum(t.values()) or 1.0
    lines.append("stages of the default search: "
                 + ", ".join(f"{k} {v:.3f} s ({100 * v / total:.0f} %)" for k, v in t.items()))
    return "\n".join(lines)
