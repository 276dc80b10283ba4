"""The "Act it out" test video: a human-proportioned figure walking in place, facing the camera.

``python -m tests.support.act_video [OUT.mp4] [--trial 07_05] [--data ../shared/data/cmu]``
renders it with the bench's synthetic filming (:func:`lab.bench.act_it_out.make_performance`
and :func:`lab.bench.act_it_out.render_frames`: the ``"person"`` design 1.7 m tall,
pyrender at 640x480, 30 fps, a level camera 3.6 m in front, plain wall and floor) and writes
an MP4 (OpenCV's ``mp4v``). The stored copy, tests/app/data/act_walk_07_05.mp4, was made
by this module; trial 07_05 (a walk of subject 07) is not in the bundled library, so the
app's search sees a performance it was not built from.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
STORED = REPO / "tests" / "app" / "data" / "act_walk_07_05.mp4"
TRIAL = "07_05"


def render_walk_video(out: Path, trial: str = TRIAL, data: Path | None = None) -> Path:
    """Render ``trial`` of the labelled folder ``data`` (default: the shared CMU set)
    performed by the "person" figure into the MP4 ``out``; returns ``out``."""
    import cv2

    from lab.bench.act_it_out import FPS, HEIGHT, WIDTH, make_performance, render_frames
    from app.paths import SHARED_CMU
    from retrieval.library import read_labels

    data = Path(data or SHARED_CMU)
    row = next((r for r in read_labels(data) if r.trial == trial), None)
    if row is None:
        raise SystemExit(f"{data}: no trial {trial}")
    perf = make_performance(row, "person")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".part" + out.suffix)
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (WIDTH, HEIGHT))
    try:
        for frame in render_frames(perf, "person"):
            writer.write(frame)
    finally:
        writer.release()
    tmp.replace(out)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out", nargs="?", default=str(STORED))
    p.add_argument("--trial", default=TRIAL)
    p.add_argument("--data", default=None)
    args = p.parse_args(argv)
    path = render_walk_video(Path(args.out), args.trial, Path(args.data) if args.data else None)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
