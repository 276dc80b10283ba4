"""Act it out on real footage (``storybeam bench act-it-out --videos DIR``).

    storybeam bench act-it-out --videos /work/data/act_real [--data ../shared/data/cmu]
                               [--top 3] [--cache out/act_it_out] [--json out/act_it_out_videos.json]

``DIR`` holds video clips and a ``labels.csv`` (``file,label``; e.g. the development set
that ``scripts/act_real.py`` materialises from ``lab/datasets/act_real_manifest.csv``).
Every clip goes through the product's flow, as ``storybeam search --video CLIP --data
LIBRARY`` does:

1. **Pose.** the whole clip through :class:`app.services.act_it_out.ActItOut`
   (:class:`ar.camera_sources.VideoFileSource`, unpaced, a fresh :class:`ar.body.BodyTracker`
   per clip, one thread): the body-found rate (share of frames with a body), what the app
   would tell the child (:meth:`ActItOut.judge`) and ``pose_ms`` per frame. The landmarks
   (never frames) are cached per clip under ``CACHE/videos/``, keyed by the clip's bytes
   and the source of :mod:`ar.body` and the flow, so a re-run after a change to the search
   or its features only searches, and a change to the pose code re-tracks.
2. **Search.** :class:`retrieval.library.ActSearch` over ``--data`` (the whole library,
   built once; nothing is left out: a real clip is in no library), the take's landmarks
   as the query (:meth:`ActSearch.search_take`, what :meth:`ActItOut.results` calls),
   ``--top`` clips: top-1 class and whether the label is among the top-``k`` clips'
   classes; ``search_ms`` per clip after one warm-up search.
3. **Diagnosis** (untimed): per clip what the take shows (:func:`describe_take`: the hips'
   rise and travel, raised hands, coming nearer, body size) and the rank of the first clip
   of the right class among the nearest :data:`DIAGNOSTIC_DEPTH`.
4. **Report.** per-class top-1 and top-k recall, overall and balanced accuracy, the
   confusion matrix (JSON, and a PNG beside the JSON), per-clip body-found rate, and the
   medians of ``pose_ms`` (all frames) and ``search_ms`` (all clips). The process is
   pinned to one core (OpenCV and the BLAS pools to one thread).

A clip with no body in any frame has no answer (predicted ``"none"``, counted wrong).
"""
from __future__ import annotations

import csv
import hashlib
import json
import os
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ar.camera_sources import VIDEO_SUFFIXES, VideoFileSource
from app.paths import REPO_ROOT
from app.services.act_it_out import ActItOut
from retrieval.errors import StoryBeamError
from retrieval.library import ActSearch
from retrieval.motion import landmarks_to_positions

CLASSES = ("walk", "run", "jump", "kick", "dance")
NONE = "none"
#: How deep the diagnostic search looks for the first clip of the right class.
DIAGNOSTIC_DEPTH = 20
#: Sources whose change invalidates cached landmarks (the pose estimator and the flow).
_POSE_SOURCES = ("ar/body", "app/services/act_it_out.py", "ar/camera_sources.py")


class VideoSetError(StoryBeamError):
    """A videos folder or its labels.csv that cannot be used (file and line named)."""


def read_video_labels(folder: Path) -> list[tuple[Path, str]]:
    """The (clip path, label) rows of ``folder/labels.csv`` (columns ``file,label``), in
    file order; every file must exist and be a video."""
    path = Path(folder) / "labels.csv"
    if not path.is_file():
        raise VideoSetError(f"--videos {folder}: no labels.csv (columns file,label)")
    rows = []
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        if not {"file", "label"} <= set(reader.fieldnames or ()):
            raise VideoSetError(f"{path}:1: expected the columns file,label, got {','.join(reader.fieldnames or [])}")
        for line, row in enumerate(reader, 2):
            clip, label = (row["file"] or "").strip(), (row["label"] or "").strip()
            if not clip or not label:
                raise VideoSetError(f"{path}:{line}: empty file or label")
            video = Path(folder) / clip
            if video.suffix.lower() not in VIDEO_SUFFIXES:
                raise VideoSetError(f"{path}:{line}: {clip} is not a video ({', '.join(VIDEO_SUFFIXES)})")
            if not video.is_file():
                raise VideoSetError(f"{path}:{line}: {video} not found")
            rows.append((video, label))
    if not rows:
        raise VideoSetError(f"{path}: no clips listed")
    return rows


