"""`storybeam render`: render the animated character through the synthetic rig to an MP4
(or one frame to a PNG)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from retrieval.errors import StoryBeamError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("render", help="render the animated character (projector, camera or overhead view) to MP4/PNG",
                              description=__doc__)
    p.add_argument("--demo", action="store_true", help="render the bundled demo scene (the only scene so far)")
    p.add_argument("--out", type=Path, default=Path("out/demo.mp4"), help="MP4 to write (default out/demo.mp4)")
    p.add_argument("--view", choices=("projector", "camera", "overhead", "all"), default="camera",
                   help="which view goes into the video; 'all' puts the three side by side")
    p.add_argument("--still", type=int, metavar="N", help="render only up to frame N and save it as a PNG (see --png)")
    p.add_argument("--png", type=Path, help="PNG path for --still (with --view all, also <name>_<view>.png per view)")
    p.add_argument("--seconds", type=float, default=10.0, help="animation length (default 10)")
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--size", default="640x480", help="frame size WxH (default 640x480)")
    p.add_argument("--character", default="robot", help="robot, cat or kid")
    p.add_argument("--json", dest="json_out", type=Path, help="also write the run's report as JSON")
    p.add_argument("--index-dir", type=Path, default=Path("out/motion_index"),
                   help="where the motion index is cached (built on first use)")
    p.set_defaults(func=run)


def parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise StoryBeamError(f"--size must look like 640x480, got {text!r}") from None
    return w, h


def run(args: argparse.Namespace) -> int:
    # deferred: the scene layer (pyrender, OpenGL, the motion library) loads only for this command
    from app.player.demo_pipeline import DemoConfig, run_demo

    if not args.demo:
        raise StoryBeamError("only the bundled demo scene can be rendered so far: pass --demo")
    if (args.still is None) != (args.png is None):
        raise StoryBeamError("--still N and --png PATH go together")
    w, h = parse_size(args.size)
    cfg = DemoConfig(seconds=args.seconds, fps=args.fps, width=w, height=h, character=args.character,
                     view=args.view, video=None if args.still is not None else args.out,
                     json_path=args.json_out, index_dir=args.index_dir, still_frame=args.still, still_png=args.png)
    if args.still is not None and args.view == "all":  # also each view on its own
        cfg.stills = {v: args.png.with_name(f"{args.png.stem}_{v}{args.png.suffix}") for v in ("camera", "projector", "overhead")}
    report = run_demo(cfg)
    target = args.png if args.still is not None else args.out
    print(f"wrote {target} ({report['frames']} frames rendered, character render median "
          f"{report['render_ms_median']} ms at {w}x{h})")
    if args.json_out:
        print(json.dumps({k: report[k] for k in ("path_error_cm", "foot_skate_cm_per_m", "render_ms_median")}))
    return 0
