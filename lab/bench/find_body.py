"""Finding the body wherever it is (issue 27): scenes with known truth, and the bench
``storybeam bench find-body``.

    storybeam bench find-body [--json OUT] [--frames 45] [--tiles-per-frame 4] [--videos DIR]

**Scenes.** Performers are cut out of the stored reference renders
(``tests/ar/data/blazepose/``: the person figure walking (12 frames) and jumping (10),
640×480, a plain wall and floor, each frame's landmarks by MediaPipe 0.10.21 in
``reference.npz``): a pixel belongs to the figure where it differs from its row's wall or
floor colour (:func:`load_performers`). :func:`compose` scales a performer's frame so that
its standing height (272 px in the render) becomes ``height`` pixels and pastes it with its
feet at a point of a 1920×1080 wall-and-floor frame (camera noise added), clipped at the
frame's edges; the truth is the reference landmarks moved the same way. The scenes
(:data:`SCENES`, each ``frames`` long, 30 fps, the walk cycling):

* ``centre``: one person 700 px tall in the middle (the whole-frame detector finds them);
* ``edge-small``: one person 180 px tall (1/6 of the height) walking near the right edge;
* ``walk-in``: one person entering from the left edge, growing from 250 to 650 px;
* ``three``: three people; the one to follow is the most central and largest at first
  (480 px, walking); two neighbours (a jumper at the left, a walker at the right) grow and
  move in, the right one becomes bigger than the followed one; the followed one is hidden
  for two frames in the middle (someone passing in front);
* ``empty``: the wall and floor only (the cost of looking for nobody).

**Bench.** Every scene tracked by :func:`ar.body.track_frames` (one thread, pinned to one
core) twice: with the extra pass (``search=True``) and without it (``search=False``, the
whole-frame detector only). Per scene and mode: frames with a pose, frames with a pose on
the right person (:func:`on_target`), the median ms per frame over the take, over tracked
frames and over frames that ran the detector, and how many tile runs. Then the cost of
acquisition alone: each frame of ``centre`` and ``edge-small`` processed by a reset
tracker (the detector always runs), median ms with and without the extra pass. With
``--videos DIR`` (a folder with ``labels.csv``: ``file,label``), each clip is tracked both
ways too: frames with a pose and ms per frame. Last, what the tile sizes rest on: the
share of walk frames in which the whole-frame detector finds the person, by the person's
height over the detector input's side (:func:`detector_size_sweep`).
"""
from __future__ import annotations

import csv
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from app.paths import REPO_ROOT
from ar.body import BodyPose, BodyTracker, track_frames
from ar.camera_sources import VideoFileSource
from retrieval.errors import StoryBeamError

REFERENCE_DIR = REPO_ROOT / "tests" / "ar" / "data" / "blazepose"
#: Frame size of the scenes, frame rate.
WIDTH, HEIGHT, FPS = 1920, 1080, 30.0
#: The person figure's standing height in the reference renders (1.7 m at 3.6 m, f = 576 px).
RENDER_HEIGHT_PX = 272.0
WALL_BGR, FLOOR_BGR = (187, 196, 200), (121, 125, 126)
#: Floor line of the scenes (fraction of the height).
HORIZON = 0.62
#: A pose is on a performer when its hips' midpoint is within this fraction of the
#: performer's height of the true one and its height within this fraction too.
ON_TARGET = 0.2


@dataclass(frozen=True)
class Performer:
    """One reference frame cut out: ``image`` (480, 640, 3) BGR, ``mask`` (480, 640) bool
    (the figure), ``truth`` (33, 2) MediaPipe's landmarks there (pixels)."""

    image: np.ndarray
    mask: np.ndarray
    truth: np.ndarray


