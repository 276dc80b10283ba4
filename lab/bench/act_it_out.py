"""Measure "Act it out" end to end on synthetic performances (``storybeam bench act-it-out``).

    storybeam bench act-it-out [--json out/act_it_out_bench.json] [--data DIR] [--limit N]
                               [--extra-limit N] [--seed S] [--seconds 3.5] [--cache out/act_it_out]
                               [--variants person,kid,person-turned,person-clutter]

What it does, per *variant* (a figure and a way of filming it):

1. **Performances.** ``--limit`` trials of the labelled folder (default the shared CMU
   set), drawn by ``--seed`` and stratified by class (:func:`choose_trials`), each
   retargeted onto the figure (:func:`ar.render.build_character`: ``"person"``, a
   human-proportioned performer 1.7 m tall, or ``"kid"``, StoryBeam's kid character at
   child size 1.2 m), cut to a take of :data:`TAKE_SECONDS` from the clip's middle, in
   place (horizontal root translation removed) and turned to face the camera (its mean
   heading, :func:`retrieval.features.mean_heading`), or 30° away for the ``-turned``
   variant.
2. **Filming.** pyrender (:class:`ar.render.ProjectorRenderer`) at 640×480, 30 fps, from
   a level camera in front (a tablet standing on a table, 58° horizontal field of view:
   3.6 m from the person with the lens 0.9 m up, 2.2 m from the kid with the lens 0.6 m
   up — whole body and a jump in frame; :data:`FIGURES`); a plain wall and floor, or
   for ``-clutter`` a random picture of coloured boxes, stripes and noise behind the
   performer (composited where nothing was drawn).
3. **Pose.** helper A's tracker (:func:`ar.body.track_frames`, one thread) on every frame:
   detection rate and ``pose_ms_median``. Landmarks (never frames) are cached under
   ``out/act_it_out/`` keyed by the take's configuration, so a re-run only searches.
4. **Search.** :class:`retrieval.library.ActSearch` over the whole folder (frontal
   features), the take's landmarks as the query (:meth:`ActSearch.search_take`), 1-NN
   class: accuracy with the query's own *trial* left out of the library and with every
   trial of its *subject* left out; per-class recall; ``search_ms`` (median, one core).
5. **Ceiling.** the same search with the take's *true mocap joints* (the source clip's
   forward kinematics, same frames) as the query (:meth:`ActSearch.search_positions`):
   what the features allow when the pose estimator is perfect.

Tuning used seed 1; the reported numbers (docs/notebook/act-it-out.md) come from seed 2.
"""
from __future__ import annotations

import hashlib
import json
import time
import zlib
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np

from ar import look_at
from ar.body import BodyTracker, track_frames
from ar.render import CharacterRig, ProjectorRenderer, build_character, part_mesh
from ar.scene import box
from retrieval.animation import retarget
from retrieval.errors import StoryBeamError
from retrieval.features import leg_length, mean_heading
from retrieval.library import ActSearch, LabelRow, read_labels
from retrieval.motion import Motion, canonical_joint_map, load_motion, positions, resample

#: Frame rate and size of the synthetic camera.
FPS = 30.0
WIDTH, HEIGHT = 640, 480
#: Length of a take (seconds); shorter clips give a shorter take (the whole clip).
TAKE_SECONDS = 3.5
#: Camera: focal length (pixels; 58° horizontal field of view at 640 px).
FOCAL_PX = 0.9 * WIDTH
#: Figures: name -> (character design, standing height, camera distance, lens height), metres.
FIGURES: dict[str, tuple[str, float, float, float]] = {
    "person": ("person", 1.7, 3.6, 0.9),
    "kid": ("kid", 1.2, 2.2, 0.6),
}
#: Variants: name -> (figure, turn in degrees, cluttered background).
VARIANTS: dict[str, tuple[str, float, bool]] = {
    "person": ("person", 0.0, False),
    "kid": ("kid", 0.0, False),
    "person-turned": ("person", 30.0, False),
    "person-clutter": ("person", 0.0, True),
}
#: Classes and how many trials of each a 60-trial draw takes (kick has only 9 in CMU).
CLASS_SHARE = {"walk": 13, "run": 13, "jump": 13, "dance": 12, "kick": 9}
#: Bumped when the rendering changes, so cached landmarks are not reused.
RENDER_VERSION = "1"
WALL_RGB = (200, 196, 188)
FLOOR_RGB = (120, 118, 112)


