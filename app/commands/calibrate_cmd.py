"""`storybeam calibrate camera|projector`: intrinsics of the camera, then projector + rig extrinsics
(from the guided three-image captures, or from Gray-code captures with ``--graycode``)."""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from retrieval.errors import StoryBeamError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("calibrate", help="calibrate the camera or the projector-camera rig", description=__doc__)
    sub = p.add_subparsers(dest="target", metavar="TARGET")
    sub.required = True

    cam = sub.add_parser("camera", help="camera intrinsics + distortion from board images")
    src = cam.add_mutually_exclusive_group(required=True)
    src.add_argument("--images", type=Path, help="folder of board images")
    src.add_argument("--camera-index", type=int, help="live camera index (captures --views frames)")
    src.add_argument("--synthetic", action="store_true", help="calibrate the synthetic bench camera (self-check)")
    cam.add_argument("--views", type=int, default=15, help="views to capture live / render synthetically")
    cam.add_argument("--board", default=None, help="board spec (default: ChArUco default board)")
    cam.add_argument("--reject-px", type=float, default=1.0, help="views fitting worse than this (and 3x median) are dropped")
    cam.add_argument("--out", type=Path, required=True, help="camera.json")
    cam.set_defaults(func=run_camera)

    proj = sub.add_parser("projector", help="projector intrinsics + camera->projector transform",
                          description="Works on a folder written by a capture run (step_XX_{dark,white,pattern}.png "
                                      "+ capture.json), or with --graycode on Gray-code captures (Moreno-Taubin). "
                                      "--synthetic runs the sequence on the synthetic rig (writing the captures to "
                                      "--images / --graycode when given) and reports errors vs truth.")
    proj.add_argument("--images", type=Path, help="capture folder")
    proj.add_argument("--graycode", type=Path, metavar="DIR",
                      help="Gray-code captures: one sub-folder per board pose, each with the camera's images of "
                           "OpenCV's GrayCodePattern sequence (its patterns, then white, then black) in name order")
    proj.add_argument("--projector-size", metavar="WxH", help="projector resolution, e.g. 1024x768 (with --graycode)")
    proj.add_argument("--black-threshold", type=float, default=None,
                      help="--graycode: min white-black difference for a lit pixel (default 40, OpenCV's)")
    proj.add_argument("--white-threshold", type=float, default=None,
                      help="--graycode: min pattern-inverse difference for a reliable bit (default 5, OpenCV's)")
    proj.add_argument("--window", type=int, default=None,
                      help="--graycode: local homography window, pixels either side of a corner (default 24)")
    proj.add_argument("--truth", type=Path, default=None,
                      help="--graycode: truth.json of synthetic captures; print the errors against it "
                           "(--synthetic does so by itself)")
    proj.add_argument("--conditions", choices=("clean", "dim"), default="clean",
                      help="--graycode --synthetic: clean (noise 1 grey level) or dim (a third of the light, "
                           "noise 2, shot noise, 0.8 px blur)")
    proj.add_argument("--poses", type=int, default=5, help="--graycode --synthetic: board poses to render (default 5), "
                                                                     "then one scan pose (board and a 30 mm box)")
    proj.add_argument("--camera", type=Path, help="camera.json (with --synthetic: optional, else calibrated first)")
    proj.add_argument("--board", default=None, help="board spec (default: ChArUco default board)")
    proj.add_argument("--synthetic", action="store_true", help="drive the guided sequence on the synthetic rig")
    proj.add_argument("--steps", type=int, default=8, help="capture steps for --synthetic (default 8)")
    proj.add_argument("--show-steps", action="store_true", help="print the guided capture instructions and exit")
    proj.add_argument("--out", type=Path, help="projector.json")
    proj.set_defaults(func=run_projector)


def run_camera(args: argparse.Namespace) -> int:
    from ar.boards import DEFAULT_BOARD_SPEC, Board  # deferred: OpenCV loads only for this command
    from ar.calibration import calibrate_camera, capture_from_camera, load_images  # deferred: OpenCV, as above

    board = Board(args.board or DEFAULT_BOARD_SPEC)
    truth = None
    if args.images:
        views = load_images(args.images)
    elif args.synthetic:
        from ar.synthetic import SyntheticCamera, calibration_poses  # deferred: the synthetic rig only for --synthetic

        cam = SyntheticCamera(board)
        views = [(f"synthetic_{i:02d}", cam.render(T)) for i, T in enumerate(calibration_poses(board, args.views))]
        truth = cam.camera
    else:
        print(f"capturing {args.views} views from camera {args.camera_index}; move the board between captures")
        views = capture_from_camera(args.camera_index, args.views, board)
    calib = calibrate_camera(views, board, reject_px=args.reject_px)
    calib.save(args.out)
    K = calib.camera_matrix
    print(f"RMS reprojection error: {calib.rms:.3f} px over {len(calib.per_view_errors)} views "
          f"({len(calib.rejected_views)} rejected)")
    for name, why in calib.rejected_views.items():
        print(f"  rejected {name}: {why}")
    print(f"fx={K[0, 0]:.2f} fy={K[1, 1]:.2f} cx={K[0, 2]:.2f} cy={K[1, 2]:.2f} dist={[round(float(v), 4) for v in calib.dist_coeffs]}")
    if truth is not None:
        print(f"vs truth: fx error {100 * (K[0, 0] / truth.K[0, 0] - 1):+.3f} %, fy error {100 * (K[1, 1] / truth.K[1, 1] - 1):+.3f} %")
    print(f"wrote {args.out}")
    return 0


