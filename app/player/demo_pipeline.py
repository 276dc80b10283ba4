"""The end-to-end animation demo: retrieve a motion, walk a character along a drawn path,
and render it through the synthetic projector-camera rig held by hand.

Used by ``storybeam demo`` (video + JSON report) and ``storybeam render --demo`` (video
or one still). Everything comes from the bundled assets, so it runs on a fresh machine:

1. build (or reuse) the motion index over ``assets/motions``;
2. the sample query is a slowed-down excerpt of a bundled walk; its own clip is left out
   of the answers, so the retrieved motion is a *different* capture of the same action;
3. retarget the answer onto the character, lay it along a sample closed path around the
   board (sized so the natural pace fills the requested seconds);
4. per frame: the synthetic rig (:class:`ar.rig.SyntheticRig`, as the projector stage
   uses it) films the board with the previous frame's projection (one frame of latency,
   as on a real rig) and steps the rig's frame loop (:meth:`ar.rig.RigTracker.step`:
   region detection, pose, filter, projector pose; the corners under its own light left
   out), the character is rendered from the estimated projector pose (projector view), the
   light is cast onto the table (camera view), and an overhead preview is rendered;
5. every few frames a landing check (ar.closed_loop) measures where projected light
   lands on the table versus where it should, through the true projector.

Imports :mod:`ar.render` (pyrender): the commands import this module when they run.
"""
from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import imageio.v2 as imageio
import numpy as np
from PIL import Image
from tqdm import tqdm

from app.paths import MOTIONS_DIR
from app.progress import progress_bar
from ar import DEFAULT_BOARD_SPEC, Board, default_projector
from ar.closed_loop import LandingCheck
from ar.render import ProjectorRenderer, PyrenderSceneRenderer
from ar.rig import RIG_SIZE, ProjectedLight, SyntheticRig
from ar.scene import (Lighting, SceneDescription, View, add_character, add_mesh, board_from_scene, build_character,
                      overhead_view, ribbon, scaled_model, table_mesh)
from retrieval.animation import (TablePath, find_loop, follow_path, foot_skate_cm_per_m, path_error_cm,
                                 retarget)
from retrieval.errors import IndexFormatError, StoryBeamError
from retrieval.library import MotionIndex, choose_clip, clip_path
from retrieval.motion import load_motion, resample

VIEW_CHOICES = ("camera", "projector", "overhead", "all")


@dataclass
class DemoConfig:
    """What to render. The defaults are the documented demo (10 s, 30 fps, 640x480)."""

    seconds: float = 10.0
    fps: float = 30.0
    width: int = 640
    height: int = 480
    character: str = "robot"
    height_m: float = 0.12
    query_trial: str = "16_15"
    view: str = "camera"
    video: Path | None = Path("out/demo.mp4")
    json_path: Path | None = Path("out/demo.json")
    index_dir: Path = Path("out/motion_index")
    still_frame: int | None = None
    still_png: Path | None = None
    landing_every: int = 10
    seed: int = 0
    progress: bool = True
    max_frames: int | None = None  # stop early (tests, quick looks)
    stills: dict = field(default_factory=dict)  # view -> PNG path, written at still_frame


def sample_path(perimeter_m: float, n: int = 200) -> np.ndarray:
    """A rounded, slightly lopsided closed loop around the board centre (scene X, Z),
    like a child's drawn circuit; starts and ends at the left."""
    t = np.linspace(0.0, 2 * np.pi, n)
    # ellipse with a gentle wobble; scale to the perimeter
    # portrait like the default board (its long side is the scene Z axis), so the
    # character walks on the paper, where projected light shows best
    x = -0.7 * np.cos(t) * (1.0 + 0.12 * np.sin(2 * t))
    z = np.sin(t) * (1.0 + 0.1 * np.cos(3 * t))
    pts = np.stack([x, z], axis=1)
    length = np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1))
    return pts * (perimeter_m / length)


def _query_motion(trial: str):
    """A 2.5 s excerpt of a bundled clip, played at 0.9x speed (a different timing from
    anything in the index)."""
    path = MOTIONS_DIR / "bvh" / f"{trial}.bvh"
    if not path.is_file():
        raise StoryBeamError(f"query clip {trial!r} not found in {MOTIONS_DIR / 'bvh'}")
    m = load_motion(path)
    n = min(m.n_frames, int(2.5 * m.fps))
    start = (m.n_frames - n) // 2
    excerpt = m.slice(start, start + n)
    slowed = resample(excerpt, excerpt.fps / 0.9).copy(fps=excerpt.fps)
    return slowed.copy(name=f"{trial}-excerpt-0.9x")


def load_or_build_index(index_dir: Path, progress: bool = True) -> tuple[MotionIndex, bool]:
    """The bundled library's index from ``index_dir``, built and saved there first if
    needed; ``(index, reused)``."""
    if MotionIndex.is_index(index_dir):
        try:
            return MotionIndex.load(index_dir), True
        except IndexFormatError:  # saved by an older StoryBeam (features on another body): built again below
            pass
    index = MotionIndex.build(MOTIONS_DIR, fps=30.0, progress=progress_bar("indexing the bundled library", "clip", progress))
    index.save(index_dir)
    return index, False


