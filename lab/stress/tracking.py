"""Lost-tracking stress: long synthetic sequences where the board is covered, leaves the
view, blurs and flickers, fed through the product's frame loop (:meth:`ar.rig.RigTracker.step`:
region detection, pose, :class:`ar.filtering.PoseTracker`).

A *scenario* is a handheld trajectory (:func:`ar.synthetic.handheld_trajectory`) cut into
segments: ``visible`` stretches separated by events — the board fully covered by a hand
(occlusion 1.0), half covered (0.5), panned out of view and back, a burst of motion blur
(a line kernel 15-35 px long), or lighting flicker (exposure jumping between 10 % and
130 % every frame, with a light gradient). Per frame it records what the tracker says
against the known truth and measures:

* **crashes**: any exception from detection, pose or tracker;
* **search paths**: how often the region search found the board, and how often the whole
  frame was searched (:attr:`ar.rig.RigTracker.counts`);
* **wild poses**: a TRACKING output whose frame-to-frame jump exceeds the true motion by
  more than ``jump_mm`` / ``jump_deg`` (a pose that leaps while the rig barely moves),
  or whose error to the truth exceeds ``wild_mm`` / ``wild_deg``;
* **recovery frames**: after each event, how many frames after the board is fully back
  (first clean ``visible`` frame = frame 0) until the tracker reports TRACKING with an
  error under ``recovered_mm`` / ``recovered_deg``. 0 means "on the very frame it
  reappears"; the done criterion is <= 1.

Everything is deterministic for a given seed.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import cv2
import numpy as np
from tqdm import tqdm

from ar.boards import DEFAULT_BOARD_SPEC, Board
from ar.filtering import TRACKING, PoseTracker
from ar.geometry import pose_error, rotation_angle_deg
from ar.rig import RigTracker
from ar.synthetic import (Degradation, PinholeModel, SyntheticCamera, TrajectoryConfig, default_camera,
                          handheld_trajectory)

EVENTS = ("covered", "half_covered", "out_of_view", "blur_burst", "flicker")


@dataclass
class Thresholds:
    jump_mm: float = 20.0  # output jump beyond the true motion, per frame
    jump_deg: float = 5.0
    wild_mm: float = 50.0  # error of a TRACKING pose to the truth
    wild_deg: float = 10.0
    recovered_mm: float = 10.0
    recovered_deg: float = 2.0


@dataclass
class Segment:
    kind: str  # "visible" or one of EVENTS
    start: int
    length: int


def make_schedule(n_frames: int, rng: np.random.Generator, events: tuple[str, ...] = EVENTS) -> list[Segment]:
    """Alternate visible stretches (20-40 frames) and events (4-30 frames), cycling through
    ``events`` so every kind occurs in a long enough sequence."""
    segments: list[Segment] = []
    i, k = 0, 0
    while i < n_frames:
        vis = int(rng.integers(20, 41))
        segments.append(Segment("visible", i, min(vis, n_frames - i)))
        i += vis
        if i >= n_frames - 25:  # leave room to see the recovery after the last event
            if i < n_frames:
                segments.append(Segment("visible", i, n_frames - i))
            break
        kind = events[k % len(events)]
        k += 1
        length = int(rng.integers(18, 31)) if kind == "out_of_view" else int(rng.integers(4, 16))
        segments.append(Segment(kind, i, length))
        i += length
    return segments


def _motion_blur(img: np.ndarray, length: int, angle_deg: float) -> np.ndarray:
    kernel = np.zeros((length, length), np.float32)
    kernel[length // 2, :] = 1.0
    rot = cv2.getRotationMatrix2D((length / 2 - 0.5, length / 2 - 0.5), angle_deg, 1.0)
    kernel = cv2.warpAffine(kernel, rot, (length, length))
    kernel /= max(kernel.sum(), 1e-6)
    return cv2.filter2D(img, -1, kernel)


def _pan_offset(seg: Segment, j: int) -> float:
    """Sideways offset (m) of the board in the camera frame while panning out and back."""
    ramp = max(3, seg.length // 3)
    if j < ramp:
        return 0.6 * (j + 1) / ramp
    if j >= seg.length - ramp:
        return 0.6 * (seg.length - j) / ramp
    return 0.6


@dataclass
class ScenarioResult:
    frames: int = 0
    crashes: int = 0
    wild_poses: int = 0
    max_jump_excess_mm: float = 0.0
    max_jump_excess_deg: float = 0.0
    max_tracking_error_mm: float = 0.0
    max_tracking_error_deg: float = 0.0
    states: dict = field(default_factory=lambda: {"tracking": 0, "holding": 0, "lost": 0})
    recoveries: list = field(default_factory=list)  # (event kind, frames) per event
    never_recovered: int = 0
    crash_examples: list = field(default_factory=list)
    ms_per_frame: float = 0.0
    search_paths: dict = field(default_factory=dict)  # the detector's path counts (region, full, ...)

    def to_dict(self) -> dict:
        d = dict(self.__dict__)
        frames = [r[1] for r in self.recoveries if r[1] is not None]
        d["recovery_frames_max"] = max(frames) if frames else None
        by_kind: dict[str, list[int]] = {}
        for kind, n in self.recoveries:
            by_kind.setdefault(kind, []).append(n if n is not None else -1)
        d["recovery_frames_by_event"] = {k: {"events": len(v), "max": max(v), "mean": round(float(np.mean(v)), 2)}
                                         for k, v in by_kind.items()}
        d.pop("recoveries")
        return d


def run_scenario(n_frames: int, seed: int = 0, camera: PinholeModel | None = None,
                 thresholds: Thresholds | None = None, tracker: PoseTracker | None = None,
                 progress=None) -> ScenarioResult:
    """Run one long sequence (see module docstring); ``tracker``: the rig's filter (default
    the product's); ``progress(n)`` advances a bar."""
    th = thresholds or Thresholds()
    rng = np.random.default_rng(seed)
    board = Board(DEFAULT_BOARD_SPEC)
    cam = SyntheticCamera(board, camera=camera or default_camera(), supersample=1)
    K, dist = cam.camera.K, cam.camera.dist
    cfg = TrajectoryConfig(seed=seed)
    poses = handheld_trajectory(board, n_frames, cfg)
    schedule = make_schedule(n_frames, rng)
    rig = RigTracker(board, K, dist, tracker=tracker)
    res = ScenarioResult()
    prev_out: np.ndarray | None = None
    prev_true: np.ndarray | None = None
    pending: list[tuple[str, int]] = []  # (event kind, frame where the board is fully back)
    t_start = time.perf_counter()
    for s_idx, seg in enumerate(schedule):
        if seg.kind == "visible" and s_idx > 0:
            pending.append((schedule[s_idx - 1].kind, seg.start))
        for j in range(seg.length):
            i = seg.start + j
            T_true = poses[i].copy()
            deg = Degradation()
            blur = None
            if seg.kind == "covered":
                deg = Degradation(occlusion=1.0)
            elif seg.kind == "half_covered":
                deg = Degradation(occlusion=0.5)
            elif seg.kind == "out_of_view":
                T_true[:3, 3] += np.array([_pan_offset(seg, j), 0.0, 0.0])
            elif seg.kind == "blur_burst":
                blur = (int(rng.integers(15, 36)), float(rng.uniform(0, 180)))
            elif seg.kind == "flicker":
                deg = Degradation(exposure=float(rng.choice([0.1, 1.3])) * float(rng.uniform(0.8, 1.2)),
                                  gradient=float(rng.uniform(0, 0.6)), noise_sigma=2.0)
            try:
                frame = cam.render(T_true, degradation=deg, rng=rng)
                if blur is not None:
                    frame = _motion_blur(frame, *blur)
                out = rig.step(frame, i / cfg.fps, i).output
            except Exception as exc:  # noqa: BLE001 - a crash is what this harness counts
                res.crashes += 1
                if len(res.crash_examples) < 5:
                    res.crash_examples.append(f"frame {i} ({seg.kind}): {type(exc).__name__}: {exc}")
                prev_out = None
                continue
            res.frames += 1
            res.states[out.state] += 1
            if out.state == TRACKING:
                err_deg, err_mm = pose_error(out.T_cam_from_board, T_true)
                res.max_tracking_error_mm = max(res.max_tracking_error_mm, err_mm)
                res.max_tracking_error_deg = max(res.max_tracking_error_deg, err_deg)
                wild = err_mm > th.wild_mm or err_deg > th.wild_deg
                if prev_out is not None and prev_true is not None:
                    out_mm = 1000 * np.linalg.norm(out.T_cam_from_board[:3, 3] - prev_out[:3, 3])
                    true_mm = 1000 * np.linalg.norm(T_true[:3, 3] - prev_true[:3, 3])
                    out_deg = rotation_angle_deg(prev_out[:3, :3].T @ out.T_cam_from_board[:3, :3])
                    true_deg = rotation_angle_deg(prev_true[:3, :3].T @ T_true[:3, :3])
                    ex_mm, ex_deg = out_mm - true_mm, out_deg - true_deg
                    res.max_jump_excess_mm = max(res.max_jump_excess_mm, ex_mm)
                    res.max_jump_excess_deg = max(res.max_jump_excess_deg, ex_deg)
                    wild = wild or ex_mm > th.jump_mm or ex_deg > th.jump_deg
                res.wild_poses += wild
                prev_out, prev_true = out.T_cam_from_board, T_true
                for kind, back in list(pending):
                    if err_mm <= th.recovered_mm and err_deg <= th.recovered_deg and i >= back:
                        res.recoveries.append((kind, i - back))
                        pending.remove((kind, back))
            else:
                prev_out = prev_true = None
            if progress is not None:
                progress(1)
    res.never_recovered = len(pending)
    res.recoveries += [(kind, None) for kind, _ in pending]
    res.ms_per_frame = round(1000 * (time.perf_counter() - t_start) / max(1, n_frames), 1)
    res.search_paths = dict(rig.counts)
    return res


