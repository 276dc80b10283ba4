"""``storybeam build-library``: build the app's bundled motion library from the shared CMU data.

    storybeam build-library --data ../shared/data/cmu --out assets/motions
                            [--fps 30] [--max-seconds 10] [--decimals 4] [--quiet]

Reads ``labels.csv`` of the labelled folder ``--data``, takes the hand-picked trials of
:data:`retrieval.library.bundle.SELECTION`, resamples each to ``--fps``, cuts it to at most
``--max-seconds`` and writes it as BVH (centimetres, ``--decimals`` decimals) into
``--out``, with the library's own ``labels.csv`` and ``CREDITS.md``
(see :func:`retrieval.library.bundle.build`).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from app.progress import progress_bar
from retrieval.errors import StoryBeamError

#: Bounds of the numeric options (a typo such as ``--fps 0`` is an error, not a broken library).
FPS_RANGE = (1.0, 240.0)
DECIMALS_RANGE = (1, 8)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``build-library`` parser (options ported from the old ``retrieval.library.bundle`` CLI)."""
    p = subparsers.add_parser("build-library", help="build the bundled motion library from the shared CMU data",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, required=True, help="shared CMU folder (with labels.csv)")
    p.add_argument("--out", type=Path, required=True, help="library folder to write (e.g. assets/motions)")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate of the bundled clips (default 30)")
    p.add_argument("--max-seconds", type=float, default=10.0, help="cut each clip to at most this long (default 10)")
    p.add_argument("--decimals", type=int, default=4, help="decimals of the BVH numbers (default 4)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def check_args(args: argparse.Namespace) -> None:
    """Refuse bad input before anything is written: a missing ``--data`` folder or one
    without ``labels.csv``, ``--out`` equal to ``--data`` (the source would be
    overwritten), or a numeric option out of range. Raises :class:`StoryBeamError`."""
    data: Path = args.data
    if not data.is_dir():
        raise StoryBeamError(f"--data {data}: not a folder (give the shared CMU folder, with labels.csv)")
    if not (data / "labels.csv").is_file():
        raise StoryBeamError(f"--data {data}: no labels.csv (is it the labelled CMU folder?)")
    if args.out.exists() and not args.out.is_dir():
        raise StoryBeamError(f"--out {args.out}: exists and is not a folder")
    if args.out.resolve() == data.resolve():
        raise StoryBeamError(f"--out {args.out}: is the --data folder; the library must go elsewhere")
    if not FPS_RANGE[0] <= args.fps <= FPS_RANGE[1]:
        raise StoryBeamError(f"--fps must be between {FPS_RANGE[0]:g} and {FPS_RANGE[1]:g}, got {args.fps:g}")
    if not args.max_seconds > 0:
        raise StoryBeamError(f"--max-seconds must be positive, got {args.max_seconds:g}")
    if not DECIMALS_RANGE[0] <= args.decimals <= DECIMALS_RANGE[1]:
        raise StoryBeamError(f"--decimals must be between {DECIMALS_RANGE[0]} and {DECIMALS_RANGE[1]}, "
                             f"got {args.decimals}")


def run(args: argparse.Namespace) -> int:
    """Check the options, build the library with a per-clip progress bar, print its size."""
    check_args(args)
    # deferred: the motion loaders and writers (numpy) load only for this command
    from retrieval.library import build_bundle

    rows = build_bundle(args.data, args.out, args.fps, args.max_seconds, args.decimals,
                 progress=progress_bar("building library", "clip", not args.quiet))
    size = sum(f.stat().st_size for f in args.out.rglob("*") if f.is_file())
    seconds = sum(float(r["seconds"]) for r in rows)
    print(f"wrote {len(rows)} clips, {seconds:.1f} s, {size / 1e6:.2f} MB to {args.out}")
    return 0