def choose_trials(rows: Sequence[LabelRow], limit: int, seed: int) -> list[LabelRow]:
    """``limit`` rows drawn by ``seed``, stratified by class: each class in proportion to
    :data:`CLASS_SHARE` (at most all its rows), the remainder from the largest classes;
    rows of other classes are ignored. Order: by class, then drawn order."""
    by: dict[str, list[LabelRow]] = defaultdict(list)
    for r in rows:
        if r.label in CLASS_SHARE:
            by[r.label].append(r)
    if not by:
        raise StoryBeamError(f"no rows of the classes {', '.join(CLASS_SHARE)} to perform")
    rng = np.random.default_rng(seed)
    total = sum(CLASS_SHARE[c] for c in by)
    want = {c: min(len(by[c]), int(round(limit * CLASS_SHARE[c] / total))) for c in by}
    spare = limit - sum(want.values())
    for c in sorted(by, key=lambda c: -len(by[c])):
        extra = max(0, min(spare, len(by[c]) - want[c]))
        want[c] += extra
        spare -= extra
    out = []
    for c in sorted(by):
        order = rng.permutation(len(by[c]))
        out += [by[c][i] for i in order[: want[c]]]
    return out[:limit] if sum(want.values()) > limit else out


@dataclass
class Performance:
    """One synthetic take: ``motion`` on the figure's skeleton (in place, turned), the
    source clip's true canonical joint ``positions`` over the same frames (metres, Y
    up) with its ``joint_map`` and leg length ``leg`` (metres), at :data:`FPS`."""

    row: LabelRow
    motion: Motion
    positions: np.ndarray
    joint_map: dict[str, int]
    leg: float