def pose_code_key() -> str:
    """A digest of the pose estimator's and the flow's source files (cache key)."""
    h = hashlib.sha1()
    for rel in _POSE_SOURCES:
        p = REPO_ROOT / rel
        for f in sorted(p.rglob("*.py")) if p.is_dir() else [p]:
            if f.is_file():
                h.update(f.relative_to(REPO_ROOT).as_posix().encode())
                h.update(f.read_bytes())
    return h.hexdigest()[:12]


def _clip_key(video: Path) -> str:
    h = hashlib.sha1(video.read_bytes())
    return h.hexdigest()[:16]


def track_clip(video: Path, cache_dir: Path | None, code_key: str | None = None) -> dict:
    """The clip's take through :class:`ActItOut` (module docstring, step 1): arrays
    ``world``, ``image_xy``, ``valid``, ``pose_ms``, and ``fps``, ``image_size``,
    ``verdict`` (the app's judgement, a dict). Cached in ``cache_dir`` when given."""
    key = f"{video.stem}-{_clip_key(video)}-{code_key or pose_code_key()}"
    path = None if cache_dir is None else Path(cache_dir) / "videos" / f"{key}.npz"
    if path is not None and path.is_file():
        try:
            with np.load(path) as z:
                out = {k: z[k] for k in ("world", "image_xy", "valid", "pose_ms")}
                meta = json.loads(str(z["meta_json"]))
            return {**out, **meta, "cached": True}
        except Exception:  # a damaged cache entry is redone
            pass
    flow = ActItOut(None)  # a fresh tracker per clip: nothing carried over from the last one
    with VideoFileSource(video, paced=False) as source:
        take = flow.take_from_source(source, seconds=0)  # the whole clip
    if not take.poses:
        raise VideoSetError(f"{video}: no frame could be read")
    world, image_xy, _vis, valid = take.arrays()
    out = {"world": world.astype(np.float32), "image_xy": image_xy.astype(np.float32), "valid": valid,
           "pose_ms": np.asarray(take.pose_ms, np.float64)}
    meta = {"fps": float(take.fps), "image_size": [int(v) for v in take.image_size],
            "verdict": flow.judge(take).as_dict()}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, **out, meta_json=json.dumps(meta))
        tmp.replace(path)
    return {**out, **meta, "cached": False}


def describe_take(world: np.ndarray, image_xy: np.ndarray, valid: np.ndarray, fps: float,
                  image_size: tuple[int, int]) -> dict:
    """What a take shows, for reading the misses: from the joints the search sees
    (:func:`retrieval.motion.landmarks_to_positions`, metres, Y up, in leg lengths ``L``)
    the hips' rise (5th to 95th percentile of their height) and sideways travel, the share
    of frames with a hand above the head; from the image the change of the trunk's length
    in pixels from the first to the last half second (> 1: the performer came nearer) and
    the median body height as a share of the picture's."""
    pos, jm, leg = landmarks_to_positions(world, image_xy, valid, image_size, fps)
    root = pos[:, jm["hips"]]

    def spread(x: np.ndarray) -> float:
        return float((np.percentile(x, 95) - np.percentile(x, 5)) / leg)

    hands = np.maximum(pos[:, jm["left_hand"], 1], pos[:, jm["right_hand"], 1])
    seen = image_xy[valid]
    trunk = np.linalg.norm((seen[:, 11] + seen[:, 12]) / 2 - (seen[:, 23] + seen[:, 24]) / 2, axis=1)
    half = max(1, int(round(fps / 2)))
    return {"rise_L": spread(root[:, 1]), "travel_L": spread(root[:, 0]),
            "hands_up": float(np.mean(hands > pos[:, jm["head"], 1])),
            "nearer": float(np.median(trunk[-half:]) / max(np.median(trunk[:half]), 1e-6)),
            "body_height": float(np.median(np.ptp(seen[:, :, 1], axis=1)) / image_size[1])}


def pin_process_to_one_core() -> int | None:
    """OpenCV to one thread and the process to one CPU (so every pool shares that CPU);
    returns the CPU. The thread-count variables of BLAS and numba are read when those
    start, so a run that wants them at 1 sets them in its environment (the notebook's
    commands do)."""
    import cv2  # deferred: OpenCV is loaded by the camera source anyway

    cv2.setNumThreads(1)
    if not hasattr(os, "sched_setaffinity"):
        return None
    cpu = sorted(os.sched_getaffinity(0))[-1]
    os.sched_setaffinity(0, {cpu})
    return cpu


