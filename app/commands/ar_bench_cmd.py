"""`storybeam ar-bench`: tracking accuracy, jitter, landing error and timing on synthetic frames."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from app.commands.output import write_json_report


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("ar-bench", help="measure AR tracking/rendering on synthetic camera frames",
                              description=__doc__)
    p.add_argument("--frames", type=int, default=100, help="frames per condition (default 100)")
    p.add_argument("--board", default=None, help="board spec (default: the ChArUco default board)")
    p.add_argument("--json", dest="json_out", type=Path, help="write the full result as JSON here")
    p.add_argument("--conditions", default=None, help="comma-separated subset of conditions to run")
    p.add_argument("--true-calibration", action="store_true",
                   help="use the synthetic rig's true calibration instead of calibrating it first")
    p.add_argument("--examples", type=Path, help="write example frames (ar_*.png) into this folder")
    p.add_argument("--blur-sigma", type=float, default=1.5, help="Gaussian blur of the 'blur' condition, px (default 1.5)")
    p.add_argument("--filter", choices=("kalman", "one-euro"), default="kalman",
                   help="pose filter whose jitter is reported (default kalman)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from tqdm import tqdm

    from app.bench.ar import BenchConfig, default_conditions, format_table, run_bench
    from ar.boards import DEFAULT_BOARD_SPEC, Board
    from retrieval.errors import StoryBeamError

    if args.frames < 2:
        raise StoryBeamError("--frames must be at least 2")
    conditions = default_conditions(blur_sigma=args.blur_sigma)
    if args.conditions:
        wanted = [c.strip() for c in args.conditions.split(",") if c.strip()]
        known = {c.name for c in conditions}
        unknown = [w for w in wanted if w not in known]
        if unknown:
            raise StoryBeamError(f"unknown condition(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
        conditions = [c for c in conditions if c.name in wanted]
    spec = args.board or DEFAULT_BOARD_SPEC
    Board(spec)  # validate early, before the long run
    cfg = BenchConfig(frames=args.frames, board_spec=spec, estimated_calibration=not args.true_calibration,
                      seed=args.seed, conditions=conditions, pose_filter=args.filter)
    examples = {} if args.examples else None
    with tqdm(total=args.frames * len(conditions), unit="frame", desc="ar-bench") as bar:
        result = run_bench(cfg, progress=bar.update, examples=examples)
    print(format_table(result))
    cal = result["calibration"]
    if "camera_fx_error_pct" in cal:
        print(f"calibration: camera rms {cal['camera_rms_px']:.3f} px, fx error {cal['camera_fx_error_pct']:+.3f} %; "
              f"projector rms {cal['projector_rms_px']:.3f} px, fx error {cal['projector_fx_error_pct']:+.3f} %; "
              f"extrinsics {cal['extrinsics_rot_err_deg']:.3f} deg, {cal['extrinsics_trans_err_mm']:.2f} mm")
    print(f"landing error (clean, median): {result['landing_error_mm_median']:.2f} mm; "
          f"detect+pose {result['detect_pose_ms_median']:.1f} ms; render {result['render_ms_median']:.1f} ms (medians)")
    if args.json_out:
        write_json_report(args.json_out, result, indent=2)
    if examples:
        _write_examples(args.examples, examples)
    return 0


#: conditions whose middle frame is written by --examples (the ones docs/ar.md shows)
EXAMPLE_CONDITIONS = ("clean", "occlusion_30", "low_light")


def _write_examples(folder: Path, examples: dict) -> None:
    """Half-size, 64-colour PNGs (small enough to commit) of the example frames."""
    import cv2
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    for cond, images in examples.items():
        if cond not in EXAMPLE_CONDITIONS:
            continue
        for kind, img in images.items():
            rgb = img if kind == "projector_view" else img[..., ::-1]  # renders are RGB, camera frames BGR
            small = cv2.resize(rgb, (rgb.shape[1] // 2, rgb.shape[0] // 2), interpolation=cv2.INTER_AREA)
            im = Image.fromarray(small).quantize(colors=64, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
            im.save(folder / f"ar_{cond}_{kind}.png", optimize=True)
    print(f"wrote example frames to {folder}")
