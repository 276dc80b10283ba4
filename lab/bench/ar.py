"""The AR bench: tracking accuracy, jitter, landing error and timing on synthetic frames.

For each named condition a handheld trajectory is rendered by the synthetic camera;
every frame goes through the product's frame loop (:meth:`ar.rig.RigTracker.step`: region
detection, IPPE pose, the Kalman (or One-Euro) tracker, projector pose), then the
projector render, and is compared with the ground truth.

The chain uses *estimated* calibrations by default (camera calibrated from 12
synthetic views, projector calibrated with the guided sequence on the synthetic rig),
so the landing error includes calibration error, as it would on a real rig.

Definitions
    rotation / translation error: angle of ``R_est^T R_true`` (deg); distance between
    estimated and true board origin in camera coordinates (mm); on raw (unfiltered)
    per-frame poses.
    jitter: RMS of the frame-to-frame *change of the error* (consecutive tracked
    frames); true motion cancels, so this is the shake a viewer would see.
    landing error: see :mod:`ar.closed_loop`; measured every ``landing_every`` frames
    with the filtered pose.
"""
from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from ar.boards import Board, DEFAULT_BOARD_SPEC
from ar.calibration import (CameraCalibration, ProjectorCalibration, ProjectorCalibrationSequence,
                            calibrate_camera, calibrate_projector, extract_projector_view, extrinsics_error)
from ar.closed_loop import LandingCheck
from ar.filtering import TRACKING, PoseKalmanFilter, PoseOneEuroFilter, PoseTracker
from ar.geometry import pose_error, rotation_angle_deg
from ar.pose import draw_pose, estimate_board_pose
from ar.render import ProjectorRenderer, add_test_scene
from ar.rig import ProjectedLight, RigTracker
from ar.scene import SceneDescription, View, add_character, board_from_scene, build_character, rest_motion, scaled_model
from ar.synthetic import (Degradation, SyntheticCamera, TrajectoryConfig, calibration_poses,
                          capture_projector_sequence, default_camera, default_proj_from_cam, default_projector,
                          handheld_trajectory)


@dataclass
class Condition:
    name: str
    trajectory: TrajectoryConfig
    degradation: Degradation
    description: str


def default_conditions(blur_sigma: float = 1.5) -> list[Condition]:
    """The bench's named conditions (clean = 0.5 m, 25 degree tilt, only 1-level read noise)."""
    def traj(**kw):
        return TrajectoryConfig(**kw)

    return [
        Condition("clean", traj(), Degradation(), "0.5 m, 25 deg tilt, read noise sigma 1"),
        Condition("noise", traj(), Degradation(noise_sigma=8.0), "read noise sigma 8 grey levels"),
        Condition("blur", traj(), Degradation(blur_sigma=blur_sigma), f"Gaussian blur sigma {blur_sigma:g} px"),
        Condition("low_light", traj(), Degradation(exposure=0.15, noise_sigma=2.0, shot_noise=1.0, gradient=0.5),
                  "15 % exposure, shot + read noise, 50 % light fall-off across the frame"),
        Condition("occlusion_30", traj(), Degradation(occlusion=0.30), "hand-like blob over 30 % of the board"),
        Condition("steep_60", traj(tilt_deg=60.0), Degradation(), "60 deg from vertical"),
        Condition("near_0.3m", traj(distance_m=0.3), Degradation(), "0.3 m"),
        Condition("far_1.0m", traj(distance_m=1.0), Degradation(), "1.0 m"),
    ]


@dataclass
class BenchConfig:
    frames: int = 100
    board_spec: str = DEFAULT_BOARD_SPEC
    landing_every: int = 5
    estimated_calibration: bool = True
    seed: int = 0
    pose_filter: str = "kalman"  # or "one-euro"
    conditions: list[Condition] = field(default_factory=default_conditions)