def confusion(labels: Sequence[str], predicted: Sequence[str], rows: Sequence[str],
              cols: Sequence[str]) -> list[list[int]]:
    """Counts ``[true][answer]``: ``rows`` the true classes, ``cols`` the answers (an
    answer not in ``cols`` counts as its last column, ``"none"``)."""
    m = [[0] * len(cols) for _ in rows]
    for t, p in zip(labels, predicted):
        if t in rows:
            m[list(rows).index(t)][list(cols).index(p) if p in cols else len(cols) - 1] += 1
    return m


def draw_confusion(matrix: list[list[int]], classes: Sequence[str], cols: Sequence[str], path: Path,
                   title: str) -> Path:
    """The confusion matrix as a PNG (rows: ``classes``, the true class; columns:
    ``cols``, the top-1 answer), counts in the cells and each row's recall at its end."""
    import matplotlib  # deferred: plotting only for the picture

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: after choosing the headless backend

    m = np.asarray(matrix, dtype=float)
    share = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=110)
    ax.imshow(share, cmap="Blues", vmin=0, vmax=1)
    for i in range(len(classes)):
        for j in range(len(cols)):
            if m[i, j]:
                ax.text(j, i, int(m[i, j]), ha="center", va="center", color="white" if share[i, j] > 0.55 else "black")
        total = int(m[i].sum())
        right = int(m[i, list(cols).index(classes[i])]) if classes[i] in cols else 0
        ax.text(len(cols) - 0.4, i, f"{right}/{total}", ha="left", va="center", fontsize=9)
    ax.set_xticks(range(len(cols)), cols)
    ax.set_yticks(range(len(classes)), classes)
    ax.set_xlabel("answer (top 1)")
    ax.set_ylabel("what the clip shows")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def _median(values: Sequence[float]) -> float:
    return float(np.median(values)) if len(values) else float("nan")


def run_act_videos_bench(videos: Path, data: Path, cache_dir: Path | None = Path("out/act_it_out"), top: int = 3,
                         progress: Callable[[int, int], None] | None = None, plot: Path | None = None,
                         search: ActSearch | None = None, moves: Path | None = None) -> dict:
    """The whole bench (module docstring); JSON-ready. ``search`` (default: built from
    ``data`` and ``moves``, :meth:`ActSearch.build`) lets a caller reuse a library."""
    if top < 1:
        raise StoryBeamError(f"--top must be at least 1, got {top}")
    rows = read_video_labels(Path(videos))
    cpu = pin_process_to_one_core()
    t0 = time.perf_counter()
    search = search if search is not None else ActSearch.build(data, moves=moves)
    build_s = time.perf_counter() - t0
    search.search_features(search.index.clip_features[0], k=1)  # loads the compiled kernels, outside the timings
    code_key = pose_code_key()
    clips, pose_ms, search_ms = [], [], []
    for n, (video, label) in enumerate(rows, 1):
        t = track_clip(video, cache_dir, code_key)
        pose_ms.extend(t["pose_ms"].tolist())
        hits, ms = [], float("nan")
        if t["valid"].any():
            s0 = time.perf_counter()
            hits = search.search_take(t["world"], t["image_xy"], t["valid"], t["fps"], tuple(t["image_size"]), k=top)
            ms = (time.perf_counter() - s0) * 1e3
            search_ms.append(ms)
        answers = [h.label for h in hits]
        shows, first_right = {}, None
        if t["valid"].any():  # untimed: what the take shows and how far down the right class comes
            shows = describe_take(t["world"], t["image_xy"], t["valid"], t["fps"], tuple(t["image_size"]))
            deep = search.search_take(t["world"], t["image_xy"], t["valid"], t["fps"], tuple(t["image_size"]),
                                      k=DIAGNOSTIC_DEPTH)
            first_right = next((i for i, h in enumerate(deep, 1) if h.label == label), None)
        clips.append({"file": video.name, "label": label, "predicted": answers[0] if answers else NONE,
                      "top": [{"trial": h.trial, "label": h.label, "distance": float(h.distance),
                               "start_s": h.start_s, "end_s": h.end_s} for h in hits],
                      f"in_top{top}": label in answers, "detect_rate": float(np.mean(t["valid"])),
                      "frames": int(len(t["valid"])), "fps": t["fps"], "image_size": t["image_size"],
                      "seconds": len(t["valid"]) / t["fps"], "pose_ms_median": _median(t["pose_ms"]),
                      "search_ms": ms, "verdict": t["verdict"], "cached_landmarks": t["cached"],
                      "shows": shows, f"first_right_in_top{DIAGNOSTIC_DEPTH}": first_right})
        if progress:
            progress(n, len(rows))
    result = summarise(clips, top)
    result.update({"videos": str(videos), "data": str(data), "moves": None if moves is None else str(moves),
                   "library_clips": len(search),
                   "library_windows": len(search.index), "library_build_s": build_s, "pinned_cpu": cpu,
                   "pose_code_key": code_key, "pose_ms_median": _median(pose_ms), "pose_frames": len(pose_ms),
                   "search_ms_median": _median(search_ms), "clips": clips})
    if plot is not None:
        acc = result["accuracy_top1"]
        result["confusion_png"] = str(draw_confusion(
            result["confusion"], result["classes"], result["confusion_columns"], plot,
            f"Act it out on {len(clips)} real clips: top-1 {acc:.2f} ({Path(videos).name})"))
    return result


