"""How the camera changes "Act it out"'s answer, with known truth (``storybeam bench act-cameras``).

    storybeam bench act-cameras [--json out/act_cameras_bench.json] [--data DIR] [--limit 60]
                                [--seed 2] [--conditions bench,table-up,...] [--noise-px 0]

Real cameras are not the act-it-out bench's level camera 3.6 m from a performer who
stays in place (lab/bench/act_it_out.py): a tablet on a table sits 0.7 m up and looks up
or down, a phone's lens is wider, video runs at 24 to 60 frames per second, children walk
towards it or across its view, a take starts wherever the child was, and the frame may
cut the body at the knees. This bench isolates the *geometry* of those conditions from
the pose estimator: each held-out CMU trial's true joints are turned into BlazePose-like
landmarks (:func:`synthetic_landmarks`: the 33 landmarks where BlazePose marks them,
the inverse of :data:`retrieval.motion.landmarks.UP_OFFSETS`), projected through a
pinhole camera of the condition (:class:`Condition`) — image landmarks in pixels, world
landmarks in the camera's axes centred on the hips, as BlazePose gives them — and
searched exactly as a camera take is (:meth:`ActSearch.search_take`, 1-NN, the trial
left out). What falls from the ``bench`` condition to another is what that camera
geometry costs the features, with no estimator noise (``--noise-px`` adds Gaussian
pixel noise to the image landmarks, a crude estimator stand-in).

A condition's camera looks along −Z from (0, height, distance) with a pitch (positive:
looking up), a horizontal field of view and an image size; the take is the clip's middle
``seconds`` (or from ``start_frac`` of the clip), resampled to the condition's frame
rate. ``travel``: ``"none"`` removes the horizontal root translation and turns the body
to face the camera (the act-it-out bench's takes); ``"towards"`` keeps it, turned so the
path points at the camera and ends ``distance`` away; ``"across"`` turns it onto +X,
centred in front of the camera. ``cut`` is the fraction of the body's standing height
(from the floor) below which the frame ends (a body cut at the knees: 0.3): landmarks
below the frame's lower edge are clamped to it (BlazePose still reports a guess there)
and the image is made just tall enough, at the condition's focal length.
"""
from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.features import leg_length, mean_heading
from retrieval.library import ActSearch, LabelRow, read_labels
from retrieval.motion import (
    LANDMARK_INDEX,
    N_LANDMARKS,
    UP_OFFSETS,
    canonical_joint_map,
    load_motion,
    positions,
    resample,
)


@dataclass(frozen=True)
class Condition:
    """One way of filming a take (see the module docstring)."""

    name: str
    height: float = 0.9          # lens height above the floor, m
    distance: float = 3.6        # horizontal distance to the body (its mean, or the path's end), m
    pitch_deg: float = 0.0       # + looks up
    hfov_deg: float = 58.0
    size: tuple[int, int] = (640, 480)
    fps: float = 30.0
    seconds: float = 3.5
    travel: str = "none"         # none | towards | across
    start_frac: float | None = None  # None: the clip's middle
    cut: float | None = None     # frame ends at this fraction of standing height (None: whole body)
    description: str = ""


