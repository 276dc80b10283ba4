"""`storybeam eval`: the research's k-fold 1-NN experiment on a labelled motion folder.

Prints the seed-style table (search time and accuracy per method) with balanced and
per-class accuracy; ``--json`` writes the same numbers; ``--sweep-dims 1-7`` adds the
study over the number of kept PCA components, with ``--plots`` as PNG figures.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from app.commands.output import write_json_report
from app.progress import progress_bar
from retrieval.errors import StoryBeamError


def parse_range(text: str) -> list[int]:
    """"1-7" -> [1..7]; "2,4,6" -> [2, 4, 6]."""
    try:
        if "-" in text:
            a, b = text.split("-", 1)
            values = list(range(int(a), int(b) + 1))
        else:
            values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise StoryBeamError(f"--sweep-dims: expected a range like 1-7 or a list like 2,4,6, got {text!r}") from None
    if not values or min(values) < 1:
        raise StoryBeamError(f"--sweep-dims: dimensions must be >= 1, got {text!r}")
    return values


def register(subparsers) -> None:
    p = subparsers.add_parser("eval", help="k-fold 1-NN evaluation of the retrieval methods",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, help="labelled folder with labels.csv")
    p.add_argument("--folds", type=int, default=3)
    p.add_argument("--dims", type=int, default=6, help="kept PCA components n (default 6, as the research)")
    p.add_argument("--fps", type=float, default=30.0, help="resample every clip to this rate (default 30)")
    p.add_argument("--methods", default="quantized-fast,quantized,dtw,forbes",
                   help="comma list of quantized-fast, quantized, dtw, forbes")
    p.add_argument("--band", type=int, default=None, help="Sakoe-Chiba band radius in frames (default none)")
    p.add_argument("--forbes-clusters", type=int, default=None, help="k for Forbes-Fiume (default min(4^n, 1024))")
    p.add_argument("--json", dest="json_out", help="write results as JSON here")
    p.add_argument("--sweep-dims", help="also sweep the proposed method over n, e.g. 1-7")
    p.add_argument("--plots", help="folder for the sweep's PNG plots")
    p.add_argument("--seed", type=int, default=0, help="fold assignment seed")
    p.add_argument("--subset", type=int, help="use a class-stratified random subset of this many clips")
    p.add_argument("--backend", choices=["auto", "numba", "numpy"], default="auto",
                   help="DTW back-end (numpy = the no-numba path used on Android)")
    p.add_argument("--no-cache", action="store_true", help="do not use the clip feature cache")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def format_table(results: dict, n_clips: int, seconds: float) -> str:
    names = list(results)
    lines = [f"{n_clips} clips ({seconds:.0f} s of motion)", ""]
    w = max(12, 2 + max(len(n) for n in names))
    lines.append(f"{'':<22}" + "".join(f"{n:>{w}}" for n in names))
    lines.append(f"{'search time (s)':<22}" + "".join(f"{results[n]['search_seconds']:>{w}.3f}" for n in names))
    lines.append(f"{'search CPU time (s)':<22}" + "".join(f"{results[n].get('search_cpu_seconds', 0):>{w}.3f}" for n in names))
    lines.append(f"{'ns per DTW cell':<22}" + "".join(f"{results[n]['ns_per_cell'] or 0:>{w}.2f}" for n in names))
    lines.append(f"{'build time (s)':<22}" + "".join(f"{results[n]['build_seconds']:>{w}.3f}" for n in names))
    lines.append(f"{'accuracy (%)':<22}" + "".join(f"{100 * results[n]['accuracy']:>{w}.3f}" for n in names))
    lines.append(f"{'balanced accuracy (%)':<22}" + "".join(f"{100 * results[n]['balanced_accuracy']:>{w}.3f}" for n in names))
    classes = sorted({c for n in names for c in results[n]["per_class"]})
    for c in classes:
        lines.append(f"{'  ' + c + ' (%)':<22}" + "".join(f"{100 * results[n]['per_class'].get(c, 0):>{w}.1f}" for n in names))
    return "\n".join(lines)


def run(args) -> int:
    from retrieval.library import load_dataset, read_labels  # deferred: numpy/numba stack only for this command
    # deferred: the experiment layer (numpy, numba kernels) only for this command
    from retrieval.experiment import METHODS, evaluate, plot_sweep, stratified_subset, sweep_dims

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise StoryBeamError(f"--methods: unknown {', '.join(bad) or '(none given)'} (choose from {', '.join(METHODS)})")
    if args.folds < 2:
        raise StoryBeamError("--folds must be at least 2")
    sweep = parse_range(args.sweep_dims) if args.sweep_dims else None
    started = time.perf_counter()
    rows = read_labels(args.data)
    clips = load_dataset(args.data, fps=args.fps, cache=not args.no_cache, rows=rows, pose="forbes" in methods,
                         progress=progress_bar(f"loading {Path(args.data).name}", "clip", not args.quiet))
    load_seconds = time.perf_counter() - started
    if args.subset:
        clips = stratified_subset(clips, args.subset, args.seed)
    motion_seconds = sum(c.seconds for c in clips)
    res = evaluate(clips, methods, args.folds, args.dims, args.seed, args.band, args.forbes_clusters,
                   progress=progress_bar("evaluating", "fold", not args.quiet), backend=args.backend)
    out = {
        "n_clips": len(clips),
        "total_seconds": motion_seconds,
        "fps": args.fps,
        "folds": args.folds,
        "dims": args.dims,
        "band": args.band,
        "seed": args.seed,
        "subset": args.subset,
        "backend": args.backend,
        "classes": {c: sum(x.label == c for x in clips) for c in sorted({x.label for x in clips})},
        "load_seconds": load_seconds,
        "methods": {n: {k: v for k, v in r.as_dict().items()} for n, r in res.items()},
    }
    print(format_table(out["methods"], len(clips), motion_seconds))
    for q in ("quantized-fast", "quantized"):
        if q in res and "dtw" in res and res[q].search_seconds > 0:
            ratio = res["dtw"].search_seconds / res[q].search_seconds
            cpu_ratio = res["dtw"].extra["search_cpu_seconds"] / max(res[q].extra["search_cpu_seconds"], 1e-12)
            key = "quantized" if q == "quantized" else "quantized_fast"
            out[f"dtw_over_{key}_search_time"] = ratio
            out[f"dtw_over_{key}_search_cpu_time"] = cpu_ratio
            print(f"exact DTW search / {q} search: {ratio:.1f}x wall, {cpu_ratio:.1f}x CPU")
    if sweep:
        out["sweep"] = sweep_dims(clips, sweep, args.folds, args.seed, args.band,
                                  progress=progress_bar("sweeping n", "n", not args.quiet),
                                  backend=args.backend)
        print("\n  n  accuracy  balanced  search(s)  cum.contrib  table")
        for r in out["sweep"]:
            print(f"{r['dims']:>3}  {100 * r['accuracy']:8.2f}  {100 * r['balanced_accuracy']:8.2f}  "
                  f"{r['search_seconds']:9.3f}  {100 * r['cumulative_ratio']:10.1f}%  {r['table']} "
                  f"{r['table_bytes'] / 2**20:.1f} MiB")
        if args.plots:
            out["plots"] = plot_sweep(out["sweep"], args.plots)
            print("plots: " + ", ".join(out["plots"]))
    out["total_run_seconds"] = time.perf_counter() - started
    if args.json_out:
        write_json_report(args.json_out, out)
    return 0