def _jitter(errs_T: list[tuple[np.ndarray, np.ndarray] | None]) -> tuple[float, float]:
    """RMS frame-to-frame change of the pose error: (deg, mm)."""
    rot, trans = [], []
    for a, b in zip(errs_T[:-1], errs_T[1:]):
        if a is None or b is None:
            continue
        (Ta, Tta), (Tb, Ttb) = a, b
        Ea = Ta[:3, :3] @ Tta[:3, :3].T
        Eb = Tb[:3, :3] @ Ttb[:3, :3].T
        rot.append(rotation_angle_deg(Eb @ Ea.T))
        trans.append(np.linalg.norm((Tb[:3, 3] - Ttb[:3, 3]) - (Ta[:3, 3] - Tta[:3, 3])) * 1000)
    if not rot:
        return float("nan"), float("nan")
    return float(np.sqrt(np.mean(np.square(rot)))), float(np.sqrt(np.mean(np.square(trans))))


def _stat(values: list[float], q: float) -> float:
    v = np.asarray([x for x in values if np.isfinite(x)], np.float64)
    return float(np.percentile(v, q)) if len(v) else float("nan")


def calibrate_rig(cam: SyntheticCamera, board: Board) -> tuple[CameraCalibration, ProjectorCalibration, dict]:
    """Calibrate the synthetic rig as a user would (camera views, then the projector sequence)."""
    views = [(f"view_{i:02d}", cam.render(T)) for i, T in enumerate(calibration_poses(board, 12))]
    camera = calibrate_camera(views, board)
    captures = capture_projector_sequence(cam, ProjectorCalibrationSequence(board))
    data, rejected = [], {}
    for step, _T, pattern, frames in captures:
        r = extract_projector_view(f"step_{step.index:02d}", frames, board, camera, pattern)
        if isinstance(r, str):
            rejected[f"step_{step.index:02d}"] = r
        else:
            data.append(r)
    projector = calibrate_projector(data, camera, cam.projector.size, rejected)
    rot, trans = extrinsics_error(projector, cam.proj_from_cam)
    report = {"camera_rms_px": camera.rms,
              "camera_fx_error_pct": float(100 * (camera.camera_matrix[0, 0] / cam.camera.K[0, 0] - 1)),
              "projector_rms_px": projector.rms,
              "projector_fx_error_pct": float(100 * (projector.camera_matrix[0, 0] / cam.projector.K[0, 0] - 1)),
              "extrinsics_rot_err_deg": rot, "extrinsics_trans_err_mm": trans}
    return camera, projector, report