#: The conditions measured (name -> condition); ``bench`` is the act-it-out bench's camera.
CONDITIONS: dict[str, Condition] = {c.name: c for c in (
    Condition("bench", description="act-it-out bench: level, 0.9 m up, 3.6 m, 58 deg, 30 fps, in place"),
    Condition("table-up", height=0.7, distance=3.2, pitch_deg=6.0, hfov_deg=70.0, size=(1280, 720),
              description="phone on a table 0.7 m up looking up 6 deg, 70 deg lens"),
    Condition("table-level", height=0.7, distance=3.0, hfov_deg=70.0, size=(1280, 720),
              description="phone on a table 0.7 m up, level, 70 deg lens"),
    Condition("high-down", height=1.5, distance=3.0, pitch_deg=-12.0, hfov_deg=70.0, size=(1280, 720),
              description="hand-held 1.5 m up looking down 12 deg, 70 deg lens"),
    Condition("towards-up", height=0.7, distance=3.2, pitch_deg=6.0, hfov_deg=70.0, size=(1280, 720),
              travel="towards", description="travels towards a phone on a table looking up 6 deg, path ending 3.2 m away"),
    Condition("wide-close", height=1.0, distance=2.2, hfov_deg=75.0, size=(720, 1280),
              description="portrait 75 deg lens 2.2 m away"),
    Condition("fps24", fps=24.0, description="bench camera at 24 fps"),
    Condition("fps60", fps=60.0, description="bench camera at 60 fps"),
    Condition("towards", height=0.8, distance=3.0, hfov_deg=70.0, size=(1280, 720), travel="towards",
              description="travels towards the camera, path ending 3 m away"),
    Condition("across", height=0.8, distance=5.0, hfov_deg=70.0, size=(1280, 720), travel="across",
              description="travels across the view 5 m away"),
    Condition("start-early", start_frac=0.1, description="take from 10 % of the clip, not its middle"),
    Condition("short", seconds=2.0, description="a 2 s take"),
    Condition("long", seconds=6.0, description="a 6 s take"),
    Condition("knees-cut", height=1.1, distance=2.5, hfov_deg=70.0, cut=0.3,
              description="frame ends at 0.3 of standing height (knees)"),
)}


def _landmark_sources() -> dict[int, tuple[str, float]]:
    """BlazePose landmark index -> (canonical joint, offset along the trunk in leg lengths)
    that synthesises it: where BlazePose marks a point relative to the CMU joint (the
    inverse of :data:`UP_OFFSETS`; face points on the head, hand points on the wrist)."""
    src: dict[int, tuple[str, float]] = {}
    for name, i in LANDMARK_INDEX.items():
        side = "left" if name.startswith("left") else "right"
        if name in ("left_shoulder", "right_shoulder", "left_hip", "right_hip", "left_elbow", "right_elbow",
                    "left_knee", "right_knee", "left_ankle", "right_ankle"):
            src[i] = (name, -UP_OFFSETS.get(name, 0.0))
        elif name.endswith(("wrist", "pinky", "index", "thumb")) and "foot" not in name:
            src[i] = (f"{side}_hand", 0.0)
        elif name.endswith("heel"):
            src[i] = (f"{side}_ankle", 0.0)
        elif name.endswith("foot_index"):
            src[i] = (f"{side}_toe", -UP_OFFSETS[f"{side}_toe"])
        else:  # the face
            src[i] = ("head", 0.1)
    return src


_SOURCES = _landmark_sources()


def synthetic_landmarks(pos: np.ndarray, joint_map: dict[str, int], leg: float) -> np.ndarray:
    """(T, 33, 3) BlazePose-like landmark points in the world (metres, Y up) from
    canonical joint positions: each landmark its joint moved along the trunk (hips →
    neck) by the inverse of the landmark mapping's offsets."""
    pos = np.asarray(pos, dtype=np.float64)
    up = pos[:, joint_map["neck"]] - pos[:, joint_map["hips"]]
    up /= np.maximum(np.linalg.norm(up, axis=1, keepdims=True), 1e-9)
    out = np.empty((len(pos), N_LANDMARKS, 3))
    for i, (joint, off) in _SOURCES.items():
        out[:, i] = pos[:, joint_map[joint]] + off * leg * up
    return out


def camera_axes(pitch_deg: float) -> np.ndarray:
    """(3, 3) rows: the camera's right, down and forward axes in the world (Y up), for a
    camera looking along −Z pitched up by ``pitch_deg``."""
    t = np.radians(pitch_deg)
    fwd = np.array([0.0, np.sin(t), -np.cos(t)])
    up = np.array([0.0, np.cos(t), np.sin(t)])
    return np.stack([np.cross(fwd, up), -up, fwd])


