"""The retrieval speed benchmark behind ``storybeam bench retrieval``.

One run measures, side by side in one process (so machine load hits every method alike),
every search on one core (one numba thread), per query, methods interleaved in a rotating
order after a warm-up query, reporting median, p95 and total per method and the ratios of
medians and of totals:

1. **same distance (look-up DTW over codes)** — the fast search
   (:mod:`retrieval.search.fast`), the seed's brute force (full table, every clip), and a
   UCR-suite-style exact rival (:mod:`lab.bench.ucr_rival`: LB_Kim, LB_Keogh both ways,
   bound order, EAPrunedDTW-style early abandoning) in both of its strategies, the faster
   (lower total) on each data set being "the rival" of the ratios (``rival_strategy``)
   — on the paper protocol (stratified
   3-fold 1-NN over the labelled clips, 120 fps) and on a derived library
   (:mod:`lab.bench.scale_library`, ≥ 2 600 clips / 9 h, 30 fps) and a ten times bigger
   one; the three must give the same clip at the same distance on every query
   (``same_answers``). This is the headline.
2. **float-feature DTW** (what a user would pick instead; *another distance*) — brute
   force (numba) and dtaidistance's C DTW with ``inner_dist='euclidean'``,
   ``use_pruning=True`` and ``max_dist`` = best so far, in UCR order; the 1-NN accuracy
   of each distance on the protocol.
3. **the ablations** of the fast search, through
   :func:`lab.experiment.evaluation.evaluate` (total seconds per fold loop);
4. **latency against library size** (1×, 3×, 10× the derived library, the same queries
   for every method) and **memory** (table layouts, index bytes per clip).

Times of the code methods start from the query's codes; the float methods' from its features.
"""
from __future__ import annotations

import os
import platform
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from tqdm import tqdm

from lab.bench.scale_library import build_scale_library
from lab.bench.ucr_rival import STRATEGIES, UCRRival
from app.paths import MOTIONS_DIR, SHARED_CMU
from app.progress import progress_bar
from retrieval.codes import DiffTable, Quantizer, table_bytes
from retrieval.dtw import HAVE_NUMBA, dtw_codes, dtw_features
from retrieval.dtw.jit import numba
from retrieval.errors import StoryBeamError
from lab.experiment import FastMatcher, evaluate, make_matcher, stack_frames, stratified_folds
from retrieval.library import Clip, load_dataset
from retrieval.search import FastSearcher, SearchStats
from retrieval.search import warm_up as warm_up_fast

#: the bundled library (the fallback when the shared CMU set is absent)
BUNDLED_LIBRARY = MOTIONS_DIR
#: the shared CMU set beside the checkout ($STORYBEAM_SHARED_DATA/cmu)

#: Protocol rows: (method key in ``protocol``, label printed in the table, distance).
PROTOCOL_ROWS = (
    ("fast", "fast exact search", "codes"),
    ("ucr_rival", "UCR-suite-style rival (lab/bench/ucr_rival.py)", "codes"),
    ("quantized", "seed method (full table, every clip)", "codes"),
    ("dtw", "exact DTW on features (numba, every clip)", "float"),
    ("dtaidistance", "dtaidistance, euclidean, pruned, UCR order", "float"),
)
ABLATION_ROWS = (
    ("fast_parallel", "fast exact, bounds in prange (all cores)"),
    ("diff_brute", "difference table, brute force (plain DP)"),
    ("bounds_plain", "+ bounds, abandoning, corridor (plain DP)"),
    ("runs_approx", "run-length block-corner approximation"),
    ("band", "fast exact with Sakoe-Chiba band"),
)


def load_clips(data: str | Path | None, fps: float, progress: bool) -> tuple[list[Clip], str, str | None]:
    """Clips of ``data``, else the shared CMU set, else the bundled library (with a note)."""
    note = None
    if data is None:
        if (SHARED_CMU / "labels.csv").is_file():
            data = SHARED_CMU
        else:
            data = BUNDLED_LIBRARY
            note = (f"shared CMU data not found at {SHARED_CMU}: benchmarking the bundled library "
                    f"({BUNDLED_LIBRARY}) instead — numbers are not comparable to the paper protocol")
    clips = load_dataset(data, fps=fps, progress=progress_bar(f"loading {Path(data).name}", "clip", progress))
    return clips, str(data), note