def plan_animation(cfg: DemoConfig, index) -> dict:
    """Retrieve, retarget and lay the motion on the sample path (no rendering)."""
    query = _query_motion(cfg.query_trial)
    t0 = time.perf_counter()
    trial, label, distance = choose_clip(index, "walk", query, exclude=(cfg.query_trial,))
    search_ms = (time.perf_counter() - t0) * 1000
    character = build_character(cfg.character, cfg.height_m)
    source = load_motion(clip_path(MOTIONS_DIR, trial))
    motion = retarget(source, character.skeleton)
    # Size the loop so a slightly slowed pace (0.8x) fills the requested time, within
    # what fits on the board (a 0.6 m loop spans about 15 x 22 cm).
    loop = find_loop(motion, blend_frames=max(1, int(0.3 * motion.fps)))
    step = motion.root_translation[loop.end] - motion.root_translation[loop.start]
    speed = float(np.linalg.norm(step[[0, 2]])) * motion.skeleton.metres_per_unit / (loop.period / motion.fps)
    perimeter = float(np.clip(0.8 * speed * cfg.seconds, 0.25, 0.6))
    path = TablePath(sample_path(perimeter))
    result = follow_path(motion, path, fps=cfg.fps, duration_s=cfg.seconds, loop=loop)
    animated = result.motion
    return {
        "character": character, "motion": animated, "path": path, "query": query.name,
        "retrieved": {"trial": trial, "label": label, "distance": distance,
                      "query": query.name, "query_label": "walk", "search_ms": search_ms},
        "path_error_cm": path_error_cm(animated, path.points),
        "foot_skate_cm_per_m": foot_skate_cm_per_m(animated),
        "foot_skate_ungated_cm_per_m": foot_skate_cm_per_m(animated, swing_speed_legs=None),
        "rate": result.rate, "perimeter_m": perimeter,
    }


