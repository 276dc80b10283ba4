"""The retrieval speed benchmark behind ``storybeam bench retrieval``.

One run measures, side by side in one process (so machine load hits every method alike):

1. **the paper protocol** — stratified 3-fold 1-NN on the labelled clips (shared CMU set,
   or the bundled library when that is absent), every method on the same folds, features
   and frame rate, through :func:`retrieval.experiment.evaluation.evaluate`: the fast exact search
   (:mod:`retrieval.search.fast`, one core), the seed's method (full table, no pruning),
   exact DTW on the real features (numba), dtaidistance's C DTW on the same features, and
   the ablations (difference table without pruning, bounds without run-length, the
   run-length approximation, a Sakoe–Chiba band, the fast search with parallel bounds);
2. **library scale** — a derived ≥ 2 600-clip / ≥ 9-hour library
   (:mod:`app.bench.scale_library`) built from the non-query folds, 1-NN latency of real
   held-out queries on one core and on all cores, and latency against library size (plot);
3. **memory** — bytes of each distance-structure layout and of the index per clip.

Search time always includes turning the query's features into codes.
"""
from __future__ import annotations

import os
import platform
import time
from pathlib import Path
from typing import Sequence

import numpy as np
from tqdm import tqdm

from app.bench.scale_library import build_scale_library
from app.paths import MOTIONS_DIR, SHARED_CMU
from app.progress import progress_bar
from retrieval.codes import DiffTable, Quantizer, table_bytes
from retrieval.dtw import HAVE_NUMBA, dtw_codes
from retrieval.dtw.jit import numba
from retrieval.errors import StoryBeamError
from retrieval.experiment import FastMatcher, evaluate, make_matcher, stack_frames, stratified_folds
from retrieval.library import Clip, load_dataset
from retrieval.search import FastSearcher, SearchStats
from retrieval.search import warm_up as warm_up_fast

#: the bundled library (the fallback when the shared CMU set is absent)
BUNDLED_LIBRARY = MOTIONS_DIR
#: the shared CMU set beside the checkout ($STORYBEAM_SHARED_DATA/cmu)

#: Protocol rows: (method name, label printed in the table).
PROTOCOL_ROWS = (
    ("fast", "fast exact search (1 core)"),
    ("quantized", "seed method (full table, no pruning)"),
    ("dtw", "exact DTW on features (numba)"),
    ("dtaidistance", "dtaidistance C DTW on features"),
)
ABLATION_ROWS = (
    ("fast_parallel", "fast exact, bounds in prange (all cores)"),
    ("diff_brute", "difference table, brute force (plain DP)"),
    ("bounds_plain", "+ bounds, abandoning, corridor (plain DP)"),
    ("runs_approx", "run-length block-corner approximation"),
    ("band", "fast exact with Sakoe-Chiba band"),
)


class DtaidistanceMatcher:
    """dtaidistance's C DTW (``dtw_ndim.distance(a, b, use_c=True)``, float64) on the
    same 17-D features: its own distance (square root of summed squared Euclidean frame
    costs), divided by ``len(a) + len(b)`` like ours."""

    name = "dtaidistance"

    def __init__(self):
        try:
            from dtaidistance import dtw_ndim  # optional: dtaidistance (a speed peer only, not a dependency)
        except ImportError as exc:
            raise StoryBeamError(f"dtaidistance is not installed: {exc}") from None
        self._distance = dtw_ndim.distance
        self.references: list[np.ndarray] = []

    def fit(self, references: Sequence[Clip]) -> "DtaidistanceMatcher":
        self.references = [np.ascontiguousarray(c.features, dtype=np.float64) for c in references]
        return self

    def distances(self, query: Clip) -> np.ndarray:
        q = np.ascontiguousarray(query.features, dtype=np.float64)
        return np.array([self._distance(q, r, use_c=True) / (len(q) + len(r)) for r in self.references])


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
        if name == "dtaidistance":
            return DtaidistanceMatcher()
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