def _yaw(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def make_performance(row: LabelRow, figure: str, turn_deg: float = 0.0,
                     take_seconds: float = TAKE_SECONDS) -> Performance:
    """The take of ``row`` performed by ``figure`` (see the module docstring, step 1)."""
    design, height, _, _ = FIGURES[figure]
    src = load_motion(row.file, row.skeleton) if row.skeleton else load_motion(row.file)
    src = resample(src, FPS)
    n = min(src.n_frames, max(2, int(round(take_seconds * FPS))))
    start = (src.n_frames - n) // 2
    src = src.slice(start, start + n)
    jm = canonical_joint_map(src.skeleton)
    true_pos = positions(src)
    ch = build_character(design, height)
    m = retarget(src, ch.skeleton)
    tm = canonical_joint_map(m.skeleton)
    heading = mean_heading(positions(m), tm)
    r = _yaw(np.radians(turn_deg) - heading)
    m.rotations[:, 0] = r @ m.rotations[:, 0]
    m.root_translation[:, [0, 2]] = 0.0
    return Performance(row, m, true_pos, jm, leg_length(src.skeleton, jm))


def _background(rng: np.random.Generator) -> np.ndarray:
    """A cluttered picture (H, W, 3) uint8: a noisy gradient, stripes and coloured boxes."""
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float32)
    base = rng.uniform(60, 200, 3)[None, None] + (x[..., None] / WIDTH - 0.5) * rng.uniform(-80, 80, 3)
    img = base + rng.normal(0, 12, (HEIGHT, WIDTH, 1))
    period, phase = rng.uniform(12, 40), rng.uniform(0, np.pi)
    img += 25 * np.sin(2 * np.pi * (x + 0.4 * y) / period + phase)[..., None]
    for _ in range(int(rng.integers(10, 20))):
        w, h = rng.integers(30, 200, 2)
        x0, y0 = rng.integers(0, WIDTH - 20), rng.integers(0, HEIGHT - 20)
        img[y0:y0 + h, x0:x0 + w] = rng.uniform(0, 255, 3)
        if rng.random() < 0.5:  # a checkered box
            cell = int(rng.integers(4, 16))
            chk = ((y[y0:y0 + h, x0:x0 + w] // cell + x[y0:y0 + h, x0:x0 + w] // cell) % 2)[..., None]
            img[y0:y0 + h, x0:x0 + w] *= 0.6 + 0.4 * chk
    return np.clip(img, 0, 255).astype(np.uint8)


def camera_K() -> np.ndarray:
    return np.array([[FOCAL_PX, 0, WIDTH / 2 - 0.5], [0, FOCAL_PX, HEIGHT / 2 - 0.5], [0, 0, 1.0]])


def render_frames(perf: Performance, figure: str, clutter: bool = False, seed: int = 0) -> Iterator[np.ndarray]:
    """The take's frames, (480, 640, 3) uint8 **BGR** (what a camera source gives), one by
    one (a take is never held whole in memory)."""
    design, height, dist, lens = FIGURES[figure]
    r = ProjectorRenderer(WIDTH, HEIGHT, camera_K(), znear=0.1, zfar=30.0, ambient=0.45, light_intensity=3.0)
    try:
        r.scene.bg_color = np.array([*np.array(WALL_RGB) / 255.0, 1.0])
        r.add("floor", part_mesh(box((12.0, 0.02, 12.0), (0.0, -0.011, 0.0)), FLOOR_RGB))
        rig = CharacterRig(r, build_character(design, height))
        rig.bind(perf.motion)
        r.set_view(look_at(np.array([0.0, lens, dist]), np.array([0.0, lens, 0.0]),
                           np.array([0.0, 1.0, 0.0])))
        back = None
        if clutter:
            back = _background(np.random.default_rng(seed))
            r.remove("floor")
        for f in range(perf.motion.n_frames):
            rig.show_frame(f)
            if back is None:
                rgb = r.render()[..., :3]
            else:
                rgb, depth = r.render(with_depth=True)
                rgb = np.where((depth > 0)[..., None], rgb[..., :3], back)
            yield np.ascontiguousarray(rgb[..., ::-1])
    finally:
        r.close()


# ----------------------------------------------------------------------------- the run
def _pin_one_core() -> list[int] | None:
    """Pin this process to one CPU core (timings "on one core"); returns the core."""
    import os

    if not hasattr(os, "sched_getaffinity"):
        return None
    cores = sorted(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {cores[-1]})
    return [cores[-1]]


def _take_key(row: LabelRow, variant: str, seed: int, take_seconds: float) -> str:
    figure, turn, clutter = VARIANTS[variant]
    st = row.file.stat()
    parts = [RENDER_VERSION, variant, figure, repr(FIGURES[figure]), repr(turn), repr(clutter), str(seed) if clutter else "",
             row.trial, str(row.file.resolve()), str(st.st_size), str(st.st_mtime_ns), repr(take_seconds),
             repr((WIDTH, HEIGHT, FOCAL_PX, FPS))]
    return hashlib.sha1("|".join(parts).encode()).hexdigest()[:16]


def perform_and_track(row: LabelRow, variant: str, seed: int, cache_dir: Path | None,
                      take_seconds: float = TAKE_SECONDS) -> dict:
    """One take of ``row`` in ``variant``: rendered, tracked by :mod:`ar.body` (one thread),
    its landmarks (never its frames) cached in ``cache_dir``. Returns the arrays
    (``world``, ``image_xy``, ``valid``, ``pose_ms``, ``true_pos``, ``true_leg``) and the
    joint map of ``true_pos``."""
    figure, turn, clutter = VARIANTS[variant]
    path = None if cache_dir is None else cache_dir / f"{variant}-{row.trial}-{_take_key(row, variant, seed, take_seconds)}.npz"
    if path is not None and path.is_file():
        try:
            with np.load(path) as z:
                out = {k: z[k] for k in z.files}
            out["joint_map"] = json.loads(str(out.pop("joint_map_json")))
            return out
        except Exception:  # a damaged cache entry is redone
            pass
    perf = make_performance(row, figure, turn, take_seconds)
    take = track_frames(render_frames(perf, figure, clutter, seed=zlib.crc32(f"{seed}:{row.trial}".encode())),
                        fps=FPS, tracker=BodyTracker(num_threads=1))
    world, image_xy, _vis, valid = take.arrays()
    out = {"world": world.astype(np.float32), "image_xy": image_xy.astype(np.float32), "valid": valid,
           "pose_ms": np.asarray(take.pose_ms, np.float64), "true_pos": perf.positions.astype(np.float32),
           "true_leg": np.float64(perf.leg)}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, **out, joint_map_json=json.dumps(perf.joint_map))
        tmp.replace(path)
    out["joint_map"] = perf.joint_map
    return out


def _recall(labels: list[str], predicted: list[str]) -> dict[str, float]:
    out = {}
    for c in sorted(set(labels)):
        idx = [i for i, lab in enumerate(labels) if lab == c]
        out[c] = sum(predicted[i] == c for i in idx) / len(idx)
    return out


def evaluate_variant(search, rows: Sequence[LabelRow], variant: str, seed: int, cache_dir: Path | None,
                     subjects: dict[str, set[str]], progress: Callable[[], None] | None = None,
                     take_seconds: float = TAKE_SECONDS) -> dict:
    """Every take of ``rows`` in ``variant``: detection, 1-NN class with the trial and with
    the subject left out, the true-joint ceiling, per-class recall, pose and search time."""
    labels, pred_trial, pred_subject, ceil_trial, ceil_subject = [], [], [], [], []
    detect, pose_ms, search_ms, takes = [], [], [], []
    for row in rows:
        t = perform_and_track(row, variant, seed, cache_dir, take_seconds)
        detect.append(float(np.mean(t["valid"])))
        pose_ms.extend(t["pose_ms"].tolist())
        same_subject = subjects.get(row.subject, set()) | {row.trial} if row.subject else {row.trial}
        labels.append(row.label)
        if t["valid"].any():
            t0 = time.perf_counter()
            hits = search.search_take(t["world"], t["image_xy"], t["valid"], FPS, (WIDTH, HEIGHT), k=1,
                                      exclude=[row.trial])
            search_ms.append((time.perf_counter() - t0) * 1000)
            pred_trial.append(hits[0].label if hits else "")
            hits = search.search_take(t["world"], t["image_xy"], t["valid"], FPS, (WIDTH, HEIGHT), k=1,
                                      exclude=same_subject)
            pred_subject.append(hits[0].label if hits else "")
        else:
            pred_trial.append("")
            pred_subject.append("")
        kw = {"joint_map": t["joint_map"], "body_size": float(t["true_leg"])}
        ceil_trial.append(search.search_positions(t["true_pos"], FPS, 1, [row.trial], **kw)[0].label)
        hits = search.search_positions(t["true_pos"], FPS, 1, same_subject, **kw)
        ceil_subject.append(hits[0].label if hits else "")
        takes.append({"trial": row.trial, "label": row.label, "subject": row.subject, "detect_rate": detect[-1],
                      "predicted": pred_trial[-1], "predicted_subject_out": pred_subject[-1],
                      "ceiling": ceil_trial[-1]})
        if progress:
            progress()

    def acc(p: list[str]) -> float:
        return float(np.mean([a == b for a, b in zip(p, labels)])) if labels else float("nan")

    figure, turn, clutter = VARIANTS[variant]
    return {
        "variant": variant, "figure": figure, "turn_deg": turn, "clutter": clutter, "takes": len(rows),
        "frames": len(pose_ms),
        "detect_rate": float(np.mean(detect)) if detect else float("nan"),
        "accuracy_trial_out": acc(pred_trial), "accuracy_subject_out": acc(pred_subject),
        "ceiling_trial_out": acc(ceil_trial), "ceiling_subject_out": acc(ceil_subject),
        "recall": _recall(labels, pred_trial), "ceiling_recall": _recall(labels, ceil_trial),
        "pose_ms_median": float(np.median(pose_ms)) if pose_ms else float("nan"),
        "search_ms": float(np.median(search_ms)) if search_ms else float("nan"),
        "per_take": takes,
    }


def run_act_it_out_bench(data: Path, limit: int = 60, seed: int = 2, variants: Sequence[str] = tuple(VARIANTS),
                         cache_dir: Path | None = Path("out/act_it_out"),
                         progress: Callable[[int, int], None] | None = None,
                         take_seconds: float = TAKE_SECONDS, extra_limit: int | None = None,
                         moves: Path | None = None) -> dict:
    """The whole bench (module docstring): one result per variant, JSON-ready.
    ``extra_limit`` (default ``limit``) trials are drawn for the turned and cluttered
    variants (a stratified draw of that size with the same seed). ``moves``: a labelled
    folder whose clips join the library (:meth:`ActSearch.build`); takes are drawn from
    ``data`` only."""
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown or not variants:
        raise StoryBeamError(f"unknown variant(s) {', '.join(unknown) or '(none given)'}; choose from {', '.join(VARIANTS)}")
    if limit < 1 or (extra_limit is not None and extra_limit < 1):
        raise StoryBeamError(f"--limit and --extra-limit must be at least 1, got {limit} and {extra_limit}")
    rows = read_labels(data)
    chosen = choose_trials(rows, limit, seed)
    extra = chosen if extra_limit is None else choose_trials(rows, extra_limit, seed)
    per_variant = {v: extra if (VARIANTS[v][1] or VARIANTS[v][2]) else chosen for v in variants}
    subjects: dict[str, set[str]] = defaultdict(set)
    for r in rows:
        if r.subject:
            subjects[r.subject].add(r.trial)
    core = _pin_one_core()
    search = ActSearch.build(data, fps=FPS, moves=moves)
    total, done = sum(len(r) for r in per_variant.values()), 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress:
            progress(done, total)

    results = [evaluate_variant(search, per_variant[v], v, seed, cache_dir, subjects, tick, take_seconds)
               for v in variants]
    return {"data": str(data), "moves": None if moves is None else str(moves),
            "seed": seed, "limit": limit, "extra_limit": extra_limit,
            "library_clips": len(search), "library_windows": len(search.index), "pinned_core": core,
            "fps": FPS, "image_size": [WIDTH, HEIGHT], "take_seconds": take_seconds, "variants": results}


def format_table(result: dict) -> str:
    """The printed summary: one row per variant, then per-class recall."""
    lines = ["| variant | takes | detect | acc trial-out | ceiling | acc subject-out | ceiling | pose ms | search ms |",
             "|---|---|---|---|---|---|---|---|---|"]
    for v in result["variants"]:
        lines.append(f"| {v['variant']} | {v['takes']} | {v['detect_rate']:.3f} | {v['accuracy_trial_out']:.3f} | "
                     f"{v['ceiling_trial_out']:.3f} | {v['accuracy_subject_out']:.3f} | {v['ceiling_subject_out']:.3f} | "
                     f"{v['pose_ms_median']:.1f} | {v['search_ms']:.1f} |")
    classes = sorted({c for v in result["variants"] for c in v["recall"]})
    lines += ["", "| variant | " + " | ".join(f"{c} (ceiling)" for c in classes) + " |",
              "|---|" + "---|" * len(classes)]
    for v in result["variants"]:
        lines.append(f"| {v['variant']} | " + " | ".join(
            f"{v['recall'].get(c, float('nan')):.2f} ({v['ceiling_recall'].get(c, float('nan')):.2f})" for c in classes)
            + " |")
    return "\n".join(lines)