def load_performers(sequence: str, reference_dir: Path = REFERENCE_DIR) -> list[Performer]:
    """The frames of a reference sequence (``person_walk``, ``person_jump``) as cut-outs."""
    path = reference_dir / "reference.npz"
    if not path.is_file():
        raise StoryBeamError(f"{path}: the pose reference renders are missing")
    with np.load(path) as ref:
        names, truth = ref[f"{sequence}/frames"], ref[f"{sequence}/static/image"]
    out = []
    for name, xy in zip(names, truth):
        image = cv2.imread(str(reference_dir / str(name)))
        if image is None:
            raise StoryBeamError(f"{reference_dir / str(name)}: not an image OpenCV can read")
        edge = np.concatenate([image[:, :40], image[:, -40:]], axis=1).astype(np.int16)
        row_colour = np.median(edge, axis=1)  # the wall or floor colour of each row
        mask = (np.abs(image.astype(np.int16) - row_colour[:, None]).max(axis=2) > 10).astype(np.uint8)
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
        out.append(Performer(image, mask > 0, np.asarray(xy[:, :2], np.float32)))
    return out


def background(size: tuple[int, int] = (WIDTH, HEIGHT), seed: int = 0) -> np.ndarray:
    """A wall above :data:`HORIZON`, a floor below, with camera noise (BGR uint8)."""
    w, h = size
    img = np.empty((h, w, 3), np.float32)
    img[:] = WALL_BGR
    img[int(h * HORIZON):] = FLOOR_BGR
    img += np.random.default_rng(seed).normal(0.0, 2.5, (h, w, 1)).astype(np.float32)
    return np.clip(img, 0, 255).astype(np.uint8)