def film(points: np.ndarray, cond: Condition, focal_px: float, size: tuple[int, int],
         rng: np.random.Generator | None = None, noise_px: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World landmark points (T, 33, 3) filmed by ``cond``'s camera: (world landmarks in
    the camera's axes — x right, y down, z away — centred on the hip midpoint, image
    landmarks in pixels, valid per frame: the hips in the image and in front of the lens)."""
    axes = camera_axes(cond.pitch_deg)
    cam = (points - np.array([0.0, cond.height, cond.distance])) @ axes.T
    w, h = size
    z = np.maximum(cam[..., 2], 1e-3)
    uv = np.stack([focal_px * cam[..., 0] / z + (w - 1) / 2, focal_px * cam[..., 1] / z + (h - 1) / 2], axis=-1)
    if rng is not None and noise_px > 0:
        uv = uv + rng.normal(0.0, noise_px, uv.shape)
    inside = (uv[..., 0] >= 0) & (uv[..., 0] < w) & (uv[..., 1] >= 0) & (uv[..., 1] < h)
    hips = (uv[:, LANDMARK_INDEX["left_hip"]] + uv[:, LANDMARK_INDEX["right_hip"]]) / 2
    valid = (cam[..., 2].min(axis=1) > 0.1) & (hips[:, 0] >= 0) & (hips[:, 0] < w) & (hips[:, 1] >= 0) & (hips[:, 1] < h)
    uv[..., 0] = np.clip(uv[..., 0], 0, w - 1)
    uv[..., 1] = np.clip(uv[..., 1], 0, h - 1)
    mid = (cam[:, LANDMARK_INDEX["left_hip"]] + cam[:, LANDMARK_INDEX["right_hip"]]) / 2
    return cam - mid[:, None], uv, valid & inside.all(axis=1) | (valid & (cond.cut is not None))


def _yaw(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


@dataclass
class Take:
    """One synthetic camera take: landmarks as :mod:`ar.body` gives them, at ``fps``."""

    world: np.ndarray
    image_xy: np.ndarray
    valid: np.ndarray
    fps: float
    size: tuple[int, int]
    meta: dict = field(default_factory=dict)


def make_take(row: LabelRow, cond: Condition, rng: np.random.Generator | None = None,
              noise_px: float = 0.0) -> Take:
    """``row``'s trial filmed under ``cond`` (module docstring)."""
    src = load_motion(row.file, row.skeleton) if row.skeleton else load_motion(row.file)
    src = resample(src, cond.fps)
    n = min(src.n_frames, max(2, int(round(cond.seconds * cond.fps))))
    start = (src.n_frames - n) // 2 if cond.start_frac is None else min(src.n_frames - n, int(cond.start_frac * src.n_frames))
    clip = src.slice(start, start + n)
    jm = canonical_joint_map(clip.skeleton)
    pos = positions(clip)
    leg = leg_length(clip.skeleton, jm)
    floor = float(np.percentile(pos[:, [jm[j] for j in ("left_ankle", "right_ankle", "left_toe", "right_toe")], 1]
                                .min(axis=1), 2.0))
    pos[..., 1] -= floor
    root = pos[:, jm["hips"]].copy()
    if cond.travel == "none":
        pos[..., [0, 2]] -= root[:, None, [0, 2]]
        pos = pos @ _yaw(-mean_heading(pos, jm)).T
    else:
        path = root[-1, [0, 2]] - root[0, [0, 2]]
        if np.linalg.norm(path) < 0.2:  # barely travels: face the camera
            pos = pos @ _yaw(-mean_heading(pos, jm)).T
            centre = pos[:, jm["hips"]].mean(axis=0)
        else:
            # turn the path onto the target direction: (x, z) of +Z is (0, 1) (towards the camera), +X (1, 0)
            target = np.array([0.0, 1.0]) if cond.travel == "towards" else np.array([1.0, 0.0])
            a = np.arctan2(path[0], path[1]) - np.arctan2(target[0], target[1])
            pos = pos @ _yaw(-a).T
            r2 = pos[:, jm["hips"]]
            centre = r2[-1] if cond.travel == "towards" else r2.mean(axis=0)
        pos[..., 0] -= centre[0]
        pos[..., 2] -= centre[2]
    points = synthetic_landmarks(pos, jm, leg)
    standing = 1.0
    if cond.cut is not None:  # an image whose lower edge is at `cut` of the standing height, at the body's distance
        standing = float(np.percentile(pos[:, jm["head"], 1], 90))
    w, h = cond.size
    focal = (w / 2) / np.tan(np.radians(cond.hfov_deg) / 2)
    size = (w, h)
    if cond.cut is not None:
        low = cond.cut * standing
        cam_low = (np.array([0.0, low, 0.0]) - np.array([0.0, cond.height, cond.distance])) @ camera_axes(cond.pitch_deg).T
        v_low = focal * cam_low[1] / cam_low[2] + (h - 1) / 2
        size = (w, int(min(h, max(2, v_low))))
    world, uv, valid = film(points, cond, focal, size, rng, noise_px)
    return Take(world, uv, valid, cond.fps, size, {"trial": row.trial, "label": row.label, "frames": n,
                                                  "in_view": float(valid.mean())})


