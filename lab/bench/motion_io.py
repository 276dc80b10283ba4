"""Time loading every motion listed in a dataset's labels.csv
(``storybeam bench motion-io [--data ../shared/data/cmu] [--repeat 3]``).

Method: the rows of ``<data>/labels.csv`` (columns ``file`` and ``skeleton``, the latter
empty for self-describing formats such as BVH) are loaded with
:func:`retrieval.motion.formats.load_motion`, ``repeat`` times; the skeleton cache is
cleared before each pass so every pass parses the skeletons too, and the best pass is
reported (frames per second of wall-clock time).
"""
from __future__ import annotations

import csv
import time
from pathlib import Path

from app.paths import SHARED_CMU
from retrieval.errors import DatasetError, StoryBeamError
from retrieval.motion.formats import clear_skeleton_cache, load_motion

#: the dataset timed by default: the shared CMU set beside the checkout ($STORYBEAM_SHARED_DATA/cmu)
DEFAULT_DATA = SHARED_CMU


def read_labels(data: Path) -> list[dict[str, str]]:
    """The rows of ``data/labels.csv``; :class:`DatasetError` if it is missing or lacks
    the ``file`` column."""
    labels = data / "labels.csv"
    if not labels.is_file():
        raise DatasetError(f"{labels} not found: --data must be a folder with a labels.csv")
    with open(labels, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise DatasetError(f"{labels} lists no motions")
    if "file" not in rows[0]:
        raise DatasetError(f"{labels} has no 'file' column")
    return rows


def run_motion_io_bench(data: str | Path = DEFAULT_DATA, repeat: int = 3) -> dict:
    """Load every motion of ``data`` ``repeat`` times; returns ``{"data", "files",
    "frames", "repeat", "best_seconds", "frames_per_second", "pass_seconds"}``."""
    if repeat < 1:
        raise StoryBeamError(f"--repeat must be at least 1, got {repeat}")
    data = Path(data)
    rows = read_labels(data)
    passes = []
    frames = 0
    for _ in range(repeat):
        clear_skeleton_cache()
        frames = 0
        start = time.perf_counter()
        for r in rows:
            skeleton = data / r["skeleton"] if r.get("skeleton") else None
            frames += load_motion(data / r["file"], skeleton).n_frames
        passes.append(time.perf_counter() - start)
    best = min(passes)
    return {"data": str(data), "files": len(rows), "frames": frames, "repeat": repeat, "best_seconds": best,
            "frames_per_second": frames / best if best > 0 else float("inf"), "pass_seconds": passes}


def format_table(result: dict) -> str:
    """One line: files, frames, best pass and throughput."""
    return (f"{result['files']} files, {result['frames']} frames: best of {result['repeat']} "
            f"{result['best_seconds']:.2f} s ({result['frames_per_second']:.0f} frames/s)")