def compose(frame: np.ndarray, performer: Performer, height: float, feet_x: float, feet_y: float) -> np.ndarray:
    """Paste ``performer`` into ``frame`` (in place) ``height`` px tall with the render's
    floor point below the figure (x 320, y 390) at (``feet_x``, ``feet_y``); returns the
    truth landmarks (33, 2) in the frame's pixels (outside it where the figure is cut)."""
    s = height / RENDER_HEIGHT_PX
    m = np.float32([[s, 0.0, feet_x - s * 320.0], [0.0, s, feet_y - s * 390.0]])
    ys, xs = np.nonzero(performer.mask)
    x0, y0 = m[0, 2] + s * xs.min(), m[1, 2] + s * ys.min()
    x1, y1 = m[0, 2] + s * (xs.max() + 1), m[1, 2] + s * (ys.max() + 1)
    h, w = frame.shape[:2]
    bx0, by0 = max(0, int(np.floor(x0))), max(0, int(np.floor(y0)))
    bx1, by1 = min(w, int(np.ceil(x1))), min(h, int(np.ceil(y1)))
    if bx1 > bx0 and by1 > by0:
        local = m.copy()
        local[:, 2] -= (bx0, by0)
        size = (bx1 - bx0, by1 - by0)
        src = cv2.warpAffine(performer.image, local, size, flags=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
        alpha = cv2.warpAffine(performer.mask.astype(np.float32), local, size, flags=cv2.INTER_LINEAR)[..., None]
        roi = frame[by0:by1, bx0:bx1]
        roi[...] = (alpha * src + (1.0 - alpha) * roi).astype(np.uint8)
    return performer.truth * s + m[:, 2]


@dataclass
class SceneFrame:
    """One frame of a scene: the image, each performer's truth landmarks (33, 2) and
    standing height (px), and which performer is to be followed (``None``: nobody)."""

    image: np.ndarray
    truths: list[np.ndarray]
    heights: list[float]
    target: int | None


def _lerp(a: float, b: float, u: float) -> float:
    return a + (b - a) * min(max(u, 0.0), 1.0)


def scene(name: str, frames: int = 45, size: tuple[int, int] = (WIDTH, HEIGHT)) -> Iterator[SceneFrame]:
    """The frames of scene ``name`` (module docstring)."""
    if name not in SCENES:
        raise StoryBeamError(f"unknown scene {name!r}; choose from {', '.join(SCENES)}")
    walk, jump = load_performers("person_walk"), load_performers("person_jump")
    w, h = size
    floor = h * 0.9
    for k in range(frames):
        u = k / max(1, frames - 1)
        img = background(size, seed=k)
        truths, heights = [], []
        target: int | None = 0

        def put(p: Performer, height: float, x: float, y: float = floor) -> None:
            truths.append(compose(img, p, height, x, y))
            heights.append(height)

        if name == "centre":
            put(walk[k % len(walk)], 700.0, w * 0.5)
        elif name == "edge-small":
            put(walk[k % len(walk)], h / 6.0, _lerp(w * 0.90, w * 0.95, u), h * 0.8)
        elif name == "walk-in":
            put(walk[k % len(walk)], _lerp(250.0, 650.0, u), _lerp(-0.02 * w, 0.45 * w, u))
        elif name == "three":
            hidden = k in (frames // 2, frames // 2 + 1)
            put(jump[k % len(jump)], _lerp(380.0, 460.0, u), _lerp(0.18 * w, 0.28 * w, u))
            put(walk[(k + 5) % len(walk)], _lerp(420.0, 620.0, u), _lerp(0.80 * w, 0.66 * w, u))
            if not hidden:
                put(walk[k % len(walk)], 480.0, _lerp(0.5 * w, 0.46 * w, u), floor - 20)
                target = 2
            else:
                target = None
        elif name == "empty":
            target = None
        yield SceneFrame(img, truths, heights, target)


#: The scenes, in the bench's order.
SCENES = ("centre", "edge-small", "walk-in", "three", "empty")


def on_target(pose: BodyPose | None, frame: SceneFrame) -> int | None:
    """Which performer ``pose`` is on (its hips' midpoint within :data:`ON_TARGET` of a
    performer's height from that performer's, its landmarks' height within that fraction
    of the true landmarks' height), else ``None``."""
    if pose is None:
        return None
    hips = pose.image_xy[23:25].mean(axis=0)
    span = np.ptp(pose.image_xy[:, 1])
    for i, (truth, height) in enumerate(zip(frame.truths, frame.heights)):
        true_span = np.ptp(truth[:, 1])
        if (np.linalg.norm(hips - truth[23:25].mean(axis=0)) <= ON_TARGET * height
                and abs(span - true_span) <= ON_TARGET * true_span):
            return i
    return None


# ----------------------------------------------------------------------------- bench
def _pin_one_core() -> int | None:
    """Pin this process to one CPU core (timings "on one core"); returns the core."""
    import os  # deferred: affinity only for the bench run

    if not hasattr(os, "sched_getaffinity"):
        return None
    core = sorted(os.sched_getaffinity(0))[-1]
    os.sched_setaffinity(0, {core})
    return core


def _median(values: list[float]) -> float:
    return float(np.median(values)) if values else float("nan")


def track_scene(frames: list[SceneFrame], tracker: BodyTracker) -> dict:
    """One scene through ``tracker`` (a take, as :func:`ar.body.track_frames` runs it):
    found / on-target rates over the frames that have a performer to follow, and times."""
    timings, cpu = [], [time.process_time()]

    def seen(k: int, image: np.ndarray, pose: BodyPose | None) -> None:
        timings.append(tracker.timing)
        cpu.append(time.process_time())

    take = track_frames([f.image for f in frames], fps=FPS, tracker=tracker, on_frame=seen)
    cpu_ms = np.diff(cpu) * 1e3  # this process's CPU time per frame (less at the mercy of other jobs than the wall clock)
    wanted = [k for k, f in enumerate(frames) if f.target is not None]
    found = [k for k in wanted if take.poses[k] is not None]
    right = [k for k in wanted if on_target(take.poses[k], frames[k]) == frames[k].target]
    wrong = [k for k, f in enumerate(frames) if take.poses[k] is not None and on_target(take.poses[k], f) != f.target]
    detect = [ms for ms, t in zip(take.pose_ms, timings) if t.detected]
    return {
        "frames": len(frames), "frames_to_follow": len(wanted),
        "found": len(found) / len(wanted) if wanted else float("nan"),
        "on_target": len(right) / len(wanted) if wanted else float("nan"),
        "wrong_frames": len(wrong), "pose_ms_median": take.pose_ms_median,
        "tracked_ms_median": _median([ms for ms, t in zip(take.pose_ms, timings) if not t.detected]),
        "detect_frames": len(detect), "detect_ms_median": _median(detect),
        "cpu_ms_median": _median(list(cpu_ms)),
        "tracked_cpu_ms_median": _median([ms for ms, t in zip(cpu_ms, timings) if not t.detected]),
        "detect_cpu_ms_median": _median([ms for ms, t in zip(cpu_ms, timings) if t.detected]),
        "tile_runs": int(sum(t.tiles for t in timings)),
    }


def acquisition_cost(frames: list[SceneFrame], tracker: BodyTracker) -> dict:
    """Every frame processed by a reset tracker (the detector always runs): median ms and
    the share of frames with a pose."""
    ms, cpu, found = [], [], 0
    for k, f in enumerate(frames):
        tracker.reset()
        t0, c0 = time.perf_counter(), time.process_time()
        found += tracker.process(f.image, k / FPS) is not None
        ms.append((time.perf_counter() - t0) * 1e3)
        cpu.append((time.process_time() - c0) * 1e3)
    return {"frames": len(frames), "found": found / len(frames), "ms_median": _median(ms), "cpu_ms_median": _median(cpu)}


def read_clip_rows(folder: Path) -> list[dict]:
    """The rows of ``folder/labels.csv`` (``file,label``), every file present."""
    labels = folder / "labels.csv"
    if not labels.is_file():
        raise StoryBeamError(f"--videos {folder}: no labels.csv (file,label)")
    with open(labels, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    if not rows or "file" not in rows[0]:
        raise StoryBeamError(f"{labels}: expected a header line and a 'file' column")
    missing = [r["file"] for r in rows if not (folder / r["file"]).is_file()]
    if missing:
        raise StoryBeamError(f"{labels}: {len(missing)} clip(s) missing, e.g. {missing[0]}")
    return rows


def detector_size_sweep(tracker: BodyTracker, fractions: tuple[float, ...] = tuple(np.round(np.arange(0.18, 0.42, 0.02), 2)),
                        side: int = 640) -> list[dict]:
    """What :data:`ar.body.acquire.DETECTABLE_FRACTION` rests on: each walk frame pasted into
    a square ``side`` frame (so the detector's 224 input is that frame, scaled), the person
    ``fraction`` × ``side`` tall, standing in the middle; the share of frames in which the
    whole-frame detector finds them, per fraction."""
    walk = load_performers("person_walk")
    out = []
    for fraction in fractions:
        hits = 0
        for k, p in enumerate(walk):
            img = background((side, side), seed=k)
            compose(img, p, fraction * side, side / 2, side * 0.5 + fraction * side / 2)
            hits += bool(tracker.detect(img))
        out.append({"fraction": float(fraction), "found": hits / len(walk)})
    return out


def track_videos(folder: Path, trackers: dict[str, BodyTracker]) -> list[dict]:
    """Every clip of ``folder/labels.csv`` (``file,label``) tracked by each of ``trackers``
    in turn (side by side, clip by clip): per tracker, the share of frames with a pose and
    the median ms per frame (wall clock and this process's CPU time)."""
    out = []
    for row in read_clip_rows(folder):
        rec: dict = {"file": row["file"], "label": row.get("label", "")}
        for mode, tracker in trackers.items():
            source = VideoFileSource(folder / row["file"])
            cpu = [time.process_time()]
            try:
                take = track_frames(source, tracker=tracker, on_frame=lambda k, image, pose: cpu.append(time.process_time()))
            finally:
                source.close()
            rec[mode] = {"frames": len(take.poses), "found": take.detect_rate, "pose_ms_median": take.pose_ms_median,
                         "cpu_ms_median": _median(list(np.diff(cpu) * 1e3))}
        out.append(rec)
    return out


def run_find_body_bench(frames: int = 45, tiles_per_frame: int | None = 4, videos: Path | None = None,
                        scenes: tuple[str, ...] = SCENES, progress: Callable[[int, int], None] | None = None) -> dict:
    """The bench (module docstring), JSON-ready."""
    if frames < 4:
        raise StoryBeamError(f"--frames must be at least 4, got {frames}")
    if videos is not None:
        read_clip_rows(Path(videos))  # a bad folder fails now, not after the scenes
    core = _pin_one_core()
    trackers = {"with": BodyTracker(num_threads=1, search=True, tiles_per_frame=tiles_per_frame),
                "without": BodyTracker(num_threads=1, search=False)}
    total, done = len(scenes) + 2 + (1 if videos else 0), 0
    result: dict = {"pinned_core": core, "image_size": [WIDTH, HEIGHT], "fps": FPS, "frames": frames,
                    "tiles_per_frame": tiles_per_frame, "tiles": len(trackers["with"].tiles((WIDTH, HEIGHT))),
                    "scenes": {}, "acquisition": {}, "videos": []}
    for name in scenes:
        shots = list(scene(name, frames))
        result["scenes"][name] = {mode: track_scene(shots, t) for mode, t in trackers.items()}
        done += 1
        if progress:
            progress(done, total)
    result["detector_size"] = detector_size_sweep(trackers["without"])
    for name in ("centre", "edge-small"):
        shots = list(scene(name, min(frames, 20)))
        result["acquisition"][name] = {mode: acquisition_cost(shots, t) for mode, t in trackers.items()}
        done += 1
        if progress:
            progress(done, total)
    if videos is not None:
        result["videos"] = track_videos(Path(videos), trackers)
        if progress:
            progress(total, total)
    return result


def format_table(result: dict) -> str:
    """The printed summary."""
    lines = ["Medians, ms per frame: wall clock / this process's CPU time.", "",
             "| scene | extra pass | found | on target | wrong frames | all frames | tracked frames | "
             "detector frames (n) | tile runs |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, modes in result["scenes"].items():
        for mode, r in modes.items():
            lines.append(f"| {name} | {mode} | {r['found']:.2f} | {r['on_target']:.2f} | {r['wrong_frames']} | "
                         f"{r['pose_ms_median']:.1f} / {r['cpu_ms_median']:.1f} | "
                         f"{r['tracked_ms_median']:.1f} / {r['tracked_cpu_ms_median']:.1f} | "
                         f"{r['detect_ms_median']:.1f} / {r['detect_cpu_ms_median']:.1f} ({r['detect_frames']}) | "
                         f"{r['tile_runs']} |")
    lines += ["", "| acquisition (reset every frame) | extra pass | found | ms |", "|---|---|---|---|"]
    for name, modes in result["acquisition"].items():
        for mode, r in modes.items():
            lines.append(f"| {name} | {mode} | {r['found']:.2f} | {r['ms_median']:.1f} / {r['cpu_ms_median']:.1f} |")
    lines += ["", "| body height / detector input side | " + " | ".join(f"{r['fraction']:.2f}" for r in result["detector_size"])
              + " |", "|---|" + "---|" * len(result["detector_size"]),
              "| frames found | " + " | ".join(f"{r['found']:.2f}" for r in result["detector_size"]) + " |"]
    if result["videos"]:
        lines += ["", "| clip | label | found with / without | ms with | ms without |", "|---|---|---|---|---|"]
        for r in result["videos"]:
            a, b = r["with"], r["without"]
            lines.append(f"| {r['file']} | {r['label']} | {a['found']:.2f} / {b['found']:.2f} | "
                         f"{a['pose_ms_median']:.1f} / {a['cpu_ms_median']:.1f} | "
                         f"{b['pose_ms_median']:.1f} / {b['cpu_ms_median']:.1f} |")
    return "\n".join(lines)
