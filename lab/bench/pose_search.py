"""Search by pose on a labelled folder, ``storybeam bench pose-search``.

Method: the library is every clip of the folder at ``fps`` (:class:`PoseSearch`: the
index's code subsequence search, then the feature refinement). For every clip whose class
has a rule in :data:`~retrieval.library.pose_search.CHARACTERISTIC` (jump, kick, run) the
pose at its most characteristic frame is the query and the clip itself is held back
(excluded from the answer: the query never finds its own clip); the top result's class is
compared with the query's. ``search_ms`` is the time from the pose's features to the
answer (encoding, the code search and the refinement), by :func:`time.perf_counter`, one
thread, after one warm-up search, on the DTW back-end asked for (``numpy`` is the path the
tablet runs without numba). The same queries are then answered with the
refinement run on *every* clip (``shortlist`` = the library's size): the two top-1
answers agree where the shortlist loses nothing, and both accuracies are reported.

Held back how: the query's clip is left out of the answer, but the index's PCA and
quantiser (fitted without labels on every frame) did see it. A stricter check,
``held_out_folds``, repeats the accuracy with stratified 3-fold splits (seed 0): each
fold's poses are searched in a pose search built from the other two folds only (its own
PCA and quantiser).
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from app.progress import progress_bar
from retrieval.library import (
    CHARACTERISTIC,
    POSE_FEATURE_SET,
    Clip,
    PoseSearch,
    characteristic_frame,
    load_dataset,
)


def run_pose_search_bench(data: str | Path, fps: float = 30.0, dims: int = 6, k: int = 5,
                          progress: bool = True, backend: str = "auto", against: str | None = None,
                          rounds: int = 5) -> dict:
    """Held-back top-1 class accuracy and search times of pose queries (module docstring);
    with ``against`` (a feature set), also :func:`side_by_side` times of the default set's
    search and a search over ``against``."""
    clips = load_dataset(data, fps=fps, feature_set=POSE_FEATURE_SET,
                         progress=progress_bar("loading", "clip", progress))
    search = PoseSearch.from_clips(clips, dims, backend, feature_set=POSE_FEATURE_SET)
    search.search(clips[0].features[0], k=k)  # warm-up: loads the compiled kernels
    per_class: dict[str, list[bool]] = {}
    per_class_full: dict[str, list[bool]] = {}
    times, agree, queries = [], 0, []
    for c in clips:
        frame = characteristic_frame(c.features, c.label)
        if frame is None:
            continue
        pose = c.features[frame]
        t0 = time.perf_counter()
        hits = search.search(pose, k=k, exclude=c.trial)
        times.append((time.perf_counter() - t0) * 1e3)
        full = search.search(pose, k=1, shortlist=len(search), exclude=c.trial)
        agree += full[0].trial == hits[0].trial
        per_class.setdefault(c.label, []).append(hits[0].label == c.label)
        per_class_full.setdefault(c.label, []).append(full[0].label == c.label)
        queries.append({"trial": c.trial, "label": c.label, "frame": frame, "top": hits[0].as_dict()})
    folds = held_out_folds(clips, dims, backend, k)
    compared = None
    if against is not None:
        other = load_dataset(data, fps=fps, feature_set=against, progress=progress_bar("loading", "clip", progress))
        compared = side_by_side({POSE_FEATURE_SET: (search, clips),
                                 against: (PoseSearch.from_clips(other, dims, backend, feature_set=against), other)},
                                k, rounds)
    t = np.array(times)
    classes = {lab: {"queries": len(v), "correct": int(sum(v)), "accuracy": float(np.mean(v)),
                     "accuracy_full_refinement": float(np.mean(per_class_full[lab]))}
               for lab, v in sorted(per_class.items())}
    return {
        "data": str(data), "fps": fps, "dims": dims, "k": k, "clips": len(clips), "queries": len(times),
        "backend": search.index.backend, "characteristic_frame": CHARACTERISTIC, "classes": classes,
        "search_ms": {"median": float(np.median(t)), "p95": float(np.percentile(t, 95)), "max": float(t.max())},
        "shortlist_agrees_with_full_refinement": f"{agree}/{len(times)}",
        "held_out_folds": folds,
        "side_by_side": compared,
        "threads": {v: os.environ.get(v, "") for v in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS")},
        "queries_detail": queries,
    }


def side_by_side(searches: dict[str, tuple[PoseSearch, list[Clip]]], k: int = 5, rounds: int = 5) -> dict:
    """Search times (ms) of two or more pose searches over the same clips, each with its own
    features, measured interleaved so that the machine's load falls on all alike: in each of
    ``rounds`` rounds every held-back query (the bench's) is answered by every search in
    turn, the order rotating by query and round; median and p95 per search."""
    names = list(searches)
    queries = {n: [(c.features[f], c.trial) for c in clips
                   if (f := characteristic_frame(c.features, c.label)) is not None]
               for n, (_, clips) in searches.items()}
    for n, (search, _) in searches.items():
        search.search(queries[n][0][0], k=k)  # warm-up
    times: dict[str, list[float]] = {n: [] for n in names}
    for r in range(rounds):
        for i in range(len(queries[names[0]])):
            for j in range(len(names)):
                n = names[(i + r + j) % len(names)]
                pose, trial = queries[n][i]
                t0 = time.perf_counter()
                searches[n][0].search(pose, k=k, exclude=trial)
                times[n].append((time.perf_counter() - t0) * 1e3)
    return {"rounds": rounds, "search_ms": {n: {"median": float(np.median(t)), "p95": float(np.percentile(t, 95)),
                                                "queries": len(t)} for n, t in times.items()}}


def held_out_folds(clips: list[Clip], dims: int, backend: str, k: int, n_folds: int = 3, seed: int = 0) -> dict:
    """Top-1 class accuracy per class when each fold is searched in a library built from the
    other folds only (stratified by label, shuffled with ``seed``)."""
    rng = np.random.default_rng(seed)
    fold_of: dict[str, int] = {}
    for label in sorted({c.label for c in clips}):
        members = [c.trial for c in clips if c.label == label]
        for j, i in enumerate(rng.permutation(len(members))):
            fold_of[members[i]] = j % n_folds
    per_class: dict[str, list[bool]] = {}
    for f in range(n_folds):
        search = PoseSearch.from_clips([c for c in clips if fold_of[c.trial] != f], dims, backend)
        for c in clips:
            frame = characteristic_frame(c.features, c.label)
            if fold_of[c.trial] != f or frame is None:
                continue
            top = search.search(c.features[frame], k=k)[0]
            per_class.setdefault(c.label, []).append(top.label == c.label)
    return {"folds": n_folds, "seed": seed,
            "classes": {lab: {"queries": len(v), "accuracy": float(np.mean(v))} for lab, v in sorted(per_class.items())}}


def format_report(r: dict) -> str:
    lines = [f"pose search on {r['data']}: {r['clips']} clips at {r['fps']:g} fps, {r['queries']} held-back "
             f"pose queries ({r['backend']})",
             f"{'class':<8} {'queries':>7} {'top-1 class':>12} {'(every clip refined)':>21}"]
    for lab, c in r["classes"].items():
        lines.append(f"{lab:<8} {c['queries']:>7} {100 * c['accuracy']:>11.1f}% "
                     f"{100 * c['accuracy_full_refinement']:>20.1f}%")
    s = r["search_ms"]
    lines.append(f"search_ms median {s['median']:.2f}, p95 {s['p95']:.2f}, max {s['max']:.2f}; "
                 f"shortlist = full refinement: {r['shortlist_agrees_with_full_refinement']}")
    folds = r["held_out_folds"]
    lines.append(f"held out by {folds['folds']}-fold split (library without the query's fold): " + ", ".join(
        f"{lab} {100 * c['accuracy']:.1f}%" for lab, c in folds["classes"].items()))
    if r.get("side_by_side"):
        lines.append(f"side by side, interleaved, {r['side_by_side']['rounds']} rounds: " + "; ".join(
            f"{n} median {t['median']:.2f} ms, p95 {t['p95']:.2f}" for n, t in r["side_by_side"]["search_ms"].items()))
    return "\n".join(lines)