def run_bench(cfg: BenchConfig, progress=None, examples: dict | None = None) -> dict:
    """Run every condition; returns the JSON-ready result. ``progress(n)`` advances a bar by n frames.

    ``examples``, when a dict, receives per-condition example images (camera view with
    axes, projector view, camera view with the projection) from the middle frame.
    """
    board = Board(cfg.board_spec)
    cam = SyntheticCamera(board)
    if cfg.estimated_calibration:
        camera, projector, calib_report = calibrate_rig(cam, board)
        K, dist = camera.camera_matrix, camera.dist_coeffs
        Kp, T_pc = projector.camera_matrix, projector.T_proj_from_cam
    else:
        K, dist = cam.camera.K, cam.camera.dist
        Kp, T_pc = cam.projector.K, cam.proj_from_cam
        calib_report = {"note": "true calibration used"}
    P = cam.projector
    renderer = ProjectorRenderer(P.width, P.height, Kp)
    landing = LandingCheck(renderer, board)
    out: dict = {"conditions": {}, "calibration": calib_report, "board": str(board.spec), "pose_filter": cfg.pose_filter,
                 "camera": {"size": list(cam.camera.size), "fx": float(cam.camera.K[0, 0])},
                 "frames_per_condition": cfg.frames}
    all_detect_ms, all_render_ms, clean_landing = [], [], []
    rng = np.random.default_rng(cfg.seed)
    for cond in cfg.conditions:
        traj = TrajectoryConfig(**{**cond.trajectory.__dict__, "seed": cfg.seed})
        poses = handheld_trajectory(board, cfg.frames, traj)
        raw_tracker = PoseTracker(filter_enabled=False)  # the unfiltered poses' jitter, beside the rig's
        rig = RigTracker(board, K, dist, T_pc, tracker=PoseTracker(
            pose_filter=PoseOneEuroFilter() if cfg.pose_filter == "one-euro" else PoseKalmanFilter()))
        rot_e, trans_e, frot_e, ftrans_e, detect_ms, render_ms, land = [], [], [], [], [], [], []
        raw_pairs, filt_pairs = [], []
        detected = 0
        states = {"tracking": 0, "holding": 0, "lost": 0}
        for i, T_true in enumerate(poses):
            frame = cam.render(T_true, degradation=cond.degradation, rng=rng)
            ts = i / traj.fps
            step = rig.step(frame, ts, i)
            detect_ms.append(step.detect_pose_ms)
            est, filt = step.estimate, step.output
            raw = raw_tracker.update(est, ts)
            states[filt.state] += 1
            if est is not None:
                detected += 1
                r, t = pose_error(est.T_cam_from_board, T_true)
                rot_e.append(r)
                trans_e.append(t)
            raw_pairs.append((raw.T_cam_from_board, T_true) if raw.state == TRACKING else None)
            filt_pairs.append((filt.T_cam_from_board, T_true) if filt.state == TRACKING else None)
            if filt.state == TRACKING:
                fr, ft = pose_error(filt.T_cam_from_board, T_true)
                frot_e.append(fr)
                ftrans_e.append(ft)
            if filt.T_cam_from_board is not None and i % cfg.landing_every == 0:
                res = landing.measure(filt.T_cam_from_board, T_pc, P.K, P.dist, cam.proj_from_cam @ T_true)
                render_ms.append(res.render_ms)
                land.extend(res.errors_mm.tolist())
            if examples is not None and i == cfg.frames // 2:
                examples[cond.name] = {"camera_axes": draw_pose(frame, est, K, dist)}
                if cond.name == "clean" and filt.T_cam_from_board is not None:
                    renderer.remove("landing_dots")
                    add_test_scene(renderer, board)
                    renderer.set_board_pose(filt.T_cam_from_board, T_pc, board)
                    proj_img = renderer.render()
                    for name in ("axis_x", "axis_y", "axis_z", "cube", "grid"):
                        renderer.remove(name)
                    landing = LandingCheck(renderer, board)
                    examples[cond.name]["projector_view"] = proj_img
                    examples[cond.name]["camera_with_projection"] = cam.render(T_true, proj_img)
            if progress:
                progress(1)
        jr, jt = _jitter(raw_pairs)
        fjr, fjt = _jitter(filt_pairs)
        n = len(poses)
        out["conditions"][cond.name] = {
            "description": cond.description,
            "detect_rate": detected / n,
            "rot_err_deg_median": _stat(rot_e, 50), "trans_err_mm_median": _stat(trans_e, 50),
            "rot_err_deg_p95": _stat(rot_e, 95), "trans_err_mm_p95": _stat(trans_e, 95),
            "filtered_rot_err_deg_median": _stat(frot_e, 50), "filtered_trans_err_mm_median": _stat(ftrans_e, 50),
            "jitter_raw_deg": jr, "jitter_raw_mm": jt, "jitter_filtered_deg": fjr, "jitter_filtered_mm": fjt,
            "landing_error_mm_median": _stat(land, 50), "landing_error_mm_p95": _stat(land, 95),
            "tracker_states": states,
            "detect_pose_ms_median": _stat(detect_ms, 50), "render_ms_median": _stat(render_ms, 50),
        }
        all_detect_ms += detect_ms
        all_render_ms += render_ms
        if cond.name == "clean":
            clean_landing = land
    renderer.close()
    out["landing_error_mm_median"] = _stat(clean_landing, 50)
    out["detect_pose_ms_median"] = _stat(all_detect_ms, 50)
    out["render_ms_median"] = _stat(all_render_ms, 50)
    return out