def run_projector(args: argparse.Namespace) -> int:
    from ar.boards import DEFAULT_BOARD_SPEC, Board  # deferred: OpenCV loads only for this command
    # deferred: OpenCV loads only for this command
    from ar.calibration import (CameraCalibration, ProjectorCalibrationSequence, calibrate_camera,
                                calibrate_projector_from_folder, extrinsics_error, write_capture)

    board = Board(args.board or DEFAULT_BOARD_SPEC)
    sequence = ProjectorCalibrationSequence(board, n_steps=args.steps)
    if args.show_steps:
        for step in sequence:
            print(step.instruction)
        return 0
    if args.out is None:
        raise StoryBeamError("--out is required")
    if args.graycode is not None:
        return run_projector_graycode(args, board)
    if args.synthetic:
        # deferred: the synthetic rig only for --synthetic
        from ar.synthetic import SyntheticCamera, calibration_poses, capture_projector_sequence

        cam = SyntheticCamera(board)
        if args.camera:
            camera = CameraCalibration.load(args.camera)
        else:
            views = [(f"synthetic_{i:02d}", cam.render(T)) for i, T in enumerate(calibration_poses(board, 12))]
            camera = calibrate_camera(views, board)
            print(f"camera calibrated on 12 synthetic views: RMS {camera.rms:.3f} px")
        folder = args.images or Path(tempfile.mkdtemp(prefix="storybeam_projcal_"))
        captures = capture_projector_sequence(cam, sequence)
        for step, *_ in captures:
            print(step.instruction)
        write_capture(folder, [(step, frames, pattern) for step, _T, pattern, frames in captures], cam.projector.size)
        print(f"captures written to {folder}")
    else:
        if not args.images or not args.camera:
            raise StoryBeamError("--images and --camera are required (or use --synthetic)")
        camera = CameraCalibration.load(args.camera)
        folder = args.images
    calib = calibrate_projector_from_folder(folder, board, camera)
    calib.save(args.out)
    K, t = calib.camera_matrix, calib.t_proj_from_cam
    print(f"projector RMS reprojection error: {calib.rms:.3f} px ({len(calib.per_view_errors)} steps used, "
          f"{len(calib.rejected_views)} rejected)")
    for name, why in calib.rejected_views.items():
        print(f"  rejected {name}: {why}")
    print(f"projector fx={K[0, 0]:.1f} fy={K[1, 1]:.1f} cx={K[0, 2]:.1f} cy={K[1, 2]:.1f}; "
          f"camera->projector t = ({t[0] * 1000:.1f}, {t[1] * 1000:.1f}, {t[2] * 1000:.1f}) mm")
    if args.synthetic:
        rot, trans = extrinsics_error(calib, cam.proj_from_cam)
        print(f"vs truth: extrinsics {rot:.3f} deg, {trans:.2f} mm; projector fx error "
              f"{100 * (K[0, 0] / cam.projector.K[0, 0] - 1):+.3f} %")
    print(f"wrote {args.out}")
    return 0


