"""`storybeam scan`: one pose's Gray-code captures -> the table as 3-D points and a height map.

Decodes the pose (``--graycode POSE_DIR``: its images of the sequence in name order),
triangulates every decoded camera pixel with the Gray-code calibration
(``storybeam calibrate projector --graycode ... --out projector.json``), writes the points
(camera frame, metres) as a PLY and, where the board is seen, the height map above the
board plane (``--height-map OUT.npz``, default next to the PLY).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from app.commands.output import emit_json_report
from retrieval.errors import StoryBeamError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("scan", help="scan the table from one pose's Gray-code captures (points + height map)",
                              description=__doc__)
    p.add_argument("--graycode", type=Path, required=True, metavar="POSE_DIR", help="one pose's Gray-code captures")
    p.add_argument("--calibration", type=Path, required=True, help="projector.json from calibrate projector --graycode")
    p.add_argument("--out", type=Path, required=True, help="SCAN.ply: the points, camera frame, metres")
    p.add_argument("--json", default=None, metavar="OUT", help="write the summary as JSON ('-' for stdout)")
    p.add_argument("--height-map", type=Path, default=None, help="height map .npz (default: SCAN.heights.npz)")
    p.add_argument("--board", default=None, help="board spec (default: the one the calibration used)")
    p.add_argument("--black-threshold", type=float, default=None, help="min white-black difference (default 40)")
    p.add_argument("--white-threshold", type=float, default=None, help="min pattern-inverse difference (default 5)")
    p.add_argument("--smooth", type=int, default=None, help="sub-pixel fit window, camera pixels (default 7; 1: off)")
    p.add_argument("--cell-mm", type=float, default=2.0, help="height map cell size in mm (default 2)")
    p.add_argument("--picture", type=Path, default=None,
                   help="PNG: the capture tinted by height beside the height map seen from above")
    p.add_argument("--truth", type=Path, default=None,
                   help="truth.json of synthetic captures (calibrate projector --graycode DIR --synthetic): "
                        "also report the height map's errors against it")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ar.boards import DEFAULT_BOARD_SPEC, Board  # deferred: OpenCV loads only for this command
    from ar.structured_light.calibrate import GrayCodeCalibration  # deferred: as above
    from ar.structured_light.decode import (DEFAULT_BLACK_THRESHOLD, DEFAULT_WHITE_THRESHOLD,  # deferred: as above
                                            decode_pose_folder)
    from ar.structured_light.scan import DEFAULT_SMOOTH_PX, scan_picture, scan_pose, write_ply  # deferred: as above

    if not args.cell_mm > 0:
        raise StoryBeamError(f"--cell-mm must be positive, got {args.cell_mm}")
    calib = GrayCodeCalibration.load(args.calibration)
    board = Board(args.board or calib.board or DEFAULT_BOARD_SPEC)
    decoded = decode_pose_folder(args.graycode, calib.projector.image_size,
                                 DEFAULT_BLACK_THRESHOLD if args.black_threshold is None else args.black_threshold,
                                 DEFAULT_WHITE_THRESHOLD if args.white_threshold is None else args.white_threshold)
    print(f"decoded {decoded.name}: {100 * decoded.mask.mean():.1f} % of camera pixels")
    scan = scan_pose(decoded, calib, board, DEFAULT_SMOOTH_PX if args.smooth is None else args.smooth,
                     args.cell_mm / 1000.0)
    write_ply(args.out, scan.points, scan.grey)
    print(f"{len(scan.points)} points -> {args.out}")
    report = {"pose": decoded.name, "calibration": str(args.calibration), "ply": str(args.out), **scan.summary()}
    if scan.height_map is None:
        print(scan.note)
    else:
        hm_path = args.height_map or args.out.with_suffix(".heights.npz")
        scan.height_map.save(hm_path)
        hm = scan.height_map
        print(f"board plane: {scan.board_plane_rms_mm:.3f} mm RMS over {scan.board_points} points")
        print(f"height map {hm.shape[1]}x{hm.shape[0]} cells of {hm.cell_m * 1000:g} mm, "
              f"{100 * hm.known_fraction:.0f} % known -> {hm_path}")
        report["height_map"]["path"] = str(hm_path)
        if args.truth is not None:
            report["vs_truth"] = _truth_errors(args.truth, hm)
    if args.picture is not None:
        import cv2  # deferred: OpenCV, as above

        args.picture.parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(args.picture), scan_picture(decoded, scan)):
            raise StoryBeamError(f"{args.picture}: cannot write the picture (a .png name?)")
        print(f"picture -> {args.picture}")
    emit_json_report(args.json, report)
    return 0


def _truth_errors(path: Path, height_map) -> dict:
    """The height map against a synthetic capture's truth (boxes and table), printed."""
    import json  # deferred: only with --truth

    from ar.structured_light.synthetic import boxes_from_truth, height_map_errors  # deferred: only with --truth

    try:
        truth = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise StoryBeamError(f"{path}: cannot read the truth file: {exc}") from None
    if not isinstance(truth, dict):
        raise StoryBeamError(f"{path}: expected a JSON object")
    errors = height_map_errors(height_map, boxes_from_truth(truth))
    for b in errors["boxes"]:
        print(f"vs truth: box {b['height_mm']:.1f} mm tall -> median {b['median_mm']:.2f} mm over {b['top_cells']} "
              f"cells of its top (error {b['error_mm']:+.2f} mm)")
    t = errors["table"]
    print(f"vs truth: table |height| median {t['abs_median_mm']:.2f} mm, 95th percentile {t['abs_p95_mm']:.2f} mm "
          f"over {t['cells']} cells")
    return errors
