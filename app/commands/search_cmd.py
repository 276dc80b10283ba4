"""`storybeam search`: the clips of a motion library nearest to a query motion file.

``--data`` is a labelled folder (indexed on the fly) or a saved index folder (contains
index.json); by default the bundled library in assets/motions.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from app.commands.output import write_json_report
from retrieval.errors import StoryBeamError

DEFAULT_LIBRARY = Path(__file__).resolve().parents[2] / "assets" / "motions"


def register(subparsers) -> None:
    p = subparsers.add_parser("search", help="find the library clips nearest to a motion file",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", default=str(DEFAULT_LIBRARY), help="labelled folder or saved index (default: bundled library)")
    p.add_argument("--query", required=True, help="motion file (.bvh, or .amc with --skeleton)")
    p.add_argument("--skeleton", help="ASF skeleton for an AMC query")
    p.add_argument("--top", type=int, default=5)
    p.add_argument("--dims", type=int, default=6, help="PCA components when indexing a folder")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate when indexing a folder")
    p.add_argument("--save-index", help="also save the index built from --data here")
    p.add_argument("--json", dest="json_out", help="write results as JSON here")
    p.set_defaults(func=run)


def run(args) -> int:
    from retrieval.library import MotionIndex

    data = Path(args.data)
    if args.top < 1:
        raise StoryBeamError("--top must be at least 1")
    if not data.exists():
        raise StoryBeamError(f"--data {data}: not found")
    query_path = Path(args.query)
    if not query_path.is_file():
        raise StoryBeamError(f"--query {query_path}: not found")
    try:
        from retrieval.motion.formats import load_motion
    except ImportError as exc:
        raise StoryBeamError(f"motion loaders unavailable: {exc}") from None
    index = MotionIndex.load(data) if MotionIndex.is_index(data) else MotionIndex.build(data, args.dims, args.fps)
    if args.save_index:
        index.save(args.save_index)
    motion = load_motion(query_path, args.skeleton) if args.skeleton else load_motion(query_path)
    matches = index.query(motion, k=args.top)
    print(f"{'rank':>4}  {'trial':<16} {'label':<10} distance")
    for i, m in enumerate(matches, 1):
        print(f"{i:>4}  {m.trial:<16} {m.label:<10} {m.distance:.5f}")
    if args.json_out:
        write_json_report(args.json_out, {"query": str(query_path), "results": [m.as_dict() for m in matches]})
    return 0