def run_demo(cfg: DemoConfig) -> dict:
    """Render the demo; returns the report (also written to ``cfg.json_path``)."""
    if cfg.view not in VIEW_CHOICES:
        raise StoryBeamError(f"unknown view {cfg.view!r}; choose one of {', '.join(VIEW_CHOICES)}")
    if cfg.seconds <= 0 or cfg.fps <= 0 or cfg.width < 64 or cfg.height < 48:
        raise StoryBeamError("seconds and fps must be positive and the frame at least 64x48")
    t_start = time.perf_counter()
    index, reused = load_or_build_index(cfg.index_dir, cfg.progress)
    plan = plan_animation(cfg, index)
    motion, character, path = plan["motion"], plan["character"], plan["path"]
    n_frames = motion.n_frames if cfg.still_frame is None else min(motion.n_frames, cfg.still_frame + 1)
    if cfg.max_frames is not None:
        n_frames = min(n_frames, int(cfg.max_frames))

    board = Board(DEFAULT_BOARD_SPEC)
    # The rig (its camera and projector) is fixed at 640x480: tracking must not depend on
    # the video size. The character is rendered at the output size; views are resized.
    # The hand's path is long enough that it never turns back within the video.
    rig = SyntheticRig(board, fps=cfg.fps, seed=cfg.seed, loop_s=max(60.0, (n_frames + 1) / cfg.fps))
    proj_model = rig.projector_model
    out_proj = scaled_model(default_projector(), cfg.width, cfg.height)
    same_size = (cfg.width, cfg.height) == RIG_SIZE
    T_pc = rig.T_proj_from_cam  # the rig's calibration (true values; see docs/design/animation.md)

    # one scene description per view and frame, drawn by pyrender (as the app draws the
    # same descriptions with Kivy GL): the character's part poses, the projector's view
    part_poses = character.all_part_poses(motion)
    projector = PyrenderSceneRenderer()
    need_overhead = cfg.view in ("overhead", "all") or "overhead" in cfg.stills
    overhead = PyrenderSceneRenderer() if need_overhead else None
    overhead_statics = [(table_mesh(1.2, 1.0), (150, 150, 160))]  # the authoring preview's grey table ...
    if path.points is not None and len(path.points) > 1:
        overhead_statics.append((ribbon(path.points), (255, 230, 0)))  # ... and the drawn path
    overhead_cam = overhead_view(cfg.width, cfg.height)
    landing_renderer = ProjectorRenderer(proj_model.width, proj_model.height, proj_model.K)
    landing = LandingCheck(landing_renderer, board)

    writer = None
    if cfg.video is not None and cfg.still_frame is None:
        Path(cfg.video).parent.mkdir(parents=True, exist_ok=True)
        writer = imageio.get_writer(str(cfg.video), fps=cfg.fps, codec="libx264", quality=7,
                                    pixelformat="yuv420p", macro_block_size=16)
    render_ms, landing_mm, frame_ms = [], [], []
    parts_ms: dict[str, list[float]] = {"camera": [], "track": [], "overhead": [], "encode": []}
    states = {"tracking": 0, "holding": 0, "lost": 0}
    shown: ProjectedLight | None = None  # what the rig's projector showed last
    fit = (lambda img: img) if same_size else (lambda img: cv2.resize(img, (cfg.width, cfg.height), interpolation=cv2.INTER_AREA))
    stills_written: dict[str, str] = {}
    bar = tqdm(total=n_frames, desc="rendering", unit="frame", disable=not cfg.progress)
    try:
        for i in range(n_frames):
            t_frame = time.perf_counter()
            T_true = rig.true_pose(i)
            track = rig.step(shown)  # film frame i with the last light, and track it
            frame_bgr = track.image
            parts_ms["track"].append(track.detect_pose_ms)
            parts_ms["camera"].append((time.perf_counter() - t_frame) * 1000 - track.detect_pose_ms)
            states[track.state] += 1
            light = np.zeros((cfg.height, cfg.width, 3), np.uint8)
            if track.T_proj_from_board is not None:
                desc = SceneDescription(View(cfg.width, cfg.height, out_proj.K,
                                             track.T_proj_from_board @ board_from_scene(board)))
                add_character(desc, character, part_poses[i])
                t0 = time.perf_counter()
                light = projector.render(desc)
                render_ms.append((time.perf_counter() - t0) * 1000)
                if i % max(1, cfg.landing_every) == 0:
                    res = landing.measure(track.T_cam_from_board, T_pc, proj_model.K, proj_model.dist, T_pc @ T_true)
                    landing_mm.extend(float(e) for e in res.errors_mm if np.isfinite(e))
            views = {"camera": fit(cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2RGB)), "projector": light}
            if overhead is not None:
                t2 = time.perf_counter()
                above = SceneDescription(overhead_cam, lighting=Lighting(0.45, 3.5))
                for mesh, colour in overhead_statics:
                    add_mesh(above, mesh, colour)
                add_character(above, character, part_poses[i])
                views["overhead"] = overhead.render(above)
                parts_ms["overhead"].append((time.perf_counter() - t2) * 1000)
            shown = ProjectedLight(light, out_proj, track.T_proj_from_board)  # the rig resizes it to its projector
            frame_ms.append((time.perf_counter() - t_frame) * 1000)
            out = np.hstack([views[v] for v in ("camera", "projector", "overhead")]) if cfg.view == "all" else views[cfg.view]
            if writer is not None:
                t3 = time.perf_counter()
                writer.append_data(out)
                parts_ms["encode"].append((time.perf_counter() - t3) * 1000)
            if cfg.still_frame is not None and i == cfg.still_frame:
                if cfg.still_png is not None:
                    _save_png(out, cfg.still_png)
                    stills_written[cfg.view] = str(cfg.still_png)
                for v, p in cfg.stills.items():
                    _save_png(views[v], p)
                    stills_written[v] = str(p)
            bar.update(1)
    finally:
        bar.close()
        if writer is not None:
            writer.close()
        # pyrender's EGL renderers share one display, and deleting one may tear it down
        # under the others: close newest first and ignore teardown errors at exit.
        for closer in ([overhead.close] if overhead is not None else []) + [landing_renderer.close, projector.close]:
            try:
                closer()
            except Exception:  # noqa: BLE001 - GL teardown only; the frames are written
                pass

    report = {
        "retrieved": plan["retrieved"],
        "path_error_cm": round(plan["path_error_cm"], 4),
        "foot_skate_cm_per_m": round(plan["foot_skate_cm_per_m"], 4),
        "foot_skate_ungated_cm_per_m": round(plan["foot_skate_ungated_cm_per_m"], 4),
        "render_ms_median": round(float(np.median(render_ms)), 2) if render_ms else None,
        "landing_error_mm": round(float(np.median(landing_mm)), 3) if landing_mm else None,
        "landing_error_mm_p95": round(float(np.percentile(landing_mm, 95)), 3) if landing_mm else None,
        "frames": int(n_frames),
        "frame_ms_median": round(float(np.median(frame_ms)), 2) if frame_ms else None,
        "tracking_states": states,
        "stage_ms_median": {k: round(float(np.median(v)), 2) for k, v in parts_ms.items() if v},
        "character": cfg.character, "character_height_m": cfg.height_m,
        "size": [cfg.width, cfg.height], "fps": cfg.fps, "view": cfg.view,
        "path_length_m": round(path.length, 4), "playback_rate": round(plan["rate"], 4),
        "index_reused": reused, "video": str(cfg.video) if writer is not None else None,
        "stills": stills_written, "total_s": round(time.perf_counter() - t_start, 2),
    }
    if cfg.json_path is not None:
        Path(cfg.json_path).parent.mkdir(parents=True, exist_ok=True)
        Path(cfg.json_path).write_text(json.dumps(report, indent=2))
    return report


def _save_png(rgb: np.ndarray, path: str | Path) -> None:
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(rgb).save(path)


def config_dict(cfg: DemoConfig) -> dict:
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(cfg).items()}
