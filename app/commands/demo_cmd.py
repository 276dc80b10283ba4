"""`storybeam demo`: the whole pipeline on a fresh machine from bundled assets only —
index the bundled motions, retrieve a walk for a sample query, walk a character along a
drawn loop, render it through the synthetic hand-held rig, and write out/demo.mp4 and
out/demo.json (retrieved clip, path error, foot skate, render time, landing error)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from app.commands.render_cmd import parse_size


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("demo", help="end-to-end demo: retrieve, animate, render -> out/demo.mp4 + out/demo.json",
                              description=__doc__)
    p.add_argument("--out-dir", type=Path, default=Path("out"), help="output folder (default out/)")
    p.add_argument("--seconds", type=float, default=10.0, help="animation length (default 10)")
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--size", default="640x480", help="frame size WxH (default 640x480)")
    p.add_argument("--view", choices=("projector", "camera", "overhead", "all"), default="all",
                   help="which view the MP4 shows (default all: camera | projector | overhead side by side)")
    p.add_argument("--character", default="robot", help="robot, cat or kid")
    p.add_argument("--max-frames", type=int, help="stop after this many frames (quick checks)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # deferred: the scene layer (pyrender, OpenGL, the motion library) loads only for this command
    from app.player.demo_pipeline import DemoConfig, run_demo

    w, h = parse_size(args.size)
    out = args.out_dir
    cfg = DemoConfig(seconds=args.seconds, fps=args.fps, width=w, height=h, character=args.character,
                     view=args.view, video=out / "demo.mp4", json_path=out / "demo.json",
                     index_dir=out / "motion_index", max_frames=args.max_frames, progress=not args.quiet)
    report = run_demo(cfg)
    keys = ("retrieved", "path_error_cm", "foot_skate_cm_per_m", "render_ms_median", "landing_error_mm", "frames")
    print(json.dumps({k: report[k] for k in keys}, indent=2))
    print(f"wrote {cfg.video} and {cfg.json_path} in {report['total_s']} s")
    return 0