def format_table(result: dict) -> str:
    """Markdown table of a bench result."""
    head = ("| condition | detect | rot med / p95 (deg) | trans med / p95 (mm) | jitter raw -> filtered (deg, mm) "
            "| landing med / p95 (mm) | detect+pose ms | render ms |")
    lines = [head, "|" + "---|" * 8]
    for name, c in result["conditions"].items():
        lines.append(
            f"| {name} | {100 * c['detect_rate']:.0f} % | {c['rot_err_deg_median']:.3f} / {c['rot_err_deg_p95']:.3f} "
            f"| {c['trans_err_mm_median']:.2f} / {c['trans_err_mm_p95']:.2f} "
            f"| {c['jitter_raw_deg']:.3f} -> {c['jitter_filtered_deg']:.3f}, {c['jitter_raw_mm']:.2f} -> {c['jitter_filtered_mm']:.2f} "
            f"| {c['landing_error_mm_median']:.2f} / {c['landing_error_mm_p95']:.2f} "
            f"| {c['detect_pose_ms_median']:.1f} | {c['render_ms_median']:.1f} |")
    return "\n".join(lines)


#: conditions whose middle frame is written by ``--examples`` (the ones docs/design/ar.md shows)
EXAMPLE_CONDITIONS = ("clean", "occlusion_30", "low_light")


