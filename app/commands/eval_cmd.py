"""`storybeam eval`: the research's k-fold 1-NN experiment on a labelled motion folder.

Prints the seed-style table (search time and accuracy per method) with balanced and
per-class accuracy; ``--json`` writes the same numbers; ``--sweep-dims 1-7`` adds the
study over the number of kept PCA components, with ``--plots`` as PNG figures (and a
confusion matrix per method and split). ``--split random,subject`` runs the random folds
and leave-one-subject-out (performer / style) one after the other and tabulates both.

Methods: ``storybeam`` (StoryBeam's own: code + clip-summary shortlist, exact float-DTW
re-ranking on MR17 + turning rate + where the hands are; the codes see the first 18),
``dtw-storybeam`` (exact DTW on the same features), and the seed's
``quantized``, ``quantized-fast``, ``dtw``, ``forbes`` on the 17 MR17 features.
``--features mr17`` and ``--heading-weight`` change what the storybeam methods see
(ablations; ``--features storybeam-no-hands`` drops where the hands are in the body's frame);
``--shortlist`` how many clips it re-ranks, ``--summary`` how many of those the clip
summaries choose (0: the codes alone, the method before issue 31).

Across skeletons (lab/experiment/cross_skeleton.py): ``--identity --skeleton-from DIR``
takes each file of DIR named like a trial of --data as a clip query (same trial first?);
``--pose-identity`` the frames at 1/4, 1/2, 3/4 of each trial as ``search --pose``
queries (same class, and with --skeleton-from same trial); ``--body`` compares the
file's own body with the canonical one.
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
    p.add_argument("--methods", default="storybeam,quantized-fast,quantized,dtw-storybeam,dtw,forbes",
                   help="comma list of storybeam, dtw-storybeam, quantized-fast, quantized, dtw, forbes")
    p.add_argument("--split", default="random",
                   help="comma list of protocols: random (stratified --folds), subject (leave one subject out)")
    p.add_argument("--features", choices=["storybeam", "storybeam-no-hands", "mr17"], default="storybeam",
                   help="features of the storybeam and dtw-storybeam methods (ablations: mr17; storybeam-no-hands, "
                        "the set without where the hands are in the body's frame)")
    p.add_argument("--heading-weight", type=float, default=None,
                   help="weight of the turning rate in the storybeam features (ablation; default the set's)")
    p.add_argument("--normalise", choices=["legs", "arms", "chain"], default=None,
                   help="how the storybeam features divide lengths (ablation; default the set's)")
    p.add_argument("--body", choices=["source", "canonical"], default=None,
                   help="features on the file's own skeleton or re-posed onto the canonical body "
                        "(ablation; default the set's)")
    p.add_argument("--centre", choices=["on", "off"], default=None,
                   help="subtract each storybeam feature's mean over the clip (ablation; default the set's)")
    p.add_argument("--identity", action="store_true",
                   help="instead of the folds: write every clip as BVH on another skeleton at another frame rate, "
                        "read it back and count how often the clip finds itself first (storybeam's find, "
                        "its class ranking and the seed's codes)")
    p.add_argument("--identity-fps", type=float, default=50.0, help="frame rate of the written BVH files (default 50)")
    p.add_argument("--skeleton-from", metavar="DIR",
                   help="with --identity / --pose-identity: a folder of the same trials on another skeleton "
                        "(BVH files named by trial, e.g. 07_01.bvh, or a labels.csv), matched to --data by name: "
                        "each is the query instead of StoryBeam's own round trip")
    p.add_argument("--pose-identity", action="store_true",
                   help="instead of the folds: the frames at 1/4, 1/2 and 3/4 of each trial as `search --pose` "
                        "queries; the top clip's class (and, with --skeleton-from, trial) -- without "
                        "--skeleton-from the poses come from --data's own files, their trial left out")
    p.add_argument("--shortlist", type=int, default=None,
                   help="clips the storybeam method re-ranks by exact float DTW (default 3)")
    p.add_argument("--summary", type=int, default=None,
                   help="of those, how many come from the clip-summary ranking (per-feature mean and 10-90%% range) "
                        "instead of the codes (default 2; 0 = the code shortlist alone)")
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


def format_splits(per_split: dict[str, dict]) -> str:
    """Accuracy and search time per method (rows) and protocol (columns)."""
    splits = list(per_split)
    names = list(next(iter(per_split.values())))
    lines = [f"{'':<16}" + "".join(f"{s + ' acc (%)':>18}{s + ' bal (%)':>18}" for s in splits)]
    for n in names:
        lines.append(f"{n:<16}" + "".join(f"{100 * per_split[s][n]['accuracy']:>18.2f}"
                                          f"{100 * per_split[s][n]['balanced_accuracy']:>18.2f}" for s in splits))
    return "\n".join(lines)


def speed_ratios(res: dict) -> dict[str, float]:
    """Exact DTW's search time over each fast method's, wall and CPU, from one run."""
    out = {}
    for fast, exact in (("quantized-fast", "dtw"), ("quantized", "dtw"), ("storybeam", "dtw-storybeam")):
        if fast in res and exact in res and res[fast]["search_seconds"] > 0:
            key = fast.replace("-", "_")
            ref = exact.replace("-", "_")
            out[f"{ref}_over_{key}_search_time"] = res[exact]["search_seconds"] / res[fast]["search_seconds"]
            out[f"{ref}_over_{key}_search_cpu_time"] = (res[exact]["search_cpu_seconds"]
                                                        / max(res[fast]["search_cpu_seconds"], 1e-12))
    return out


#: The "other skeleton" of --identity: a child-sized canonical body (1.3 m) with its own
#: proportions (longer shins, shorter arms, wider shoulders than the default adult).
IDENTITY_HEIGHT_M = 1.3
IDENTITY_PROPORTIONS = {"thigh": 0.23, "shin": 0.26, "upper_arm": 0.15, "forearm": 0.14,
                        "shoulder_half_width": 0.12, "hip_half_width": 0.07, "head_top": 0.15}


def identity_check(rows, clips, fps: float, feature_set: str, write_fps: float, shortlist: int | None, dims: int,
                   progress=None, seed_clips=None) -> dict:
    """"Find this clip": every clip, retargeted (StoryBeam's retarget) onto a different
    canonical skeleton, resampled to ``write_fps``, written as BVH with StoryBeam's writer
    and read back, is the query against the whole library (the clips as loaded). Counts
    how often the clip itself is first: for storybeam's "find this clip" ranking
    (:meth:`StoryBeamSearcher.find`: centred features, their own code shortlist, exact
    float DTW), for storybeam's class ranking (code shortlist + float-DTW re-ranking,
    :meth:`StoryBeamSearcher.search`) and for the seed's codes alone (the fast exact search, ties by
    library order), with how many library clips tie with the seed's best distance. The seed
    sees ``seed_clips`` (the library in MR17 on the file's own body) when given, else the
    MR17 columns of ``clips``."""
    import tempfile  # deferred: only for --identity

    import numpy as np  # deferred: numpy stack only for this command

    from retrieval.animation import BodyProportions, canonical_skeleton, retarget  # deferred: as above
    from retrieval.codes import DiffTable, Quantizer  # deferred: as above
    from retrieval.features import get_feature_set  # deferred: as above
    from retrieval.library import SHORTLIST, StoryBeamSearcher, clip_from_motion  # deferred: as above
    from retrieval.motion import load_motion, resample, save_bvh  # deferred: as above
    from retrieval.search import FastSearcher  # deferred: as above

    target = canonical_skeleton(BodyProportions(**IDENTITY_PROPORTIONS), IDENTITY_HEIGHT_M, "identity-child")
    sb = StoryBeamSearcher.fit([c.features for c in clips], dims, shortlist or SHORTLIST,
                               code_columns=get_feature_set(feature_set).code_columns)
    # the seed's method: its quantiser on the MR17 columns, the exact fast search over its codes
    seed_lib = [c.features[:, :17] for c in (clips if seed_clips is None else seed_clips)]
    seed_q = Quantizer.fit(np.concatenate(seed_lib), dims)
    seed_fast = FastSearcher([seed_q.encode(f) for f in seed_lib], DiffTable.from_ratios(seed_q.ratios))
    found_sb = found_find = found_seed = 0
    ties = []
    misses = []
    find_misses = []
    with tempfile.TemporaryDirectory() as tmp:
        for n, (row, clip) in enumerate(zip(rows, clips)):
            motion = load_motion(row.file, row.skeleton) if row.skeleton else load_motion(row.file)
            moved = resample(retarget(motion, target, name=row.trial), write_fps)
            path = save_bvh(moved, Path(tmp) / f"{row.trial}.bvh")
            again = load_motion(path)
            back = clip_from_motion(again, row.trial, row.label, fps, feature_set)
            hits = sb.search(back.features, k=1)
            found_sb += hits[0].index == n
            found = sb.find(back.features, k=1)
            found_find += found[0].index == n
            if found[0].index != n:
                find_misses.append({"trial": row.trial, "found": clips[found[0].index].trial})
            seed_back = back.features if seed_clips is None else clip_from_motion(
                again, row.trial, row.label, fps, "mr17").features
            res = seed_fast.search([seed_q.encode(seed_back[:, :17])], k=min(len(clips), 8),
                                   parallel=False)
            found_seed += int(res.indices[0, 0]) == n
            ties.append(int(np.sum(res.distances[0] <= res.distances[0, 0])))
            if hits[0].index != n:
                misses.append({"trial": row.trial, "found": clips[hits[0].index].trial})
            if progress is not None:
                progress(n + 1, len(rows))
    total = len(clips)
    return {"clips": total, "write_fps": write_fps, "skeleton": f"canonical {IDENTITY_HEIGHT_M} m, {IDENTITY_PROPORTIONS}",
            "storybeam_find_top1": found_find / total, "storybeam_top1": found_sb / total,
            "quantized_top1": found_seed / total,
            "quantized_mean_ties_at_best": float(np.mean(ties)), "storybeam_find_misses": find_misses,
            "storybeam_misses": misses}


def _misses_line(misses: list[dict], key: str) -> str:
    shown = ", ".join(f"{m['trial']}->{m[key]}" for m in misses[:12])
    return shown + (f", ... ({len(misses)} in all)" if len(misses) > 12 else "")


def seed_mr17_clips(args, rows, clips, feature_set: str, pose: bool = False, progress=None):
    """The seed's own features for its methods: ``clips`` again in MR17 on the file's own
    body (same order), or None when ``feature_set``'s first 17 columns already are that
    (MR17 itself, or a set on the file's body)."""
    from retrieval.features import get_feature_set  # deferred: numpy stack only for this command
    from retrieval.library import load_dataset  # deferred: as above

    if feature_set == "mr17" or get_feature_set(feature_set).body == "source":
        return None
    by_trial = {c.trial: c for c in load_dataset(args.data, fps=args.fps, feature_set="mr17", rows=rows,
                                                 cache=not args.no_cache, pose=pose, progress=progress)}
    return [by_trial[c.trial] for c in clips]


def run_identity(args, rows, clips, feature_set: str) -> int:
    """``--identity`` and/or ``--pose-identity``, with or without ``--skeleton-from``:
    run, print a line each (and the misses), write the JSON."""
    # deferred: numpy/numba stack only for this command
    from retrieval.library import SHORTLIST, load_dataset, pose_feature_set
    # deferred: the experiment layer, only for this command
    from lab.experiment import other_skeleton_trials, pose_identity, skeleton_identity

    out = {"data": str(args.data), "fps": args.fps, "dims": args.dims, "feature_set": feature_set,
           "skeleton_from": args.skeleton_from}
    others = other_skeleton_trials(args.skeleton_from) if args.skeleton_from else None
    if args.identity and others is None:
        ident = identity_check(rows, clips, args.fps, feature_set, args.identity_fps, args.shortlist, args.dims,
                               progress_bar("identity round trips", "clip", not args.quiet),
                               seed_mr17_clips(args, rows, clips, feature_set))
        print(f"{ident['clips']} clips written as BVH on another skeleton at {args.identity_fps:g} fps and read back: "
              f"found first: storybeam find {100 * ident['storybeam_find_top1']:.2f} %, "
              f"storybeam class ranking {100 * ident['storybeam_top1']:.2f} %, "
              f"quantized {100 * ident['quantized_top1']:.2f} % "
              f"(mean {ident['quantized_mean_ties_at_best']:.2f} clips tie at the seed's best distance)")
        out["identity"] = ident
    elif args.identity:
        ident = skeleton_identity(rows, clips, others, args.fps, feature_set, args.dims, args.shortlist or SHORTLIST,
                                  progress_bar("other-skeleton trials", "trial", not args.quiet))
        n = ident["trials"]
        print(f"{n} trials of {args.skeleton_from} against {len(clips)} clips: same trial first: "
              f"storybeam find {round(ident['find_top1'] * n)}/{n} ({100 * ident['find_top1']:.1f} %), "
              f"class ranking {round(ident['search_top1'] * n)}/{n} ({100 * ident['search_top1']:.1f} %)")
        missed = [m for m in ident["misses"] if m["find"] != m["trial"]]
        if missed:
            print("  find's misses (trial->found): " + _misses_line(missed, "find"))
        if ident["not_in_library"]:
            print(f"  not in --data: {', '.join(ident['not_in_library'])}")
        out["skeleton_identity"] = ident
    if args.pose_identity:
        # the pose search's own library: its feature set at this rate (PoseSearch.build's)
        pose_set = pose_feature_set(args.body)
        pose_clips = clips if feature_set == pose_set else load_dataset(
            args.data, fps=args.fps, feature_set=pose_set, rows=rows, cache=not args.no_cache,
            progress=progress_bar("loading pose features", "clip", not args.quiet))
        pose = pose_identity(rows, pose_clips, others, args.dims, pose_set,
                             progress_bar("pose queries", "trial", not args.quiet))
        n = pose["poses"]
        text = (f"{n} poses (1/4, 1/2, 3/4 of {pose['trials']} trials"
                + (f" of {args.skeleton_from}" if others is not None else ", their own trial left out")
                + f"): top clip of the same class {round(pose['same_class'] * n)}/{n} ({pose['same_class']:.2f})")
        if others is not None:
            text += f", the same trial {round(pose['same_trial'] * n)}/{n} ({pose['same_trial']:.2f})"
        print(text)
        print("  same class by class: " + ", ".join(f"{c} {v:.2f}" for c, v in pose["per_class"].items()))
        out["pose_identity"] = pose
    if args.json_out:
        write_json_report(args.json_out, out)
    return 0


def run(args) -> int:
    from retrieval.library import load_dataset, read_labels  # deferred: numpy/numba stack only for this command
    # deferred: the experiment layer (numpy, numba kernels) only for this command
    from lab.experiment import (
        METHODS,
        SEED_METHODS,
        SPLITS,
        evaluate,
        plot_confusion,
        plot_sweep,
        stratified_subset,
        sweep_dims,
    )
    # deferred: as above
    from retrieval.features import get_feature_set, heading_weight_of, register_feature_set, storybeam_feature_set

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise StoryBeamError(f"--methods: unknown {', '.join(bad) or '(none given)'} (choose from {', '.join(METHODS)})")
    splits = [s.strip() for s in args.split.split(",") if s.strip()]
    if not splits or any(s not in SPLITS for s in splits):
        raise StoryBeamError(f"--split: expected a comma list of {', '.join(SPLITS)}, got {args.split!r}")
    if args.folds < 2:
        raise StoryBeamError("--folds must be at least 2")
    if args.shortlist is not None and args.shortlist < 1:
        raise StoryBeamError("--shortlist must be at least 1")
    if args.summary is not None and args.summary < 0:
        raise StoryBeamError("--summary must be at least 0")
    sweep = parse_range(args.sweep_dims) if args.sweep_dims else None
    feature_set = "mr17"
    if any(m not in SEED_METHODS for m in methods) and args.features != "mr17":
        feature_set = args.features
        if (args.heading_weight is not None or args.normalise is not None or args.centre is not None
                or args.body is not None):
            base = get_feature_set(feature_set)
            w = heading_weight_of(base) if args.heading_weight is None else args.heading_weight
            norm = args.normalise or base.normalise
            centre = base.centre if args.centre is None else args.centre == "on"
            body = args.body or base.body
            hands = max((s.weight for s in base.specs if s.kind == "across"), default=0.0)
            feature_set = register_feature_set(storybeam_feature_set(
                w, f"{feature_set}-w{w:g}-{norm}-{'centred' if centre else 'raw'}-{body}", norm, centre, body,
                hands)).name
    started = time.perf_counter()
    rows = read_labels(args.data)
    unlabelled = [r for r in rows if not r.label]
    if args.skeleton_from and not (args.identity or args.pose_identity):
        raise StoryBeamError("--skeleton-from goes with --identity or --pose-identity")
    if unlabelled and (args.pose_identity or not args.identity):
        raise StoryBeamError(f"{Path(args.data) / 'labels.csv'}, line {unlabelled[0].line}: clip {unlabelled[0].trial!r} "
                             f"has no label ({len(unlabelled)} unlabelled in all): the evaluation needs every clip "
                             "labelled")
    clips = load_dataset(args.data, fps=args.fps, feature_set=feature_set, cache=not args.no_cache, rows=rows,
                         pose="forbes" in methods,
                         progress=progress_bar(f"loading {Path(args.data).name}", "clip", not args.quiet))
    load_seconds = time.perf_counter() - started
    if args.subset:
        clips = stratified_subset(clips, args.subset, args.seed)
    motion_seconds = sum(c.seconds for c in clips)
    if args.identity or args.pose_identity:
        if args.subset:
            raise StoryBeamError("--identity and --pose-identity use the whole folder: drop --subset")
        return run_identity(args, rows, clips, feature_set)
    # the seed's methods keep the seed's features (MR17 on the file's own body), as the research
    seed_clips = None
    if set(methods) & set(SEED_METHODS):
        seed_clips = seed_mr17_clips(args, rows, clips, feature_set, "forbes" in methods,
                                     progress_bar("loading the seed's MR17", "clip", not args.quiet))
    per_split = {}
    for split in splits:
        kw = {"shortlist": args.shortlist} if args.shortlist else {}
        if args.summary is not None:
            kw["summary"] = args.summary
        res = evaluate(clips, methods, args.folds, args.dims, args.seed, args.band, args.forbes_clusters,
                       progress=progress_bar(f"evaluating ({split} split)", "fold", not args.quiet),
                       backend=args.backend, split=split, seed_clips=seed_clips,
                       code_columns=get_feature_set(feature_set).code_columns, **kw)
        per_split[split] = {n: r.as_dict() for n, r in res.items()}
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
        "split": splits[0],
        "feature_set": feature_set,
        "shortlist": args.shortlist,
        "summary": args.summary,
        "classes": {c: sum(x.label == c for x in clips) for c in sorted({x.label for x in clips})},
        "subjects": {s: sum(x.subject == s for x in clips) for s in sorted({x.subject for x in clips})},
        "load_seconds": load_seconds,
        "methods": per_split[splits[0]],
        "splits": {s: {"methods": per_split[s], **speed_ratios(per_split[s])} for s in splits},
    }
    out.update(speed_ratios(per_split[splits[0]]))
    for split in splits:
        if len(splits) > 1:
            print(f"\n== {split} split ==")
        print(format_table(per_split[split], len(clips), motion_seconds))
        for key, ratio in speed_ratios(per_split[split]).items():
            if key.endswith("_search_time"):
                cpu = out["splits"][split][key.replace("_search_time", "_search_cpu_time")]
                print(f"{key.replace('_', ' ')}: {ratio:.1f}x wall, {cpu:.1f}x CPU")
    if len(splits) > 1:
        print("\n" + format_splits(per_split))
    if args.plots:
        out["confusion_plots"] = []
        for split in splits:
            out["confusion_plots"] += plot_confusion(per_split[split], args.plots, f"confusion_{split}",
                                                     f"{Path(args.data).name}, {split} split, ")
        print("plots: " + ", ".join(out["confusion_plots"]))
    if sweep:
        out["sweep"] = sweep_dims(seed_clips or clips, sweep, args.folds, args.seed, args.band,
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