def evaluate(search: ActSearch, rows: Sequence[LabelRow], cond: Condition, noise_px: float = 0.0,
             seed: int = 0, progress: Callable[[], None] | None = None) -> dict:
    """1-NN class of every row filmed under ``cond`` (trial left out): accuracy,
    per-class recall, the confusion pairs and the median search time."""
    rng = np.random.default_rng(seed)
    labels, predicted, ms, per_take = [], [], [], []
    for row in rows:
        take = make_take(row, cond, rng, noise_px)
        labels.append(row.label)
        if take.valid.any():
            t0 = time.perf_counter()
            hits = search.search_take(take.world, take.image_xy, take.valid, take.fps, take.size, k=1,
                                      exclude=[row.trial])
            ms.append((time.perf_counter() - t0) * 1000)
            predicted.append(hits[0].label if hits else "")
        else:
            predicted.append("")
        per_take.append({**take.meta, "predicted": predicted[-1]})
        if progress:
            progress()
    recall = {}
    for c in sorted(set(labels)):
        idx = [i for i, lab in enumerate(labels) if lab == c]
        recall[c] = float(np.mean([predicted[i] == c for i in idx]))
    confusion: dict[str, int] = defaultdict(int)
    for a, b in zip(labels, predicted):
        if a != b:
            confusion[f"{a}->{b or 'none'}"] += 1
    return {"condition": asdict(cond), "takes": len(rows),
            "accuracy": float(np.mean([a == b for a, b in zip(labels, predicted)])) if labels else float("nan"),
            "recall": recall, "confusion": dict(sorted(confusion.items(), key=lambda kv: -kv[1])),
            "search_ms": float(np.median(ms)) if ms else float("nan"), "per_take": per_take}


def run_act_cameras_bench(data: Path, limit: int = 60, seed: int = 2, conditions: Sequence[str] = tuple(CONDITIONS),
                          noise_px: float = 0.0, search: ActSearch | None = None,
                          progress: Callable[[int, int], None] | None = None, moves: Path | None = None) -> dict:
    """Every condition over the same ``limit`` trials (stratified draw of ``seed``, from
    ``data`` only), searched in ``data`` and ``moves`` (:meth:`ActSearch.build`)."""
    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown or not conditions:
        raise StoryBeamError(f"unknown condition(s) {', '.join(unknown) or '(none given)'}; "
                             f"choose from {', '.join(CONDITIONS)}")
    from lab.bench.act_it_out import choose_trials  # deferred: that module loads the renderer and the tracker

    rows = choose_trials(read_labels(data), limit, seed)
    search = search or ActSearch.build(data, fps=30.0, moves=moves)
    total, done = len(rows) * len(conditions), 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress:
            progress(done, total)

    results = [evaluate(search, rows, CONDITIONS[c], noise_px, seed, tick) for c in conditions]
    return {"data": str(data), "moves": None if moves is None else str(moves), "seed": seed, "limit": limit,
            "noise_px": noise_px, "library_clips": len(search),
            "conditions": results}


def format_table(result: dict) -> str:
    """The printed summary: one row per condition, per-class recall and the top confusions."""
    classes = sorted({c for r in result["conditions"] for c in r["recall"]})
    lines = ["| condition | takes | accuracy | " + " | ".join(classes) + " | top confusions | search ms |",
             "|---|---|---|" + "---|" * len(classes) + "---|---|"]
    for r in result["conditions"]:
        conf = ", ".join(f"{k} {v}" for k, v in list(r["confusion"].items())[:3])
        lines.append(f"| {r['condition']['name']} | {r['takes']} | {r['accuracy']:.3f} | "
                     + " | ".join(f"{r['recall'].get(c, float('nan')):.2f}" for c in classes)
                     + f" | {conf} | {r['search_ms']:.1f} |")
    return "\n".join(lines)
