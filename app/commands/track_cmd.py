"""`storybeam track`: the rig's tracking on a recording -- per frame the board's pose, how it was
found (detected, followed between detections, lost) and its reprojection error; the summary
as a table and, with --json, every frame."""
from __future__ import annotations

import argparse
from pathlib import Path

from app.commands.output import write_json_report
from retrieval.errors import StoryBeamError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "track", help="track a board through a video (pose per frame, how it was found)", description=__doc__,
        epilog="Without --camera the camera is assumed: 63 degrees field of view across the long side, square "
               "pixels, principal point at the image centre, no lens distortion (a phone's main camera).")
    p.add_argument("--video", type=Path, required=True, help="a video file, or a folder of images in name order")
    p.add_argument("--board", required=True, help="board spec, e.g. charuco:5x7:0.04:0.02:DICT_6X6_250")
    p.add_argument("--camera", type=Path, default=None,
                   help="camera.json from `storybeam calibrate camera` (default: assumed from the frame size)")
    p.add_argument("--json", dest="json_out", type=Path, default=None, help="write the per-frame report here")
    p.add_argument("--fps", type=float, default=None, help="frame rate of a folder of images (default 30)")
    p.add_argument("--limit", type=int, default=None, help="track at most this many frames")
    p.add_argument("--compare-plain", action="store_true",
                   help="also run OpenCV's plain detector (default settings) on every frame, side by side")
    p.add_argument("--no-follow", action="store_true",
                   help="do not follow the corners between detections (to measure what following brings)")
    p.add_argument("--no-rescue", action="store_true",
                   help="no rescue detection pass for dim, small, blurred boards (to measure what it brings)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm  # deferred: only long commands draw bars

    from ar.boards import Board  # deferred: loads OpenCV
    from ar.calibration import CameraCalibration  # deferred: loads OpenCV
    from ar.track_video import format_summary, open_recording, track_recording  # deferred: loads OpenCV

    if args.limit is not None and args.limit < 1:
        raise StoryBeamError(f"--limit must be at least 1, got {args.limit}")
    if args.fps is not None and not 0 < args.fps <= 1000:
        raise StoryBeamError(f"--fps must be between 0 and 1000, got {args.fps}")
    board = Board(args.board)
    camera = CameraCalibration.load(args.camera) if args.camera is not None else None
    source = open_recording(args.video, args.fps)
    total = getattr(source, "frame_count", 0) or len(getattr(source, "files", [])) or None
    if total and args.limit:
        total = min(total, args.limit)
    try:
        with tqdm(total=total, unit="frame", desc=f"track {Path(args.video).name}") as bar:
            report = track_recording(source, board, camera, plain=args.compare_plain, limit=args.limit,
                                     progress=bar.update, follow=not args.no_follow, rescue=not args.no_rescue)
    finally:
        source.close()
    cam = report["camera"]
    if cam["assumed"]:
        print(f"camera assumed (no --camera): {cam['hfov_deg']:g} deg field of view across the long side, principal point "
              f"at the centre, no distortion; fx = {cam['K'][0][0]:.1f} px at {cam['size'][0]}x{cam['size'][1]}")
    print(format_summary(report))
    if args.json_out:
        write_json_report(args.json_out, report)
    return 0