def write_examples(folder: Path, examples: dict) -> list[Path]:
    """Half-size, 64-colour PNGs (small enough to commit) of the example frames that
    :func:`run_bench` collected, one ``ar_<condition>_<kind>.png`` per image of the
    :data:`EXAMPLE_CONDITIONS`; returns the paths written."""
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for cond, images in examples.items():
        if cond not in EXAMPLE_CONDITIONS:
            continue
        for kind, img in images.items():
            rgb = img if kind == "projector_view" else img[..., ::-1]  # renders are RGB, camera frames BGR
            small = cv2.resize(rgb, (rgb.shape[1] // 2, rgb.shape[0] // 2), interpolation=cv2.INTER_AREA)
            im = Image.fromarray(small).quantize(colors=64, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
            path = folder / f"ar_{cond}_{kind}.png"
            im.save(path, optimize=True)
            written.append(path)
    return written


# ------------------------------------------------------------------ camera frame -> projector frame
#: the rig's tracking and projector resolution for the frame timing (the app's ``RIG_SIZE``)
FRAME_SIZE = (640, 480)


def _pyrender_renderer():
    """The reference renderer (pyrender through EGL/OSMesa)."""
    from ar.render.scene_render import PyrenderSceneRenderer  # deferred: pyrender, only in the process that measures it

    return PyrenderSceneRenderer()


#: renderer name -> factory (called once, in the process that measures it) of an object
#: with ``render(SceneDescription) -> (H, W, 3) uint8`` (and optionally ``close()``). The
#: app's Kivy GL renderer lives in ``app.ui``, which the benches may not import: the
#: ``storybeam bench ar`` command plugs it in (:func:`app.commands.bench_cmd.kivy_gl_renderer`).
FRAME_RENDERERS = {"pyrender": _pyrender_renderer}


def pin_one_core() -> dict:
    """Set OpenCV, BLAS/OpenMP, numba and Mesa llvmpipe to one thread (before any GL
    context exists); returns what was set, for the JSON."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS", "LP_NUM_THREADS"):
        os.environ[var] = "1"
    cv2.setNumThreads(1)
    affinity = None
    if hasattr(os, "sched_setaffinity"):
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpus[0]})
        affinity = cpus[0]
    return {"opencv_threads": cv2.getNumThreads(), "LP_NUM_THREADS": 1, "OMP_NUM_THREADS": 1, "cpu": affinity}


def stage_description(view, character, part_poses: np.ndarray, T_proj_from_scene: np.ndarray | None):
    """What the projector shows: ``character`` (parts at ``part_poses``, scene frame) seen
    from the tracked projector pose; no pose = an empty (black) frame."""
    if T_proj_from_scene is None:
        return SceneDescription(view)
    desc = SceneDescription(View(view.width, view.height, view.K, T_proj_from_scene, view.znear, view.zfar))
    add_character(desc, character, part_poses)
    return desc


def measure_frames(renderer_name: str, factory, conditions: list[Condition], frames: int = 100, seed: int = 0,
                   board_spec: str = DEFAULT_BOARD_SPEC, one_core: bool = True) -> dict:
    """Camera frame -> projector frame, timed on ``frames`` synthetic 640x480 frames per condition.

    Per frame: the product's frame loop (:meth:`ar.rig.RigTracker.step`: board detection
    and pose on the region the last pose predicts, whole frame when lost, the corners
    under the previous frame's light left out as the stage does, the Kalman tracker, the
    projector pose), the projector's scene (a 10 cm robot standing at the board centre, its 20-odd parts posed
    per frame) and the render by
    the renderer ``factory()`` makes. ``detect_pose_ms`` covers detection, pose and filter; ``render_ms``
    making the description and rendering it; ``frame_ms`` both. The rig uses its true
    calibration here (the accuracy part of :func:`run_bench` uses an estimated one).
    ``before_detect_pose_ms``: the same frames through the detection as it was before
    issue 13 (whole frame, the full 250-code dictionary), timed in the same loop, so the
    ratio holds however busy the machine is. The ``*_ms`` figures are wall-clock; ``cpu``
    holds the same figures in CPU time of the whole process (``time.process_time``: every
    thread, the renderer's included), which on a shared, busy machine is the closer
    estimate of what one idle core would take (wall-clock then also counts the time other
    jobs held the core).
    Meant to run in a fresh process (:func:`run_frame_bench`): GL and thread settings stay its own.
    """
    pinned = pin_one_core() if one_core else {}
    renderer = factory()
    board = Board(board_spec)
    w, h = FRAME_SIZE
    camera = scaled_model(default_camera(), w, h)
    projector = scaled_model(default_projector(), w, h)
    T_pc = default_proj_from_cam()
    view = View(w, h, projector.K)
    character = build_character("robot", 0.10)
    motion = rest_motion(character, 30)
    poses_char = character.all_part_poses(motion)  # (F, P, 4, 4), standing at the board centre
    cam = SyntheticCamera(board, camera=camera, supersample=2)
    out: dict = {"renderer": renderer_name, "size": [w, h], "threads": pinned, "conditions": {}}
    for cond in conditions:
        rng = np.random.default_rng(seed)
        traj = TrajectoryConfig(**{**cond.trajectory.__dict__, "seed": seed})
        truth = handheld_trajectory(board, frames, traj)
        images = [cam.render(T, degradation=cond.degradation, rng=rng) for T in truth]
        rig = RigTracker(board, camera.K, camera.dist, T_pc)
        legacy = Board(board_spec, full_dictionary=True)  # the detection before issue 13, timed alongside
        det_ms, ren_ms, frame_ms, rot, trans, legacy_ms = [], [], [], [], [], []
        cpu_det, cpu_ren, cpu_frame, cpu_legacy, lit = [], [], [], [], []
        renderer.render(stage_description(view, character, poses_char[0], None))  # warm-up: GL set-up, uploads
        shown: ProjectedLight | None = None  # the light of the frame before, handed to the rig as the stage does
        for i, (img, T_true) in enumerate(zip(images, truth)):
            t_legacy, c_legacy = time.perf_counter(), time.process_time()
            estimate_board_pose(img, legacy, camera.K, camera.dist)
            legacy_ms.append((time.perf_counter() - t_legacy) * 1000)
            cpu_legacy.append((time.process_time() - c_legacy) * 1000)
            t0, c0 = time.perf_counter(), time.process_time()
            step = rig.step(img, i / traj.fps, i, shown)
            t1, c1 = time.perf_counter(), time.process_time()
            est = step.estimate
            T_ps = step.T_proj_from_board @ board_from_scene(board) if step.T_proj_from_board is not None else None
            light = renderer.render(stage_description(view, character, poses_char[i % len(poses_char)], T_ps))
            t2, c2 = time.perf_counter(), time.process_time()
            shown = ProjectedLight(light, projector, step.T_proj_from_board)
            assert light.shape == (h, w, 3)
            lit.append(float((light.max(axis=2) > 20).mean()))
            det_ms.append((t1 - t0) * 1000)
            ren_ms.append((t2 - t1) * 1000)
            frame_ms.append((t2 - t0) * 1000)
            cpu_det.append((c1 - c0) * 1000)
            cpu_ren.append((c2 - c1) * 1000)
            cpu_frame.append((c2 - c0) * 1000)
            if est is not None:
                r, t = pose_error(est.T_cam_from_board, T_true)
                rot.append(r)
                trans.append(t)
        out["conditions"][cond.name] = {
            "detect_pose_ms_median": _stat(det_ms, 50), "render_ms_median": _stat(ren_ms, 50),
            "frame_ms_median": _stat(frame_ms, 50), "frame_ms_p95": _stat(frame_ms, 95),
            "detect_rate": len(rot) / frames, "rot_err_deg_median": _stat(rot, 50),
            "trans_err_mm_median": _stat(trans, 50), "search_paths": dict(rig.counts),
            "lit_fraction_median": _stat(lit, 50),  # share of projector pixels lit: the character is drawn
            "before_detect_pose_ms_median": _stat(legacy_ms, 50),
            "detect_pose_speedup": _stat(legacy_ms, 50) / max(1e-9, _stat(det_ms, 50)),
            "cpu": {"detect_pose_ms_median": _stat(cpu_det, 50), "render_ms_median": _stat(cpu_ren, 50),
                    "frame_ms_median": _stat(cpu_frame, 50), "frame_ms_p95": _stat(cpu_frame, 95),
                    "before_detect_pose_ms_median": _stat(cpu_legacy, 50)}}
    if hasattr(renderer, "close"):
        renderer.close()
    return out


def _measure_in_child(args: tuple) -> dict:
    try:
        return measure_frames(*args)
    except Exception as exc:  # noqa: BLE001 - a renderer that cannot start is reported, not fatal
        return {"renderer": args[0], "error": f"{type(exc).__name__}: {exc}"}


def run_frame_bench(conditions: list[Condition], frames: int = 100, seed: int = 0,
                    renderers: dict | None = None, board_spec: str = DEFAULT_BOARD_SPEC,
                    one_core: bool = True) -> dict:
    """:func:`measure_frames` for each ``{name: factory}`` of ``renderers`` (default
    :data:`FRAME_RENDERERS`), each in a fresh spawned process (its own GL context and thread
    settings; a factory must be a module-level function so the process can import it);
    ``{name: result}``, a renderer that could not run carries ``error``."""
    results = {}
    for name, factory in (renderers or FRAME_RENDERERS).items():
        with concurrent.futures.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
            job = (name, factory, conditions, frames, seed, board_spec, one_core)
            results[name] = pool.submit(_measure_in_child, job).result()
    return results


def merge_frame_results(result: dict, frame_results: dict) -> None:
    """Put each condition's per-renderer frame timings under ``result["conditions"][c]["renderers"]``."""
    for name, res in frame_results.items():
        for cond, c in result["conditions"].items():
            entry = res.get("conditions", {}).get(cond) if "error" not in res else {"error": res["error"]}
            if entry is not None:
                c.setdefault("renderers", {})[name] = entry
    result["frame"] = {name: {k: v for k, v in res.items() if k != "conditions"} for name, res in frame_results.items()}


def format_frame_table(result: dict) -> str:
    """Markdown table of the camera -> projector frame timings."""
    lines = ["| condition | renderer | detect 640x480 | rot / trans med | detect+pose+filter ms (before, speed-up); "
             "cpu ms | render ms; cpu | frame ms med / p95; cpu |", "|" + "---|" * 7]
    for cond, c in result["conditions"].items():
        for name, r in c.get("renderers", {}).items():
            if "error" in r:
                lines.append(f"| {cond} | {name} | not run: {r['error']} | | | | |")
                continue
            cpu = r["cpu"]
            lines.append(f"| {cond} | {name} | {100 * r['detect_rate']:.0f} % | {r['rot_err_deg_median']:.3f} deg / "
                         f"{r['trans_err_mm_median']:.2f} mm | {r['detect_pose_ms_median']:.1f} "
                         f"({r['before_detect_pose_ms_median']:.1f}, x{r['detect_pose_speedup']:.1f}); "
                         f"cpu {cpu['detect_pose_ms_median']:.1f} | {r['render_ms_median']:.1f}; cpu "
                         f"{cpu['render_ms_median']:.1f} | {r['frame_ms_median']:.1f} / {r['frame_ms_p95']:.1f}; cpu "
                         f"{cpu['frame_ms_median']:.1f} / {cpu['frame_ms_p95']:.1f} |")
    return "\n".join(lines)
