"""Stick-figure thumbnails of library clips, so children pick "more like this" by looking.

A thumbnail is a handful of poses sampled across the clip: the canonical body's bones
(:data:`retrieval.motion.body.CANONICAL_PARENTS`) from forward kinematics
(:func:`retrieval.motion.kinematics.positions`), seen from a three-quarter side view, the
figure's travel removed (it stays in its box; its height above the floor is kept so a
jump is seen as a jump). Coordinates are normalised to a unit box, so the UI draws them
with a few Kivy ``Line`` instructions at any size -- no renderer, no image files.

Loading a clip costs tens of milliseconds, so :class:`ThumbnailCache` computes
thumbnails on a background thread and keeps them (the first look at a list shows the
motion icon until the figure is ready).
"""
from __future__ import annotations

import csv
import logging
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.motion import CANONICAL_JOINTS, CANONICAL_PARENTS, Motion, canonical_joint_map, load_motion, positions

log = logging.getLogger(__name__)

#: bones as (parent, child) indices into CANONICAL_JOINTS
BONES: tuple[tuple[int, int], ...] = tuple(
    (CANONICAL_JOINTS.index(parent), CANONICAL_JOINTS.index(child))
    for child, parent in CANONICAL_PARENTS.items() if parent is not None)
HEAD = CANONICAL_JOINTS.index("head")
VIEW_YAW_DEG = 60.0  # 90 = pure side view; a little toward the front shows arms and legs apart


@dataclass(frozen=True)
class StickFrames:
    """``points`` (F, J, 2) in 0..1 (x right, y up), J = the canonical joints."""

    trial: str
    points: np.ndarray

    @property
    def n_frames(self) -> int:
        return len(self.points)


def stick_frames(motion: Motion, n_frames: int = 8, trial: str = "") -> StickFrames:
    """``n_frames`` poses evenly spread over ``motion``, normalised for drawing."""
    if motion.n_frames < 1:
        raise StoryBeamError(f"clip {trial or motion.name!r} has no frames")
    joints = canonical_joint_map(motion.skeleton)
    idx = np.linspace(0, motion.n_frames - 1, n_frames).round().astype(int)
    pos = positions(motion)[idx][:, [joints[name] for name in CANONICAL_JOINTS]]  # (F, J, 3), metres, Y up
    hips = pos[:, CANONICAL_JOINTS.index("hips")]
    pos = pos - np.stack([hips[:, 0], np.zeros(len(hips)), hips[:, 2]], axis=1)[:, None]  # travel removed
    # face the figure along +X at its first frame (from the hips' left->right direction)
    across = pos[0, CANONICAL_JOINTS.index("left_hip")] - pos[0, CANONICAL_JOINTS.index("right_hip")]
    facing = np.arctan2(-across[2], across[0])  # heading of the body's forward direction about Y
    yaw = np.radians(VIEW_YAW_DEG) - facing
    c, s = np.cos(yaw), np.sin(yaw)
    x = pos[..., 0] * c - pos[..., 2] * s
    y = pos[..., 1]
    lo = np.array([x.min(), y.min()])
    span = max(x.max() - lo[0], y.max() - lo[1], 1e-6)
    pts = np.stack([(x - lo[0]) / span, (y - lo[1]) / span], axis=-1)
    pts[..., 0] += (1.0 - (pts[..., 0].max() - pts[..., 0].min())) / 2 - pts[..., 0].min()  # centre horizontally
    return StickFrames(trial or motion.name, pts.astype(np.float32))


def library_files(motions_dir: str | Path) -> dict[str, Path]:
    """Clip id -> motion file, from the library's ``labels.csv`` (empty if unreadable)."""
    motions_dir = Path(motions_dir)
    try:
        with open(motions_dir / "labels.csv", newline="", encoding="utf-8") as fh:
            return {r["trial"].strip(): motions_dir / r["file"].strip() for r in csv.DictReader(fh)
                    if (r.get("trial") or "").strip() and (r.get("file") or "").strip()}
    except (OSError, KeyError, UnicodeDecodeError, csv.Error) as exc:
        log.warning("motion library %s unreadable: %s", motions_dir, exc)
        return {}


def clip_stick_frames(path: str | Path, trial: str, n_frames: int = 8) -> StickFrames:
    """The stick figure of the clip in ``path`` (its library id ``trial``)."""
    return stick_frames(load_motion(path), n_frames, trial)


class ThumbnailCache:
    """Stick figures of library clips, computed on one background thread and kept.

    ``get(trial)`` answers at once: the frames, or None while they are being made (or
    when the clip cannot be read -- then the UI keeps the motion icon)."""

    def __init__(self, motions_dir: str | Path, n_frames: int = 8):
        self.files = library_files(motions_dir)
        self.n_frames = n_frames
        self._done: dict[str, StickFrames | None] = {}
        self._queue: list[tuple[str, Callable | None]] = []
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None

    def get(self, trial: str) -> StickFrames | None:
        return self._done.get(trial)

    def failed(self, trial: str) -> bool:
        return trial in self._done and self._done[trial] is None

    def request(self, trials: list[str], on_ready: Callable[[str, StickFrames], None] | None = None) -> None:
        """Make thumbnails for ``trials`` in the background; ``on_ready(trial, frames)`` is
        called for each one made -- on the background thread, or at once for one already
        made (the UI re-posts it to its own thread either way)."""
        ready = []
        with self._cond:
            for trial in trials:
                if trial not in self._done:
                    self._queue.append((trial, on_ready))
                elif self._done[trial] is not None:
                    ready.append(trial)
            self._cond.notify()
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="storybeam-thumbs", daemon=True)
                self._thread.start()
        for trial in ready:  # made already (between the caller's get() and this call): answer now
            if on_ready is not None:
                on_ready(trial, self._done[trial])

    def wait(self, trials: list[str], timeout: float = 30.0) -> bool:
        """Block until every one of ``trials`` is done (tests, screenshots)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if all(t in self._done for t in trials):
                return True
            time.sleep(0.02)
        return False

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._queue:
                    self._cond.wait()
                trial, on_ready = self._queue.pop(0)
            if trial in self._done:  # asked for twice (a list reopened): answer the later asker too
                if self._done[trial] is not None and on_ready is not None:
                    on_ready(trial, self._done[trial])
                continue
            path = self.files.get(trial)
            try:
                if path is None:
                    raise StoryBeamError(f"clip {trial!r} is not in the library")
                frames = clip_stick_frames(path, trial, self.n_frames)
            except (StoryBeamError, OSError, ValueError) as exc:
                log.info("no thumbnail for %s: %s", trial, exc)
                self._done[trial] = None
                continue
            self._done[trial] = frames
            if on_ready is not None:
                on_ready(trial, frames)