def _latencies(searcher: FastSearcher, queries: Sequence[np.ndarray], parallel: bool, progress: bool,
               desc: str) -> np.ndarray:
    searcher.search([queries[0]], parallel=parallel)  # warm caches
    out = []
    for q in tqdm(queries, desc=desc, unit="query", disable=not progress, leave=False):
        t = time.perf_counter()
        searcher.search([q], parallel=parallel)
        out.append(time.perf_counter() - t)
    return np.array(out) * 1e3


def _seed_latencies(library: Sequence[np.ndarray], table, queries: Sequence[np.ndarray]) -> np.ndarray:
    out = []
    for q in queries:
        t = time.perf_counter()
        np.argmin([dtw_codes(q, r, table) for r in library])
        out.append(time.perf_counter() - t)
    return np.array(out) * 1e3


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
    methods = [m for m, _ in PROTOCOL_ROWS] + [m for m, _ in ABLATION_ROWS]
    set_threads(1)  # the protocol compares single-core searches (fast_parallel sets its own)
    # fast_parallel needs all threads while it runs: evaluate() runs methods fold by fold,
    # so the thread count is switched by a thin wrapper around its distances()
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

    res = evaluate(clips, methods, folds, dims, seed, progress=progress_bar("evaluating", "fold", progress),
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
    fast_s = protocol["fast"]["seconds"]

    # ---------------------------------------------------------------- scale
    scale_clips = clips if scale_fps == fps else load_clips(source, scale_fps, progress)[0]
    parts = stratified_folds([c.label for c in scale_clips], folds, seed)
    query_idx = parts[0]
    ref_idx = np.setdiff1d(np.arange(len(scale_clips)), query_idx)
    refs = [scale_clips[i] for i in ref_idx]
    quant = Quantizer.fit(stack_frames([c.features for c in refs]), dims)
    min_clips, min_hours = (300, 0.25) if quick else (2600, 9.0)
    lib = build_scale_library(refs, quant, min_clips=min_clips, min_hours=min_hours, seed=seed, progress=progress)
    table = DiffTable.from_ratios(quant.ratios)
    t0 = time.perf_counter()
    searcher = FastSearcher(lib.codes, table)
    index_seconds = time.perf_counter() - t0
    queries = [quant.encode(scale_clips[i].features) for i in query_idx]
    if quick:
        queries = queries[:5]
    set_threads(1)
    one = _latencies(searcher, queries, False, progress, "1-NN latency, 1 core")
    set_threads(all_threads)
    many = _latencies(searcher, queries, True, progress, f"1-NN latency, {all_threads} cores")
    set_threads(1)
    sizes = sorted({s for s in (30, 100, 300, 1000, 3000) if s < lib.clips} | {lib.clips})
    curve = []
    seed_table = quant.table()
    for n in tqdm(sizes, desc="latency vs library size", unit="size", disable=not progress, leave=False):
        sub = FastSearcher(lib.codes[:n], table)
        ms = _latencies(sub, queries[: (5 if quick else 20)], False, False, "")
        seed_ms = _seed_latencies(lib.codes[:n], seed_table, queries[:3])
        curve.append({"clips": n, "hours": sum(len(c) for c in lib.codes[:n]) / lib.fps / 3600,
                      "fast_ms_median": float(np.median(ms)), "seed_ms_median": float(np.median(seed_ms))})
    set_threads(all_threads)
    plot_path = plot_latency_curve(curve, plot) if plot else None

    out = {
        "protocol": protocol,
        "speedup_vs_exact_dtw": protocol["dtw"]["seconds"] / fast_s,
        "speedup_vs_dtaidistance": protocol["dtaidistance"]["seconds"] / fast_s,
        "speedup_vs_seed_method": protocol["quantized"]["seconds"] / fast_s,
        "query_ms_median": float(np.median(one)),
        "query_ms_p95": float(np.percentile(one, 95)),
        "query_ms_median_all_cores": float(np.median(many)),
        "query_ms_p95_all_cores": float(np.percentile(many, 95)),
        "library_clips": lib.clips,
        "library_hours": lib.hours,
        "library_fps": lib.fps,
        "library_note": ("derived from the non-query folds of the source clips by mirroring, time scaling "
                         "0.8-1.25 and same-class splicing (retrieval/augment.py); codes only"),
        "latency_queries": len(queries),
        "index_build_seconds": index_seconds,
        "table_bytes": table.nbytes,
        "table_bytes_by_layout": {lay: table_bytes(lay, dims) for lay in ("diff", "component", "full")},
        "index_bytes_per_clip": searcher.index_bytes_per_clip,
        "codes_bytes_per_clip": 4 * lib.frames / lib.clips,
        "ablations": {m: {**protocol[m], "speedup_vs_seed_method": protocol["quantized"]["seconds"] / protocol[m]["seconds"]}
                      for m, _ in ABLATION_ROWS},
        "latency_vs_library_size": curve,
        "plot": str(plot_path) if plot_path else None,
        "settings": {"data": source, "clips": len(clips), "motion_seconds": sum(c.seconds for c in clips),
                     "fps": fps, "scale_fps": scale_fps, "dims": dims, "folds": folds, "seed": seed,
                     "band_frames": band_frames, "quick": quick, "threads_all": all_threads,
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
    ax.loglog(n, [c["fast_ms_median"] for c in curve], "o-", label="fast exact search (1 core)")
    ax.loglog(n, [c["seed_ms_median"] for c in curve], "s--", label="seed method (full table, no pruning)")
    ax.axhline(50, color="grey", lw=0.8, ls=":", label="50 ms")
    ax.set_xlabel("library size (clips; derived library, 30 fps codes)")
    ax.set_ylabel("1-NN query time, median (ms)")
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
    lines = [f"paper protocol: {s['clips']} clips ({s['motion_seconds']:.0f} s) from {s['data']}, "
             f"{s['folds']}-fold 1-NN, {s['fps']:g} fps, n = {s['dims']}",
             f"{'method':<48}{'search s':>10}{'accuracy %':>12}{'fast is x':>11}{'pruned %':>10}"]
    fast = p["fast"]["seconds"]
    for m, label in PROTOCOL_ROWS + ABLATION_ROWS:
        r = p[m]
        pr = f"{100 * r['pruned_fraction']:.1f}" if "pruned_fraction" in r else "-"
        lines.append(f"{label:<48}{r['seconds']:>10.3f}{100 * r['accuracy']:>12.2f}{r['seconds'] / fast:>11.1f}{pr:>10}")
    lines += [
        "",
        f"speed-up of the fast exact search: {out['speedup_vs_exact_dtw']:.1f}x vs exact DTW, "
        f"{out['speedup_vs_dtaidistance']:.1f}x vs dtaidistance, {out['speedup_vs_seed_method']:.1f}x vs the seed method",
        f"scale library: {out['library_clips']} clips, {out['library_hours']:.2f} h at {out['library_fps']:g} fps (derived, codes only)",
        f"1-NN latency over it, {out['latency_queries']} held-out queries: 1 core median {out['query_ms_median']:.1f} ms, "
        f"p95 {out['query_ms_p95']:.1f} ms; {s['threads_all']} cores median {out['query_ms_median_all_cores']:.1f} ms, "
        f"p95 {out['query_ms_p95_all_cores']:.1f} ms",
        "latency vs size (median ms, fast / seed): " + ", ".join(
            f"{c['clips']}: {c['fast_ms_median']:.1f} / {c['seed_ms_median']:.0f}" for c in out["latency_vs_library_size"]),
        f"distance structure: {out['table_bytes']} B (difference table; component "
        f"{out['table_bytes_by_layout']['component']} B; seed's full table {out['table_bytes_by_layout']['full']} B); "
        f"index {out['index_bytes_per_clip']:.0f} B per clip (codes alone {out['codes_bytes_per_clip']:.0f} B)",
        f"{out['machine'].get('cpu_model', '?')}; "
        f"load average at the end: {', '.join(f'{x:.2f}' for x in out['machine']['load_average_at_end'])} "
        f"on {out['machine']['cpus']} CPUs",
    ]
    return "\n".join(lines)
