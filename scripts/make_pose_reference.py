"""Make the stored BlazePose reference for tests/ar/test_body_reference.py (issue 18).

Two steps, in two environments (MediaPipe pins numpy < 2 and brings its own OpenCV, so
it never enters StoryBeam's .venv):

1. ``.venv/bin/python scripts/make_pose_reference.py render [--data /work/shared/data/cmu]``
   renders the short sequences of :data:`SEQUENCES` with pyrender -- a CMU clip retargeted
   onto ``build_character("person")`` or ``"kid"``, in place, facing a level camera in
   front, 640x480, 30 fps (the figures and camera of ``storybeam bench act-it-out``:
   :func:`lab.bench.act_it_out.make_performance` / ``render_frames``) -- and writes the
   frames as JPEG (quality :data:`JPEG_QUALITY`) to ``tests/ar/data/blazepose/``.
2. ``/tmp/mpenv/bin/python scripts/make_pose_reference.py reference`` (an environment with
   only ``pip install mediapipe==0.10.21``) reads those JPEGs back with OpenCV, converts
   them to RGB and runs MediaPipe's *legacy* solution ``mp.solutions.pose.Pose``
   (``model_complexity=1``: the "full" landmark model, the same two .tflite files as
   assets/models/blazepose/) in three modes, one fresh ``Pose`` per sequence and mode:

   * ``static`` -- ``static_image_mode=True``: the detector on every frame, no tracking, no
     smoothing;
   * ``track``  -- ``static_image_mode=False, smooth_landmarks=False``: tracking from the
     previous frame's auxiliary landmarks, the main landmarks unsmoothed;
   * ``smooth`` -- ``static_image_mode=False, smooth_landmarks=True``: video mode as an app
     uses it.

   The legacy solution stamps the k-th processed frame (k = 0, 1, ...) at
   ``(k + 1) * 33333`` microseconds (``solution_base.py``), which the tests pass as
   ``timestamp_s``. Written: ``tests/ar/data/blazepose/reference.npz`` with, per sequence
   ``S`` and mode ``M``: ``S/M/image`` (T, 33, 5: x, y in pixels, z in pixels (MediaPipe's
   z times the image width), visibility, presence; NaN where no pose), ``S/M/world``
   (T, 33, 3, metres; NaN where no pose), ``S/M/valid`` (T,) bool, plus ``S/frames`` (the
   JPEG names in order) and ``meta`` (a JSON string: versions, settings). The legacy
   solution leaves ``presence`` unset: that column is 0.

3. ``OMP_NUM_THREADS=1 taskset -c 1 .venv/bin/python scripts/make_pose_reference.py compare``
   runs StoryBeam's :mod:`ar.body` on the same frames in the three modes and prints, per
   sequence and mode, the frames where both found a pose and the per-landmark agreement
   (max / median, pixels and cm), then the time per frame on one thread: the
   interpreter alone, a tracked frame, a frame that runs the detector (wall clock and
   the thread's CPU time).

4. ``OMP_NUM_THREADS=1 taskset -c 1 /tmp/mpenv/bin/python scripts/make_pose_reference.py
   mediapipe-time`` times MediaPipe's own legacy solution on the person frames, on the
   same core, for comparison: a frame in video mode (tracked) and in static mode
   (detector + landmarks), medians after a warm-up pass.

Only steps 2 and 4 need MediaPipe; step 1 needs the shared CMU data.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "tests" / "ar" / "data" / "blazepose"
JPEG_QUALITY = 90
#: name -> (CMU trial, figure, first frame of the take, number of frames). Consecutive
#: frames at 30 fps, so tracking and smoothing see a real video.
SEQUENCES: dict[str, tuple[str, str, int, int]] = {
    "person_walk": ("02_01", "person", 20, 12),
    "person_jump": ("02_04", "person", 30, 10),
    "kid_walk": ("02_02", "kid", 20, 8),
    "kid_dance": ("05_02", "kid", 40, 8),
}
MODES = {
    "static": {"static_image_mode": True, "smooth_landmarks": False},
    "track": {"static_image_mode": False, "smooth_landmarks": False},
    "smooth": {"static_image_mode": False, "smooth_landmarks": True},
}


def frame_names(name: str) -> list[str]:
    return [f"{name}_{k:02d}.jpg" for k in range(SEQUENCES[name][3])]


def render(data: Path) -> None:
    import cv2

    sys.path.insert(0, str(REPO))
    from lab.bench.act_it_out import make_performance, render_frames
    from retrieval.library import read_labels

    rows = {r.trial: r for r in read_labels(data)}
    OUT.mkdir(parents=True, exist_ok=True)
    for name, (trial, figure, start, n) in SEQUENCES.items():
        perf = make_performance(rows[trial], figure)
        names = frame_names(name)
        for f, bgr in enumerate(render_frames(perf, figure)):
            if f >= start + n:
                break
            if f >= start:
                cv2.imwrite(str(OUT / names[f - start]), bgr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        print(f"{name}: {n} frames of {trial} ({figure}) from frame {start}")


def reference() -> None:
    import cv2
    import mediapipe as mp
    import numpy as np

    out: dict[str, np.ndarray] = {}
    for name in SEQUENCES:
        names = frame_names(name)
        frames = [cv2.cvtColor(cv2.imread(str(OUT / n)), cv2.COLOR_BGR2RGB) for n in names]
        out[f"{name}/frames"] = np.array(names)
        for mode, kw in MODES.items():
            t = len(frames)
            image = np.full((t, 33, 5), np.nan, np.float32)
            world = np.full((t, 33, 3), np.nan, np.float32)
            valid = np.zeros(t, bool)
            with mp.solutions.pose.Pose(model_complexity=1, enable_segmentation=False,
                                        min_detection_confidence=0.5, min_tracking_confidence=0.5, **kw) as pose:
                for k, rgb in enumerate(frames):
                    h, w = rgb.shape[:2]
                    res = pose.process(rgb)
                    if res.pose_landmarks is None:
                        continue
                    valid[k] = True
                    image[k] = [[p.x * w, p.y * h, p.z * w, p.visibility, p.presence]
                                for p in res.pose_landmarks.landmark]
                    world[k] = [[p.x, p.y, p.z] for p in res.pose_world_landmarks.landmark]
            out[f"{name}/{mode}/image"], out[f"{name}/{mode}/world"], out[f"{name}/{mode}/valid"] = image, world, valid
            print(f"{name} {mode}: pose in {int(valid.sum())}/{t} frames")
    meta = {"mediapipe": mp.__version__, "numpy": np.__version__, "opencv": cv2.__version__,
            "solution": "mp.solutions.pose.Pose(model_complexity=1, enable_segmentation=False, "
                        "min_detection_confidence=0.5, min_tracking_confidence=0.5)",
            "modes": MODES, "timestamps_us": "(k + 1) * 33333 for the k-th frame of a sequence",
            "sequences": {k: list(v) for k, v in SEQUENCES.items()}}
    out["meta"] = np.array(json.dumps(meta))
    np.savez_compressed(OUT / "reference.npz", **out)
    print(f"wrote {OUT / 'reference.npz'}")


def compare(repeats: int = 5) -> None:
    import time

    import cv2
    import numpy as np

    sys.path.insert(0, str(REPO))
    from ar.body import BodyTracker

    ref = np.load(OUT / "reference.npz")
    frames = {name: [cv2.imread(str(OUT / n)) for n in frame_names(name)] for name in SEQUENCES}
    print(f"{'sequence':12s} {'mode':7s} both/ours/theirs  px max   px median  cm max   cm median")
    for mode, kw in MODES.items():
        tracker = BodyTracker(smooth=kw["smooth_landmarks"], track=not kw["static_image_mode"])
        for name, imgs in frames.items():
            tracker.reset()
            px, cm, ours = [], [], 0
            theirs = ref[f"{name}/{mode}/valid"]
            for k, img in enumerate(imgs):
                pose = tracker.process(img, (k + 1) * 33333e-6)
                ours += pose is not None
                if pose is not None and theirs[k]:
                    px.append(np.linalg.norm(pose.image_xy - ref[f"{name}/{mode}/image"][k, :, :2], axis=1))
                    cm.append(100 * np.linalg.norm(pose.world - ref[f"{name}/{mode}/world"][k], axis=1))
            px_a, cm_a = np.concatenate(px), np.concatenate(cm)
            print(f"{name:12s} {mode:7s} {len(px):2d}/{ours:2d}/{int(theirs.sum()):2d}        "
                  f"{px_a.max():.2e} {np.median(px_a):.2e}  {cm_a.max():.2e} {np.median(cm_a):.2e}")

    def clock(fn) -> tuple[float, float]:
        w, c = time.perf_counter(), time.thread_time()
        fn()
        return (time.perf_counter() - w) * 1e3, (time.thread_time() - c) * 1e3

    tracker = BodyTracker(smooth=True, num_threads=1)
    x256, x224 = np.zeros((1, 256, 256, 3), np.float32), np.zeros((1, 224, 224, 3), np.float32)
    inv_l = [clock(lambda: tracker.landmarker.run(x256, ("flag",))) for _ in range(10 * repeats)]
    inv_d = [clock(lambda: tracker.detector.run(x224, ("scores",))) for _ in range(10 * repeats)]
    tracked, detected = [], []
    person = [img for name, imgs in frames.items() if name.startswith("person") for img in imgs]
    for rep in range(repeats):
        tracker.reset()
        for k, img in enumerate(person):
            m = clock(lambda: tracker.process(img, rep * 100 + k / 30))
            (detected if tracker.timing.detected else tracked).append(m)

    def med(v, i):
        return float(np.median([x[i] for x in v]))
    print(f"one thread, ms (wall / thread CPU), medians; load average {open('/proc/loadavg').read().split()[:3]}")
    print(f"  interpreter only: detector {med(inv_d, 0):.1f} / {med(inv_d, 1):.1f}, "
          f"landmark model {med(inv_l, 0):.1f} / {med(inv_l, 1):.1f}")
    print(f"  tracked frame {med(tracked, 0):.1f} / {med(tracked, 1):.1f} (n={len(tracked)}); "
          f"frame with detection {med(detected, 0):.1f} / {med(detected, 1):.1f} (n={len(detected)})")


def mediapipe_time(repeats: int = 5) -> None:
    import time

    import cv2
    import mediapipe as mp
    import numpy as np

    frames = [cv2.cvtColor(cv2.imread(str(OUT / n)), cv2.COLOR_BGR2RGB)
              for name in SEQUENCES if name.startswith("person") for n in frame_names(name)]
    for static in (False, True):
        with mp.solutions.pose.Pose(model_complexity=1, static_image_mode=static, smooth_landmarks=not static) as pose:
            ms = []
            for _ in range(repeats):
                for f in frames:
                    t = time.perf_counter()
                    pose.process(f)
                    ms.append((time.perf_counter() - t) * 1e3)
        what = "static (detector + landmarks every frame)" if static else "video (tracked, smoothed)"
        print(f"mediapipe {mp.__version__} legacy Pose, {what}: median {np.median(ms[len(frames):]):.1f} ms")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("step", choices=("render", "reference", "compare", "mediapipe-time"))
    ap.add_argument("--data", type=Path, default=Path("/work/shared/data/cmu"), help="the CMU folder (render)")
    args = ap.parse_args(argv)
    {"render": lambda: render(args.data), "reference": reference, "compare": compare,
     "mediapipe-time": mediapipe_time}[args.step]()


if __name__ == "__main__":
    main()
