"""`storybeam cluster`: group a labelled motion folder without its labels, then score the
groups against them.

    storybeam cluster --data ../shared/data/cmu --json OUT [--k K] [--k-min 4] [--k-max 12] [--fps 30] [--dims 6]

Every clip is described by its kinetic energy per body part over time and its 2-bit frame
codes, and the descriptors are clustered by Ward's method; the number of clusters is
``--k`` or, by default, the one in ``--k-min``..``--k-max`` (4..12) with the largest mean
silhouette (the labels are never used to choose it). See :mod:`retrieval.library.grouping`. Prints one
line per group (its name: the most common label; its size; its representative clip) and
the scores; ``--json OUT`` (``-``: stdout) writes::

  {"data", "clips", "fps", "dims", "criterion", "clusters": K, "purity", "ari",
   "silhouette": {K: score, ...}, "at_label_count": {"clusters", "purity", "ari"},
   "groups": [{"number", "name", "size", "representative", "labels": {label: count}}]}

``purity`` and ``ari`` (adjusted Rand index) are measured against ``labels.csv``;
``at_label_count`` repeats them with K = the number of labels, for comparison.
"""
from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

from app.commands.output import emit_json_report
from app.progress import progress_bar
from retrieval.errors import StoryBeamError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("cluster", help="group a motion folder by kinetic energy and codes; purity and ARI",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, required=True, help="labelled folder (with labels.csv)")
    p.add_argument("--json", dest="json_out", metavar="OUT", help="write the result as JSON here ('-': stdout)")
    p.add_argument("--k", type=int, default=None, help="number of groups (default: chosen by the silhouette)")
    p.add_argument("--k-min", type=int, default=None, help="smallest K the silhouette criterion tries (default 4)")
    p.add_argument("--k-max", type=int, default=None, help="largest K the silhouette criterion tries (default 12)")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate the clips are resampled to (default 30)")
    p.add_argument("--dims", type=int, default=6, help="PCA components of the codes (default 6)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Group, score, report."""
    # deferred: loads scipy's clustering and the retrieval stack
    from retrieval.library import K_MAX, K_MIN, adjusted_rand_index, group, group_folder, purity

    if not args.data.is_dir():
        raise StoryBeamError(f"--data {args.data}: not a folder")
    if not 1 <= args.dims <= 8:
        raise StoryBeamError(f"--dims must be between 1 and 8, got {args.dims}")
    if not 1.0 <= args.fps <= 240.0:
        raise StoryBeamError(f"--fps must be between 1 and 240, got {args.fps:g}")
    k_max = K_MAX if args.k_max is None else args.k_max
    k_min = min(K_MIN, k_max) if args.k_min is None else args.k_min
    if k_min < 2 or k_max < k_min:
        raise StoryBeamError(f"--k-min and --k-max must satisfy 2 <= k-min <= k-max, got {k_min} and {k_max}")
    result = group_folder(args.data, args.fps, args.dims, args.k, k_max,
                          progress_bar("kinetic energy", "clip", not args.quiet), k_min)
    g, labels = result.grouping, list(result.labels)
    n_labels = len(set(labels))
    at_labels = g if g.k == n_labels else None
    if at_labels is None and 1 <= n_labels <= len(labels):
        at_labels = group(result.descriptors, result.trials, labels, n_labels)
    report = {
        "data": str(args.data), "clips": len(labels), "fps": args.fps, "dims": args.dims,
        "criterion": "given --k" if args.k is not None else f"largest mean silhouette, K in {k_min}..{k_max}",
        "clusters": g.k, "purity": purity(g.clusters, labels), "ari": adjusted_rand_index(g.clusters, labels),
        "silhouette": {str(k): s for k, s in g.scores.items()},
        "at_label_count": None if at_labels is None else {
            "clusters": at_labels.k, "purity": purity(at_labels.clusters, labels),
            "ari": adjusted_rand_index(at_labels.clusters, labels)},
        "groups": [{"number": grp.number, "name": grp.name, "size": len(grp.members),
                    "representative": grp.representative,
                    "labels": dict(Counter(labels[i] for i in grp.members).most_common())} for grp in g.groups],
    }
    if args.json_out != "-":
        for grp in report["groups"]:
            mix = ", ".join(f"{lab} {n}" for lab, n in grp["labels"].items())
            print(f"group {grp['number']:>2}  {grp['name'] or '(picture)':<22} {grp['size']:>4} clips  "
                  f"rep {grp['representative']:<12} {mix}")
        print(f"{report['clips']} clips, K = {g.k} ({report['criterion']}): purity {report['purity']:.3f}, "
              f"ARI {report['ari']:.3f}")
        if report["at_label_count"] is not None:
            a = report["at_label_count"]
            print(f"at K = {a['clusters']} (the number of labels): purity {a['purity']:.3f}, ARI {a['ari']:.3f}")
    emit_json_report(args.json_out, report)
    return 0