def run_projector_graycode(args: argparse.Namespace, board) -> int:
    """``calibrate projector --graycode DIR``: decode, local homographies, camera/projector/stereo calibration."""
    import numpy as np  # deferred: with OpenCV, only for this command
    from ar.calibration import CameraCalibration  # deferred: OpenCV loads only for this command
    from ar.geometry import rotation_angle_deg  # deferred: as above
    from ar.structured_light.calibrate import DEFAULT_WINDOW_PX, calibrate_graycode_folder  # deferred: as above
    from ar.structured_light.decode import DEFAULT_BLACK_THRESHOLD, DEFAULT_WHITE_THRESHOLD  # deferred: as above
    from ar.structured_light.patterns import parse_projector_size  # deferred: as above

    if args.images is not None:
        raise StoryBeamError("give either --images (guided captures) or --graycode (Gray-code captures), not both")
    camera = CameraCalibration.load(args.camera) if args.camera else None
    truth_path = args.truth
    if args.synthetic:
        # deferred: the synthetic rig only for --synthetic
        from ar.structured_light.synthetic import (GrayCodeScene, default_scan_box, graycode_poses, scan_view,
                                                   write_graycode_captures)
        from ar.synthetic import SyntheticCamera, default_projector  # deferred: as above

        projector = default_projector()
        if args.projector_size:
            projector = projector.scaled(*parse_projector_size(args.projector_size))
        cam = SyntheticCamera(board, projector=projector)
        box = default_scan_box(board)
        scene = GrayCodeScene(cam, [box])
        poses = graycode_poses(board, cam.proj_from_cam, args.poses)
        fov = (projector.width / projector.K[0, 0], projector.height / projector.K[1, 1])
        poses.append(scan_view(board, box, cam.proj_from_cam, fov))
        from ar.synthetic import Degradation  # deferred: as above

        degradation = (Degradation(noise_sigma=2.0, blur_sigma=0.8, exposure=0.35, shot_noise=0.5)
                       if args.conditions == "dim" else None)
        write_graycode_captures(args.graycode, scene, poses, degradation, progress=print, scan_pose=len(poses) - 1)
        size, truth_path = projector.size, truth_path or args.graycode / "truth.json"
        print(f"synthetic captures written to {args.graycode}")
    elif not args.projector_size:
        raise StoryBeamError("--projector-size WxH is required with --graycode (the resolution the patterns were made for)")
    else:
        size = parse_projector_size(args.projector_size)
    calib = calibrate_graycode_folder(
        args.graycode, board, size, camera,
        DEFAULT_BLACK_THRESHOLD if args.black_threshold is None else args.black_threshold,
        DEFAULT_WHITE_THRESHOLD if args.white_threshold is None else args.white_threshold,
        DEFAULT_WINDOW_PX if args.window is None else args.window, progress=print)
    calib.save(args.out)
    Kc, Kp, T = calib.camera.camera_matrix, calib.projector.camera_matrix, calib.T
    print(f"camera    fx={Kc[0, 0]:.2f} fy={Kc[1, 1]:.2f} cx={Kc[0, 2]:.2f} cy={Kc[1, 2]:.2f} "
          f"dist={[round(float(v), 4) for v in calib.camera.dist_coeffs]} (RMS {calib.camera.rms:.3f} px"
          f"{', given' if camera is not None else ''})")
    print(f"projector fx={Kp[0, 0]:.2f} fy={Kp[1, 1]:.2f} cx={Kp[0, 2]:.2f} cy={Kp[1, 2]:.2f} "
          f"dist={[round(float(v), 4) for v in calib.projector.dist_coeffs]} (RMS {calib.projector_rms:.3f} px)")
    print(f"camera -> projector: T = ({T[0] * 1000:.2f}, {T[1] * 1000:.2f}, {T[2] * 1000:.2f}) mm, "
          f"|T| = {np.linalg.norm(T) * 1000:.2f} mm, R = {rotation_angle_deg(calib.R):.3f} deg")
    print(f"stereo RMS {calib.rms:.3f} px over {len(calib.per_pose)} poses")
    print("  pose            corners  camera px  projector px")
    for name, e in calib.per_pose.items():
        print(f"  {name:<15} {e['corners']:>7}  {e['camera_px']:>9.3f}  {e['projector_px']:>12.3f}")
    for name, why in calib.rejected_poses.items():
        print(f"  rejected {name}: {why}")
    if truth_path is not None:
        _print_truth_errors(truth_path, calib)
    print(f"wrote {args.out}")
    return 0


def _print_truth_errors(path: Path, calib) -> None:
    """The Gray-code calibration against a synthetic capture's ``truth.json``."""
    import json  # deferred: only with a truth file

    import numpy as np  # deferred: as above

    from ar.geometry import rotation_angle_deg  # deferred: as above

    try:
        truth = json.loads(Path(path).read_text())
        Kt = np.array(truth["projector"]["camera_matrix"], float)
        Kc = np.array(truth["camera"]["camera_matrix"], float)
        Rt, Tt = np.array(truth["R"], float), np.array(truth["T"], float)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise StoryBeamError(f"{path}: not a synthetic capture's truth file ({exc})") from None
    Kp, K = calib.projector.camera_matrix, calib.camera.camera_matrix
    print(f"vs truth: projector fx {100 * (Kp[0, 0] / Kt[0, 0] - 1):+.3f} %, fy {100 * (Kp[1, 1] / Kt[1, 1] - 1):+.3f} %; "
          f"camera fx {100 * (K[0, 0] / Kc[0, 0] - 1):+.3f} %; T {np.linalg.norm(calib.T - Tt) * 1000:.3f} mm; "
          f"R {rotation_angle_deg(calib.R @ Rt.T):.4f} deg")