def _matcher_factory(band_frames: int, registry: list):
    def factory(name, dims=6, band=None, forbes_clusters=None, seed=0, **extra):
        specs = {
            "fast": dict(),
            "fast_parallel": dict(parallel=True),
            "diff_brute": dict(run_length=False, use_bounds=False),
            "bounds_plain": dict(run_length=False),
            "runs_approx": dict(mode="runs"),
            "band": dict(band=band_frames),
        }
        if name in specs:
            m = FastMatcher(name, dims, **specs[name])
            registry.append(m)
            return m
        return make_matcher(name, dims=dims, band=band, forbes_clusters=forbes_clusters, seed=seed, **extra)
    return factory


def set_threads(n: int | None) -> int:
    """Set numba's thread count (``None``: all of them); returns the count (1 without numba)."""
    if not HAVE_NUMBA:
        return 1
    if n is None:
        n = numba.config.NUMBA_NUM_THREADS
    numba.set_num_threads(int(n))
    return int(n)


def _stats(ms: Sequence[float]) -> dict:
    a = np.asarray(ms, dtype=np.float64)
    return {"ms_median": float(np.median(a)), "ms_p95": float(np.percentile(a, 95)), "ms_total": float(a.sum()),
            "queries": int(a.size)}


def interleaved(methods: dict[str, Callable[[int], tuple[int, float]]], n_queries: int, progress: bool = False,
                desc: str = "") -> tuple[dict[str, list[float]], dict[str, list[tuple[int, float]]]]:
    """Time every method on every query, interleaved: query i runs the methods in an order
    rotated by i (so drifting machine load and cache state hit every method alike), each
    call timed alone with ``time.perf_counter``. Every method answers query 0 once first,
    untimed (warm-up). Returns per-method milliseconds and answers ``(index, distance)``."""
    names = list(methods)
    for name in names:
        methods[name](0)
    times: dict[str, list[float]] = {n: [] for n in names}
    answers: dict[str, list[tuple[int, float]]] = {n: [] for n in names}
    for qi in tqdm(range(n_queries), desc=desc, unit="query", disable=not progress, leave=False):
        r = qi % len(names)
        for name in names[r:] + names[:r]:
            t = time.perf_counter()
            ans = methods[name](qi)
            times[name].append((time.perf_counter() - t) * 1e3)
            answers[name].append(ans)
    return times, answers


def _brute_codes(library: Sequence[np.ndarray], table: np.ndarray) -> Callable[[np.ndarray], tuple[int, float]]:
    """The seed's method: look-up DTW (full table) against every clip, first minimum."""
    def run(q: np.ndarray) -> tuple[int, float]:
        d = np.array([dtw_codes(q, r, table) for r in library])
        i = int(np.argmin(d))
        return i, float(d[i])
    return run


def _fast(searcher: FastSearcher) -> Callable[[np.ndarray], tuple[int, float]]:
    def run(q: np.ndarray) -> tuple[int, float]:
        res = searcher.search([q], k=1, parallel=False)
        return int(res.indices[0, 0]), float(res.distances[0, 0])
    return run


def _rival(rival: UCRRival) -> Callable[[np.ndarray], tuple[int, float]]:
    def run(q: np.ndarray) -> tuple[int, float]:
        r = rival.search(q)
        return r.index, r.distance
    return run


#: the rival's strategies as bench methods; "ucr_rival" is the faster of them on each data set
RIVALS = tuple(f"ucr_rival_{s}" for s in STRATEGIES)


def _rivals(library: Sequence[np.ndarray], table: DiffTable) -> dict[str, Callable[[np.ndarray], tuple[int, float]]]:
    """The rival in each of its strategies (:data:`RIVALS`)."""
    return {f"ucr_rival_{s}": _rival(UCRRival(library, table, s)) for s in STRATEGIES}


def _pick_rival(times: dict[str, list[float]], answers: dict[str, list[tuple[int, float]]] | None = None) -> str:
    """Add ``"ucr_rival"``: the strategy of :data:`RIVALS` with the lower total time on this
    data set (the rival as a specialist would configure it for that data); returns the
    strategy's name."""
    best = min(RIVALS, key=lambda n: sum(times[n]))
    times["ucr_rival"] = times[best]
    if answers is not None:
        answers["ucr_rival"] = answers[best]
    return best.removeprefix("ucr_rival_")