def summarise(clips: list[dict], top: int) -> dict:
    """Accuracy figures over per-clip results (``label``, ``predicted``, ``in_topK``,
    ``detect_rate``): per-class top-1/top-k recall, overall and balanced accuracy, the
    confusion matrix, and how many clips had a body in at least 95 % of their frames."""
    labels = [c["label"] for c in clips]
    predicted = [c["predicted"] for c in clips]
    classes = [c for c in CLASSES if c in labels] + sorted(set(labels) - set(CLASSES))
    cols = list(CLASSES) + sorted((set(labels) | set(predicted)) - set(CLASSES) - {NONE}) + [NONE]
    per_class = {}
    for c in classes:
        idx = [i for i, lab in enumerate(labels) if lab == c]
        per_class[c] = {"clips": len(idx), "top1": sum(predicted[i] == c for i in idx) / len(idx),
                        f"top{top}": sum(clips[i][f"in_top{top}"] for i in idx) / len(idx),
                        "detect_rate_median": _median([clips[i]["detect_rate"] for i in idx])}
    detect = [c["detect_rate"] for c in clips]
    return {
        "top": top, "classes": classes, "clips_total": len(clips),
        "accuracy_top1": float(np.mean([p == t for p, t in zip(predicted, labels)])) if clips else float("nan"),
        f"accuracy_top{top}": float(np.mean([c[f"in_top{top}"] for c in clips])) if clips else float("nan"),
        "balanced_top1": float(np.mean([v["top1"] for v in per_class.values()])) if per_class else float("nan"),
        "per_class": per_class, "confusion": confusion(labels, predicted, classes, cols),
        "confusion_columns": cols,
        "clips_body_95": int(sum(d >= 0.95 for d in detect)), "detect_rate_median": _median(detect),
    }


def format_videos_table(result: dict) -> str:
    """The printed summary: per class, then overall, then one line per clip."""
    top = result["top"]
    lines = [f"| class | clips | top-1 | top-{top} | body found (median) |", "|---|---|---|---|---|"]
    for c, v in result["per_class"].items():
        lines.append(f"| {c} | {v['clips']} | {v['top1']:.2f} | {v[f'top{top}']:.2f} | {v['detect_rate_median']:.0%} |")
    lines.append(f"| all | {result['clips_total']} | {result['accuracy_top1']:.2f} | {result[f'accuracy_top{top}']:.2f} | "
                 f"{result['detect_rate_median']:.0%} |")
    lines += ["", f"balanced top-1 {result['balanced_top1']:.2f}; body in >= 95 % of frames on "
              f"{result['clips_body_95']}/{result['clips_total']} clips; pose {result['pose_ms_median']:.1f} ms/frame "
              f"(median of {result['pose_frames']} frames), search {result['search_ms_median']:.1f} ms (median), "
              f"one core (cpu {result['pinned_cpu']}); library {result['library_clips']} clips"]
    if result.get("confusion_png"):
        lines.append(f"confusion matrix: {result['confusion_png']}")
    lines += ["", "| clip | label | answer | top | right at | body | rise | hands up | frames @ fps | size |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for c in result["clips"]:
        mark = "" if c["predicted"] == c["label"] else " ✗"
        shows, rank = c.get("shows") or {}, c.get(f"first_right_in_top{DIAGNOSTIC_DEPTH}")
        lines.append(f"| {c['file']} | {c['label']} | {c['predicted']}{mark} | {','.join(h['label'] for h in c['top'])} | "
                     f"{rank or '-'} | {c['detect_rate']:.0%} | {shows.get('rise_L', float('nan')):.2f} L | "
                     f"{shows.get('hands_up', float('nan')):.0%} | {c['frames']} @ {c['fps']:.1f} | "
                     f"{c['image_size'][0]}x{c['image_size'][1]} |")
    return "\n".join(lines)
