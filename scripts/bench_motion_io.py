"""Time loading every motion listed in a dataset's labels.csv.

    .venv/bin/python scripts/bench_motion_io.py [--data ../shared/data/cmu] [--repeat 3]
"""
from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

from retrieval.motion.formats import clear_skeleton_cache, load_motion


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path("../shared/data/cmu"))
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with open(args.data / "labels.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    best = None
    for _ in range(args.repeat):
        clear_skeleton_cache()
        frames = 0
        start = time.perf_counter()
        for r in rows:
            skeleton = args.data / r["skeleton"] if r["skeleton"] else None
            frames += load_motion(args.data / r["file"], skeleton).n_frames
        elapsed = time.perf_counter() - start
        best = elapsed if best is None else min(best, elapsed)
    print(f"{len(rows)} files, {frames} frames: best of {args.repeat} {best:.2f} s ({frames / best:.0f} frames/s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