def _float_brute(library: Sequence[np.ndarray]) -> Callable[[np.ndarray], tuple[int, float]]:
    """Exact DTW on the real features (Euclidean frame cost, numba) against every clip."""
    def run(x: np.ndarray) -> tuple[int, float]:
        d = np.array([dtw_features(x, r) for r in library])
        i = int(np.argmin(d))
        return i, float(d[i])
    return run


class DtaidistancePruned:
    """dtaidistance's C DTW configured as its authors advise for a nearest-neighbour
    search: ``dtw_ndim.distance(a, b, inner_dist='euclidean', use_pruning=True,
    max_dist=<best so far>, use_c=True)`` — with ``inner_dist='euclidean'`` it is the
    project's float-feature DTW (frame cost = Euclidean distance; default would be squared
    Euclidean, another distance) — candidates visited in the UCR order: sorted by
    max(LB_Kim, LB_Keogh both ways), where with no window a clip's envelope is its
    bounding box per dimension (every frame cost ≥ the distance from a frame to the other
    clip's box), stopping at the first bound above the best so far."""

    def __init__(self, library: Sequence[np.ndarray]):
        try:
            from dtaidistance import dtw_ndim  # optional: dtaidistance (a speed peer only, not a dependency)
        except ImportError as exc:
            raise StoryBeamError(f"dtaidistance is not installed: {exc}") from None
        self._distance = dtw_ndim.distance
        self.library = [np.ascontiguousarray(r, dtype=np.float64) for r in library]
        self.lo = np.array([r.min(axis=0) for r in self.library])
        self.hi = np.array([r.max(axis=0) for r in self.library])
        self.first = np.array([r[0] for r in self.library])
        self.last = np.array([r[-1] for r in self.library])
        self.lengths = np.array([len(r) for r in self.library], dtype=np.float64)

    @staticmethod
    def _box_sum(frames: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Σ over frames of the Euclidean distance to each box (lo, hi): (boxes,)."""
        ex = np.maximum(lo[None, :, :] - frames[:, None, :], 0.0) + np.maximum(frames[:, None, :] - hi[None, :, :], 0.0)
        return np.sqrt((ex * ex).sum(axis=2)).sum(axis=0)

    def bounds(self, x: np.ndarray) -> np.ndarray:
        kim = np.linalg.norm(self.first - x[0], axis=1) + np.linalg.norm(self.last - x[-1], axis=1)
        eq = self._box_sum(x, self.lo, self.hi)
        ec = np.array([self._box_sum(r, x.min(axis=0)[None], x.max(axis=0)[None])[0] for r in self.library])
        return np.maximum(np.maximum(kim, eq), ec) * (1.0 - 1e-9) / (len(x) + self.lengths)

    def __call__(self, x: np.ndarray) -> tuple[int, float]:
        x = np.ascontiguousarray(x, dtype=np.float64)
        lbs = self.bounds(x)
        best_d, best_i = np.inf, -1
        for c in np.argsort(lbs, kind="stable"):
            if lbs[c] > best_d:
                break
            norm = len(x) + self.lengths[c]
            kw = {} if best_d == np.inf else {"max_dist": best_d * norm * (1.0 + 1e-9)}
            d = self._distance(x, self.library[c], use_c=True, inner_dist="euclidean", use_pruning=True, **kw) / norm
            if d < best_d or (d == best_d and c < best_i):
                best_d, best_i = d, int(c)
        return best_i, float(best_d)


def _same(answers: dict[str, list[tuple[int, float]]], names: Sequence[str]) -> bool:
    ref = answers[names[0]]
    return all(answers[n] == ref for n in names[1:])


def _ratio(times: dict[str, list[float]], slow: str, fast: str) -> dict:
    a, b = _stats(times[slow]), _stats(times[fast])
    return {"median": a["ms_median"] / b["ms_median"], "total": a["ms_total"] / b["ms_total"]}


def _protocol_interleaved(clips: Sequence[Clip], folds: int, dims: int, seed: int, progress: bool) -> dict:
    """Per-query, interleaved timing of every method on the paper protocol (one core)."""
    parts = stratified_folds([c.label for c in clips], folds, seed)
    names = ("fast", *RIVALS, "brute_codes", "brute_float", "dtaidistance_pruned")
    times: dict[str, list[float]] = {n: [] for n in names}
    answers: dict[str, list[tuple[int, float]]] = {n: [] for n in names}
    correct: dict[str, int] = {n: 0 for n in names}
    for f, q_idx in enumerate(parts):
        r_idx = np.setdiff1d(np.arange(len(clips)), q_idx)
        refs = [clips[i] for i in r_idx]
        quant = Quantizer.fit(stack_frames([c.features for c in refs]), dims)
        table = DiffTable.from_ratios(quant.ratios)
        ref_codes = [quant.encode(c.features) for c in refs]
        q_codes = [quant.encode(clips[i].features) for i in q_idx]
        q_feats = [np.ascontiguousarray(clips[i].features, dtype=np.float64) for i in q_idx]
        fast, rivals = _fast(FastSearcher(ref_codes, table)), _rivals(ref_codes, table)
        brute = _brute_codes(ref_codes, quant.table())
        fbrute = _float_brute([c.features for c in refs])
        dtai = DtaidistancePruned([c.features for c in refs])
        methods = {"fast": lambda i: fast(q_codes[i]),
                   **{n: (lambda i, r=r: r(q_codes[i])) for n, r in rivals.items()},
                   "brute_codes": lambda i: brute(q_codes[i]), "brute_float": lambda i: fbrute(q_feats[i]),
                   "dtaidistance_pruned": lambda i: dtai(q_feats[i])}
        t, a = interleaved(methods, len(q_idx), progress, f"protocol fold {f + 1}/{folds}, interleaved")
        for n in names:
            times[n] += t[n]
            answers[n] += a[n]
            correct[n] += sum(refs[i].label == clips[q].label for (i, _), q in zip(a[n], q_idx))
    strategy = _pick_rival(times, answers)
    correct["ucr_rival"] = correct[f"ucr_rival_{strategy}"]
    out = {n: {**_stats(times[n]), "accuracy": correct[n] / len(clips)} for n in (*names, "ucr_rival")}
    return {"methods": out, "rival_strategy": strategy,
            "same_answers_codes": _same(answers, ("fast", *RIVALS, "brute_codes")),
            "same_answers_float": [i for i, _ in answers["brute_float"]] == [i for i, _ in answers["dtaidistance_pruned"]],
            "float_max_rel_diff": max(abs(a[1] - b[1]) / max(abs(b[1]), 1e-300)
                                      for a, b in zip(answers["dtaidistance_pruned"], answers["brute_float"])),
            "code_vs_float_different_nn": sum(a[0] != b[0] for a, b in zip(answers["brute_codes"], answers["brute_float"])),
            "queries": len(clips),
            "vs_ucr_codes": _ratio(times, "ucr_rival", "fast"),
            "vs_brute_codes": _ratio(times, "brute_codes", "fast"),
            "dtaidistance_vs_ucr_codes": _ratio(times, "dtaidistance_pruned", "ucr_rival")}


def _prefix_reaching(codes: Sequence[np.ndarray], fps: float, min_clips: int, min_hours: float) -> int:
    """How many clips of the (deterministic) derived stream reach both targets — the size of
    :func:`build_scale_library` with those targets and the same seed."""
    frames = np.cumsum([len(c) for c in codes])
    ok = np.flatnonzero((np.arange(1, len(codes) + 1) >= min_clips) & (frames >= min_hours * 3600 * fps))
    if len(ok) == 0:
        raise StoryBeamError("scale library: the big library is smaller than the small one")
    return int(ok[0]) + 1


def run_retrieval_bench(data: str | Path | None = None, fps: float = 120.0, scale_fps: float = 30.0,
                        quick: bool = False, dims: int = 6, folds: int = 3, seed: int = 0,
                        plot: str | Path | None = None, progress: bool = True) -> dict:
    """Everything in the module docstring; returns the JSON-ready result dictionary."""
    if not HAVE_NUMBA:
        raise StoryBeamError("the retrieval benchmark needs numba (it compares the compiled kernels)")
    started = time.perf_counter()
    if quick and data is None:
        data = BUNDLED_LIBRARY
    clips, source, note = load_clips(data, fps, progress)
    if note:
        print(note)
    all_threads = set_threads(None)
    warm_up_fast()
    band_frames = int(round(0.5 * fps))
    registry: list[FastMatcher] = []
    set_threads(1)  # every figure below is one core but the parallel ablation and row
    factory = _matcher_factory(band_frames, registry)

    def threaded_factory(name, **kw):
        m = factory(name, **kw)
        if name == "fast_parallel":
            inner = m.distances

            def distances(query):
                set_threads(all_threads)
                try:
                    return inner(query)
                finally:
                    set_threads(1)
            m.distances = distances
        return m

    # ---------------------------------------------------------------- protocol
    methods = ["fast"] + [m for m, _ in ABLATION_ROWS]
    res = evaluate(clips, methods, folds, dims, seed, progress=progress_bar("ablations", "fold", progress),
                   matcher_factory=threaded_factory)
    protocol = {m: {"seconds": r.search_seconds, "accuracy": r.accuracy, "balanced_accuracy": r.balanced_accuracy,
                    "build_seconds": r.build_seconds} for m, r in res.items()}
    stats: dict[str, SearchStats] = {}
    for m in registry:
        s = stats.setdefault(m.name, SearchStats())
        s.candidates += m.stats.candidates
        s.pruned += m.stats.pruned
        s.abandoned += m.stats.abandoned
        s.completed += m.stats.completed
        s.range_rejected += m.stats.range_rejected
    for name, s in stats.items():
        protocol[name].update(s.as_dict())
    inter = _protocol_interleaved(clips, folds, dims, seed, progress)
    im = inter["methods"]
    for key, name in (("quantized", "brute_codes"), ("ucr_rival", "ucr_rival"), ("dtw", "brute_float"),
                      ("dtaidistance", "dtaidistance_pruned")):
        protocol[key] = {"seconds": im[name]["ms_total"] / 1e3, "accuracy": im[name]["accuracy"]}

    # ---------------------------------------------------------------- scale
    scale_clips = clips if scale_fps == fps else load_clips(source, scale_fps, progress)[0]
    parts = stratified_folds([c.label for c in scale_clips], folds, seed)
    query_idx = parts[0]
    ref_idx = np.setdiff1d(np.arange(len(scale_clips)), query_idx)
    refs = [scale_clips[i] for i in ref_idx]
    quant = Quantizer.fit(stack_frames([c.features for c in refs]), dims)
    # the library (>= 2 600 clips, >= 9 h) is the first clips of the big one (>= 30 000 clips, >= 90 h):
    # the derived stream is deterministic for a seed, so both are what build_scale_library makes alone
    (min_clips, min_hours), (big_clips, big_hours) = ((300, 0.25), (900, 0.75)) if quick else ((2600, 9.0), (30000, 90.0))
    big = build_scale_library(refs, quant, min_clips=big_clips, min_hours=big_hours, seed=seed, progress=progress)
    n_small = _prefix_reaching(big.codes, big.fps, min_clips, min_hours)
    table = DiffTable.from_ratios(quant.ratios)
    seed_table = quant.table()
    queries = [quant.encode(scale_clips[i].features) for i in query_idx]
    if quick:
        queries = queries[:5]
    t0 = time.perf_counter()
    searcher = FastSearcher(big.codes[:n_small], table)
    index_seconds = time.perf_counter() - t0
    small = {"fast": _fast(searcher), **_rivals(big.codes[:n_small], table),
             "brute_codes": _brute_codes(big.codes[:n_small], seed_table)}
    lt, la = interleaved({n: (lambda i, f=f: f(queries[i])) for n, f in small.items()}, len(queries), progress,
                         f"{n_small} clips, interleaved")
    same_small = _same(la, ("fast", *RIVALS, "brute_codes"))
    small_strategy = _pick_rival(lt, la)
    set_threads(all_threads)
    many = []
    for q in queries:
        t = time.perf_counter()
        searcher.search([q], parallel=True)
        many.append((time.perf_counter() - t) * 1e3)
    set_threads(1)
    big_searcher = FastSearcher(big.codes, table)
    big_fast = _fast(big_searcher)
    bt, ba = interleaved({"fast": lambda i: big_fast(queries[i]),
                          **{n: (lambda i, r=r: r(queries[i])) for n, r in _rivals(big.codes, table).items()}},
                         len(queries), progress, f"{big.clips} clips, interleaved")
    same_big = _same(ba, ("fast", *RIVALS))
    big_strategy = _pick_rival(bt, ba)
    # latency against library size: the same queries for every method and size
    sizes = sorted({n_small, min(big.clips, 3 * n_small), big.clips})
    curve_q = queries[: (3 if quick else 8)]
    curve = []
    for n in tqdm(sizes, desc="latency vs library size", unit="size", disable=not progress, leave=False):
        ms = {"fast": _fast(FastSearcher(big.codes[:n], table)), **_rivals(big.codes[:n], table),
              "brute_codes": _brute_codes(big.codes[:n], seed_table)}
        ct, ca = interleaved({k: (lambda i, f=f: f(curve_q[i])) for k, f in ms.items()}, len(curve_q))
        strategy = _pick_rival(ct, ca)
        curve.append({"clips": n, "hours": sum(len(c) for c in big.codes[:n]) / big.fps / 3600,
                      "same_answers": _same(ca, tuple(ms)), "rival_strategy": strategy,
                      **{f"{k}_ms_median": float(np.median(v)) for k, v in ct.items()}})
    set_threads(all_threads)
    plot_path = plot_latency_curve(curve, plot) if plot else None

    small_stats = {n: _stats(v) for n, v in lt.items()}
    big_stats = {n: _stats(v) for n, v in bt.items()}
    lib_ratio = _ratio(lt, "ucr_rival", "fast")
    fast_total = im["fast"]["ms_total"] / 1e3
    out = {
        "vs_ucr_codes_median": lib_ratio["median"],
        "vs_ucr_codes_total": lib_ratio["total"],
        "protocol_vs_ucr_codes_median": inter["vs_ucr_codes"]["median"],
        "protocol_vs_ucr_codes_total": inter["vs_ucr_codes"]["total"],
        "same_answers": bool(same_small and inter["same_answers_codes"] and same_big
                             and all(c["same_answers"] for c in curve)),
        "library_clips": n_small,
        "library_hours": sum(len(c) for c in big.codes[:n_small]) / big.fps / 3600,
        "library_fps": big.fps,
        "big_library_clips": big.clips,
        "big_library_hours": big.hours,
        "big_library_ms_median": big_stats["fast"]["ms_median"],
        "big_library_ms_p95": big_stats["fast"]["ms_p95"],
        "big_library_bytes_per_clip": big_searcher.index_bytes_per_clip,
        "big_library_vs_ucr_codes_median": _ratio(bt, "ucr_rival", "fast")["median"],
        "big_library_vs_ucr_codes_total": _ratio(bt, "ucr_rival", "fast")["total"],
        "rival_strategy": {"protocol": inter["rival_strategy"], "library": small_strategy, "big_library": big_strategy},
        "library": {"methods": small_stats, "same_answers": same_small,
                    "vs_brute_codes": _ratio(lt, "brute_codes", "fast"),
                    "rival_faster_queries": int(sum(r < f for r, f in zip(lt["ucr_rival"], lt["fast"])))},
        "big_library": {"methods": big_stats, "same_answers_fast_rival": same_big},
        "protocol_interleaved": inter,
        "protocol": protocol,
        # kept for older readers; "exact_dtw" and "dtaidistance" are *float-feature* DTW, another distance
        "speedup_vs_exact_dtw": im["brute_float"]["ms_total"] / 1e3 / fast_total,
        "speedup_vs_dtaidistance": im["dtaidistance_pruned"]["ms_total"] / 1e3 / fast_total,
        "speedup_vs_seed_method": im["brute_codes"]["ms_total"] / 1e3 / fast_total,
        "query_ms_median": small_stats["fast"]["ms_median"],
        "query_ms_p95": small_stats["fast"]["ms_p95"],
        "query_ms_median_all_cores": float(np.median(many)),
        "query_ms_p95_all_cores": float(np.percentile(many, 95)),
        "library_note": ("derived from the non-query folds of the source clips by mirroring, time scaling "
                         "0.8-1.25 and same-class splicing (lab/bench/augment.py); codes only; the library is "
                         "the first library_clips clips of the big one"),
        "latency_queries": len(queries),
        "index_build_seconds": index_seconds,
        "table_bytes": table.nbytes,
        "table_bytes_by_layout": {lay: table_bytes(lay, dims) for lay in ("diff", "component", "full")},
        "index_bytes_per_clip": searcher.index_bytes_per_clip,
        "codes_bytes_per_clip": 4 * sum(len(c) for c in big.codes[:n_small]) / n_small,
        "ablations": {m: {**protocol[m], "speedup_vs_seed_method": protocol["quantized"]["seconds"] / protocol[m]["seconds"]}
                      for m, _ in ABLATION_ROWS},
        "latency_vs_library_size": curve,
        "curve_queries": len(curve_q),
        "plot": str(plot_path) if plot_path else None,
        "settings": {"data": source, "clips": len(clips), "motion_seconds": sum(c.seconds for c in clips),
                     "fps": fps, "scale_fps": scale_fps, "dims": dims, "folds": folds, "seed": seed,
                     "band_frames": band_frames, "quick": quick, "threads_all": all_threads,
                     "timing": "per query, from codes (code methods) or features (float methods), methods "
                               "interleaved in rotating order, one numba thread, after one warm-up query",
                     "note": note},
        "machine": machine_info(),
        "total_seconds": time.perf_counter() - started,
    }
    return out


def plot_latency_curve(curve: list[dict], path: str | Path) -> Path:
    import matplotlib  # optional: matplotlib (only for --plot)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # optional: matplotlib (only for --plot)

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    n = [c["clips"] for c in curve]
    fig, ax = plt.subplots(figsize=(5.0, 3.4), dpi=110)
    ax.loglog(n, [c["fast_ms_median"] for c in curve], "o-", label="fast exact search")
    ax.loglog(n, [c["ucr_rival_ms_median"] for c in curve], "^-.", label="UCR-suite-style rival")
    ax.loglog(n, [c["brute_codes_ms_median"] for c in curve], "s--", label="seed method (every clip)")
    ax.axhline(50, color="grey", lw=0.8, ls=":", label="50 ms")
    ax.set_xlabel("library size (clips; derived library, 30 fps codes)")
    ax.set_ylabel("1-NN query time, median (ms, 1 core)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (Linux), else what :mod:`platform` knows:
    ratios against other runs only compare on the same model."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_info() -> dict:
    """What a reader needs to compare this run with another: cores, CPU model, load."""
    return {"cpus": os.cpu_count(), "cpu_model": cpu_model(), "load_average_at_end": list(os.getloadavg()),
            "python": platform.python_version(), "processor": platform.processor() or platform.machine()}


def format_report(out: dict) -> str:
    p = out["protocol"]
    s = out["settings"]
    pi = out["protocol_interleaved"]["methods"]
    lines = [f"paper protocol: {s['clips']} clips ({s['motion_seconds']:.0f} s) from {s['data']}, "
             f"{s['folds']}-fold 1-NN, {s['fps']:g} fps, n = {s['dims']}; per query, interleaved, 1 core",
             f"{'method':<50}{'distance':>9}{'median ms':>11}{'p95 ms':>9}{'total s':>9}{'accuracy %':>12}"]
    keys = {"fast": "fast", "ucr_rival": "ucr_rival", "quantized": "brute_codes", "dtw": "brute_float",
            "dtaidistance": "dtaidistance_pruned"}
    for m, label, dist in PROTOCOL_ROWS:
        r = pi[keys[m]]
        lines.append(f"{label:<50}{dist:>9}{r['ms_median']:>11.2f}{r['ms_p95']:>9.2f}{r['ms_total'] / 1e3:>9.3f}"
                     f"{100 * r['accuracy']:>12.2f}")
    inter = out["protocol_interleaved"]
    lines += [f"UCR rival = its faster strategy here: {inter['rival_strategy']} (cascade total "
              f"{pi['ucr_rival_cascade']['ms_total'] / 1e3:.3f} s, sorted {pi['ucr_rival_sorted']['ms_total'] / 1e3:.3f} s)",
              f"same distance, fast vs UCR rival: {out['protocol_vs_ucr_codes_median']:.1f}x (medians), "
              f"{out['protocol_vs_ucr_codes_total']:.1f}x (totals); vs the seed's brute force "
              f"{inter['vs_brute_codes']['median']:.1f}x / {inter['vs_brute_codes']['total']:.1f}x; "
              f"same answers: {inter['same_answers_codes']}",
              f"float-feature DTW (another distance: different nearest clip on {inter['code_vs_float_different_nn']} "
              f"of {inter['queries']} queries): dtaidistance pruned vs brute force same answers "
              f"{inter['same_answers_float']} (max rel. diff {inter['float_max_rel_diff']:.1e})",
              "",
              f"ablations (total search s over the protocol, 1 core unless said; {s['folds']} folds)",
              f"{'method':<48}{'search s':>10}{'accuracy %':>12}{'pruned %':>10}"]
    for m, label in ABLATION_ROWS:
        r = p[m]
        pr = f"{100 * r['pruned_fraction']:.1f}" if "pruned_fraction" in r else "-"
        lines.append(f"{label:<48}{r['seconds']:>10.3f}{100 * r['accuracy']:>12.2f}{pr:>10}")
    lib, big = out["library"]["methods"], out["big_library"]["methods"]
    lines += [
        "",
        f"derived library: {out['library_clips']} clips, {out['library_hours']:.2f} h at {out['library_fps']:g} fps "
        f"(codes only), {out['latency_queries']} held-out queries, per query, interleaved, 1 core",
        f"{'method':<50}{'median ms':>11}{'p95 ms':>9}{'total s':>9}",
    ]
    for name in lib:
        r = lib[name]
        lines.append(f"{name:<50}{r['ms_median']:>11.2f}{r['ms_p95']:>9.2f}{r['ms_total'] / 1e3:>9.3f}")
    lines += [
        f"speed-up (same distance) vs UCR rival ({out['rival_strategy']['library']}): "
        f"{out['vs_ucr_codes_median']:.1f}x medians, "
        f"{out['vs_ucr_codes_total']:.1f}x totals; rival faster on {out['library']['rival_faster_queries']} of "
        f"{out['latency_queries']} queries; same answers: {out['library']['same_answers']}",
        f"big library: {out['big_library_clips']} clips, {out['big_library_hours']:.1f} h: fast median "
        f"{big['fast']['ms_median']:.2f} ms, p95 {big['fast']['ms_p95']:.2f} ms; rival "
        f"({out['rival_strategy']['big_library']}) median "
        f"{big['ucr_rival']['ms_median']:.2f} ms, p95 {big['ucr_rival']['ms_p95']:.2f} ms "
        f"({out['big_library_vs_ucr_codes_median']:.1f}x / {out['big_library_vs_ucr_codes_total']:.1f}x); "
        f"{out['big_library_bytes_per_clip']:.0f} B per clip",
        f"all cores ({s['threads_all']}), derived library: fast median {out['query_ms_median_all_cores']:.2f} ms, "
        f"p95 {out['query_ms_p95_all_cores']:.2f} ms",
        f"latency vs size ({out['curve_queries']} queries, median ms, fast / rival / seed): " + ", ".join(
            f"{c['clips']}: {c['fast_ms_median']:.2f} / {c['ucr_rival_ms_median']:.2f} / {c['brute_codes_ms_median']:.0f}"
            for c in out["latency_vs_library_size"]),
        f"same answers everywhere (fast, rival, brute force where run): {out['same_answers']}",
        f"distance structure: {out['table_bytes']} B (difference table; component "
        f"{out['table_bytes_by_layout']['component']} B; seed's full table {out['table_bytes_by_layout']['full']} B); "
        f"index {out['index_bytes_per_clip']:.0f} B per clip (codes alone {out['codes_bytes_per_clip']:.0f} B)",
        f"{out['machine'].get('cpu_model', '?')}; "
        f"load average at the end: {', '.join(f'{x:.2f}' for x in out['machine']['load_average_at_end'])} "
        f"on {out['machine']['cpus']} CPUs; whole run {out['total_seconds']:.0f} s",
    ]
    return "\n".join(lines)