def run_tracking_campaign(frames: int = 3000, seed: int = 0, camera: PinholeModel | None = None) -> dict:
    """The `storybeam stress --only tracking` entry: one long sequence, with a progress bar."""
    with tqdm(total=frames, desc="tracking loss", unit="frame") as bar:
        res = run_scenario(frames, seed=seed, camera=camera, progress=bar.update)
    out = res.to_dict()
    out["inputs"] = 0  # frames are not fuzz inputs; reported as "frames"
    out["failures"] = res.wild_poses + res.never_recovered + res.crashes
    out["camera"] = f"{(camera or default_camera()).width}x{(camera or default_camera()).height}"
    out["thresholds"] = Thresholds().__dict__
    return out


def half_resolution_camera() -> PinholeModel:
    """The bench camera at 400x300 (4x fewer pixels: the CI version runs in seconds)."""
    c = default_camera()
    K = c.K.copy()
    K[:2] *= 0.5
    K[0, 2] = (c.K[0, 2] + 0.5) * 0.5 - 0.5
    K[1, 2] = (c.K[1, 2] + 0.5) * 0.5 - 0.5
    return PinholeModel(K, c.dist.copy(), c.width // 2, c.height // 2)


__all__ = ["run_scenario", "run_tracking_campaign", "make_schedule", "Thresholds", "EVENTS",
           "half_resolution_camera", "math"]
