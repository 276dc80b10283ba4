"""The product's search method (``storybeam``) at library scale (issue 12).

StoryBeam's own method (:class:`retrieval.library.StoryBeamSearcher`: a code shortlist by
the fast search, then exact float DTW on the ``storybeam`` features re-ranking it) keeps
the float features of every clip, so it cannot run on the codes-only scale library of
``storybeam bench retrieval``. This bench builds the same derived library
(:func:`lab.bench.scale_library.derived_takes`: mirrored, time-scaled, spliced takes of
the real clips, ≥ 2 600 clips and ≥ 9 h at 30 fps) with the ``storybeam`` features kept,
fits the searcher on it, and times the 1-NN of each held-out real clip (a stratified
third of the shared CMU set, none of whose takes the library was derived from) on one
core (numba at one thread, the process pinned to one CPU). Beside it, on the first few
queries, exact DTW on the same features over the whole library (the method's own
baseline, interleaved query by query) gives the speed ratio at this size and how often
the shortlist found exact DTW's nearest clip.

Like ``bench retrieval`` this is a speed test bed: derived clips are transformations of
real ones, so no accuracy is claimed from it.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from lab.bench.retrieval import set_threads
from lab.bench.scale_library import derived_takes
from retrieval.dtw import HAVE_NUMBA, dtw_features
from retrieval.errors import StoryBeamError
from retrieval.features import get_feature_set
from lab.experiment import stratified_folds
from retrieval.library import SHORTLIST, StoryBeamSearcher, load_dataset

FEATURE_SET = "storybeam"


def _pin_one_cpu() -> list[int]:
    """Pin this process to one CPU (the last one it may use); returns the CPUs now allowed."""
    try:
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpus[-1]})
        return sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return []


def run_storybeam_scale_bench(data: str | Path, fps: float = 30.0, min_clips: int = 2600, min_hours: float = 9.0,
                              folds: int = 3, seed: int = 0, baseline_queries: int = 5,
                              shortlist: int = SHORTLIST, progress: bool = True) -> dict:
    """Build, time and compare as in the module docstring; returns the JSON-ready result."""
    if not HAVE_NUMBA:
        raise StoryBeamError("the storybeam-scale bench needs numba (it times the compiled search)")
    started = time.perf_counter()
    clips = load_dataset(data, fps=fps, feature_set=FEATURE_SET)
    if len(clips) < 2 * folds:
        raise StoryBeamError(f"{data}: {len(clips)} clips are too few for {folds} folds")
    parts = stratified_folds([c.label for c in clips], folds, seed)
    query_idx = list(parts[0])
    refs = [clips[i] for i in np.setdiff1d(np.arange(len(clips)), query_idx)]
    cpus = _pin_one_cpu()
    set_threads(1)
    t0 = time.perf_counter()
    library: list[np.ndarray] = []
    labels: list[str] = []
    bar = tqdm(total=min_clips, desc="deriving the library", unit="clip", disable=not progress)
    for label, feats in derived_takes(refs, min_clips, min_hours, seed, feature_set=FEATURE_SET):
        library.append(np.ascontiguousarray(feats, dtype=np.float64))
        labels.append(label)
        bar.update(1)
    bar.close()
    derive_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    searcher = StoryBeamSearcher.fit(library, shortlist=shortlist,
                                     code_columns=get_feature_set(FEATURE_SET).code_columns)
    build_s = time.perf_counter() - t0
    queries = [np.ascontiguousarray(clips[i].features, dtype=np.float64) for i in query_idx]
    searcher.search(queries[0])  # compile and warm up
    dtw_features(queries[0][:5], library[0][:5])
    ms: list[float] = []
    cpu_ms: list[float] = []
    base_ms: list[float] = []
    agree = 0
    n_base = min(baseline_queries, len(queries))
    for qi, q in enumerate(tqdm(queries, desc="1-NN queries", unit="query", disable=not progress)):
        t, c = time.perf_counter(), time.process_time()
        hit = searcher.search(q, k=1)[0]
        ms.append((time.perf_counter() - t) * 1e3)
        cpu_ms.append((time.process_time() - c) * 1e3)
        if qi < n_base:  # the method's own baseline on the same query, right after it
            t = time.perf_counter()
            d = np.array([dtw_features(q, ref) for ref in library])
            base_ms.append((time.perf_counter() - t) * 1e3)
            best = int(np.argmin(d))
            agree += int(hit.index == best or np.isclose(d[best], hit.distance, rtol=0, atol=1e-12))
    frames = int(sum(len(f) for f in library))
    a = np.asarray(ms)
    paired = np.asarray(ms[:n_base])
    return {
        "data": str(data), "fps": fps, "feature_set": FEATURE_SET, "seed": seed, "shortlist": shortlist,
        "pinned_cpus": cpus, "numba_threads": 1,
        "library": {"clips": len(library), "frames": frames, "hours": frames / fps / 3600,
                    "bytes_features": int(sum(f.nbytes for f in library)),
                    "bytes_codes_int16": int(2 * frames),
                    "derive_seconds": derive_s, "build_seconds": build_s},
        "queries": len(queries),
        "search_ms": {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)), "mean": float(a.mean()),
                      "max": float(a.max()), "cpu_median": float(np.median(cpu_ms)),
                      "cpu_p95": float(np.percentile(cpu_ms, 95))},
        "baseline": {"queries": n_base,
                     "exact_dtw_ms_median": float(np.median(base_ms)) if base_ms else None,
                     "storybeam_ms_median_same_queries": float(np.median(paired)) if n_base else None,
                     "ratio_of_medians": float(np.median(base_ms) / np.median(paired)) if n_base else None,
                     "same_nearest_clip": agree},
        "target_ms": 50.0,
        "seconds": time.perf_counter() - started,
    }


def format_table(out: dict) -> str:
    lib, s, b = out["library"], out["search_ms"], out["baseline"]
    lines = [
        f"storybeam method at scale: {lib['clips']} derived clips, {lib['hours']:.1f} h at {out['fps']:g} fps "
        f"(features {lib['bytes_features'] / 2**20:.0f} MiB), {out['queries']} held-out real queries, "
        f"one core (CPUs {out['pinned_cpus']}), shortlist {out['shortlist']}",
        "| measure | value |",
        "|---|---|",
        f"| 1-NN search, median / p95 / max (ms) | {s['median']:.1f} / {s['p95']:.1f} / {s['max']:.1f} |",
        f"| the same, process CPU time, median / p95 (ms) | {s['cpu_median']:.1f} / {s['cpu_p95']:.1f} |",
        f"| target | < {out['target_ms']:.0f} ms: {'met' if s['p95'] < out['target_ms'] else 'not met'} (p95), "
        f"{'met' if s['median'] < out['target_ms'] else 'not met'} (median) |",
    ]
    if b["queries"]:
        lines.append(f"| exact DTW on the same features, first {b['queries']} queries, median (ms) | "
                     f"{b['exact_dtw_ms_median']:.0f} (storybeam {b['storybeam_ms_median_same_queries']:.1f}: "
                     f"{b['ratio_of_medians']:.0f}x) |")
        lines.append(f"| same nearest clip as exact DTW | {b['same_nearest_clip']} of {b['queries']} |")
    lines.append(f"| library derive / index build (s) | {lib['derive_seconds']:.1f} / {lib['build_seconds']:.1f} |")
    return "\n".join(lines)


__all__ = ["run_storybeam_scale_bench", "format_table", "FEATURE_SET"]
