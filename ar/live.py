"""Tracking off the UI thread: camera frames in, the newest filtered board pose out.

:class:`LiveTracker` runs two daemon threads over a :class:`ar.camera_sources.CameraSource`:

* the *grabber* reads frames as the source delivers them (a device at its own rate, a
  recording paced at its frame rate) and puts each in a one-frame mailbox. If the
  mailbox still holds a frame the tracker has not taken, that older frame is replaced
  and counted as **dropped**: the newest frame always wins, so the pose never lags
  behind a queue of stale frames;
* the *tracker* takes the newest frame, finds the board
  (:class:`ar.pose.RegionPoseEstimator`: the region the last pose predicts, the whole
  frame when lost), filters the pose (:class:`ar.filtering.PoseTracker`: tracking /
  holding / lost) and publishes a :class:`LiveResult`.

The UI thread only calls :meth:`LiveTracker.latest` (a lock-protected read, never
blocks on OpenCV) or receives ``on_result`` calls from the tracker thread. Bookkeeping:
every frame the grabber read is either processed or dropped
(``captured == processed + dropped + in_mailbox``), which :meth:`LiveTracker.stats` reports.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable

import cv2
import numpy as np

from ar.boards import Board
from ar.camera_sources import CameraFrame, CameraSource, CameraSourceError
from ar.filtering import PoseTracker, TrackerOutput
from ar.pose import PoseEstimate, RegionPoseEstimator


@dataclass
class LiveResult:
    """One processed frame: which one, what the tracker said, and how long it took."""

    frame_index: int
    timestamp_s: float
    output: TrackerOutput
    estimate: PoseEstimate | None
    detect_pose_ms: float  # board detection and pose on this frame
    latency_ms: float  # from the frame's arrival in the mailbox to the published result
    image: np.ndarray | None = None  # the frame itself, when ``keep_images``


@dataclass
class LiveStats:
    """Counts since start: frames read, processed and dropped (replaced unprocessed), board found."""

    captured: int
    processed: int
    dropped: int
    detected: int
    running: bool
    error: str | None


class LiveTracker:
    """Camera source -> board pose -> filter on worker threads; newest frame wins."""

    def __init__(self, source: CameraSource, board: Board, K: np.ndarray, dist: np.ndarray,
                 tracker: PoseTracker | None = None, estimator: RegionPoseEstimator | None = None,
                 on_result: Callable[[LiveResult], None] | None = None, keep_images: bool = False,
                 opencv_threads: int | None = 1):
        """``opencv_threads``: OpenCV's thread count, set when tracking starts (process-wide in
        OpenCV; 1 keeps the other core for the UI and the renderer; ``None`` leaves it as it is)."""
        self.source = source
        self.board = board
        self.estimator = estimator or RegionPoseEstimator(board, K, dist)
        self.tracker = tracker or PoseTracker()
        self.on_result = on_result
        self.keep_images = keep_images
        self.opencv_threads = opencv_threads
        self._lock = threading.Lock()
        self._new_frame = threading.Condition(self._lock)
        self._mailbox: tuple[CameraFrame, float] | None = None
        self._latest: LiveResult | None = None
        self._captured = self._processed = self._dropped = self._detected = 0
        self._source_done = False
        self._stop = threading.Event()
        self._error: str | None = None
        self._threads: list[threading.Thread] = []

    # ------------------------------------------------------------------ control
    def start(self) -> "LiveTracker":
        if self._threads:
            return self
        self._threads = [threading.Thread(target=self._grab_loop, name="rig-grabber", daemon=True),
                         threading.Thread(target=self._track_loop, name="rig-tracker", daemon=True)]
        for t in self._threads:
            t.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop both threads and close the source."""
        self._stop.set()
        with self._lock:
            self._new_frame.notify_all()
        for t in self._threads:
            t.join(timeout_s)
        self.source.close()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait until a recording has been played through and its last frame handled; True if it was."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        for t in self._threads:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            t.join(left)
        return not any(t.is_alive() for t in self._threads)

    def __enter__(self) -> "LiveTracker":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # ------------------------------------------------------------------ reading
    def latest(self) -> LiveResult | None:
        """The newest published result (``None`` before the first); never blocks on tracking."""
        with self._lock:
            return self._latest

    def stats(self) -> LiveStats:
        with self._lock:
            running = any(t.is_alive() for t in self._threads)
            return LiveStats(self._captured, self._processed, self._dropped, self._detected, running, self._error)

    # ------------------------------------------------------------------ threads
    def _grab_loop(self) -> None:
        try:
            while not self._stop.is_set():
                frame = self.source.read()
                if frame is None:
                    break
                with self._lock:
                    self._captured += 1
                    if self._mailbox is not None:
                        self._dropped += 1  # the tracker never saw it: the newer frame wins
                    self._mailbox = (frame, time.perf_counter())
                    self._new_frame.notify()
        except CameraSourceError as exc:
            with self._lock:
                self._error = str(exc)
        finally:
            with self._lock:
                self._source_done = True
                self._new_frame.notify_all()

    def _track_loop(self) -> None:
        if self.opencv_threads is not None:
            cv2.setNumThreads(int(self.opencv_threads))
        while True:
            with self._lock:
                while self._mailbox is None and not self._source_done and not self._stop.is_set():
                    self._new_frame.wait(0.5)
                if self._stop.is_set() or self._mailbox is None:
                    return  # stopped, or the recording ended and its last frame was handled
                frame, arrived = self._mailbox
                self._mailbox = None
            result = self._process(frame, arrived)
            with self._lock:
                self._processed += 1
                self._detected += result.estimate is not None
                self._latest = result
            if self.on_result is not None:
                self.on_result(result)

    def _process(self, frame: CameraFrame, arrived: float) -> LiveResult:
        t0 = time.perf_counter()
        estimate = self.estimator.estimate(frame.image)
        t1 = time.perf_counter()
        output = self.tracker.update(estimate, frame.timestamp_s)
        return LiveResult(frame.index, frame.timestamp_s, output, estimate, (t1 - t0) * 1000,
                          (time.perf_counter() - arrived) * 1000, frame.image if self.keep_images else None)


__all__ = ["LiveResult", "LiveStats", "LiveTracker"]
