"""Tracking off the UI thread: camera frames in, the newest tracked rig state out.

:class:`LiveTracker` runs two daemon threads over a :class:`ar.camera_sources.CameraSource`:

* the *grabber* reads frames as the source delivers them (a device at its own rate, a
  recording paced at its frame rate) and puts each in a one-frame mailbox. If the
  mailbox still holds a frame the tracker has not taken, that older frame is replaced
  and counted as **dropped**: the newest frame always wins, so the pose never lags
  behind a queue of stale frames;
* the *tracker* takes the newest frame and steps the rig's frame loop on it
  (:meth:`ar.rig.RigTracker.step`: region detection, pose, filter -- tracking / holding /
  lost on the frame's own timestamp -- and the projector pose) and publishes the
  :class:`ar.rig.RigState`, with the latency from the frame's arrival.

The UI thread only calls :meth:`LiveTracker.latest` (a lock-protected read, never
blocks on OpenCV) or receives ``on_result`` calls from the tracker thread. Bookkeeping:
every frame the grabber read is either processed or dropped
(``captured == processed + dropped + in_mailbox``), which :meth:`LiveTracker.stats` reports.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import cv2

from ar.camera_sources import CameraFrame, CameraSource, CameraSourceError

if TYPE_CHECKING:  # ar.rig imports this module (its live rig runs on these threads)
    from ar.rig import ProjectedLight, RigState, RigTracker


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
    """Camera source -> the rig's frame loop on worker threads; newest frame wins."""

    def __init__(self, source: CameraSource, rig: RigTracker,
                 on_result: Callable[[RigState], None] | None = None, keep_images: bool = False,
                 opencv_threads: int | None = 1):
        """``rig``: the frame loop to step (:class:`ar.rig.RigTracker`); ``opencv_threads``:
        OpenCV's thread count, set when tracking starts (process-wide in OpenCV; 1 keeps the
        other core for the UI and the renderer; ``None`` leaves it as it is)."""
        self.source = source
        self.rig = rig
        #: what the projector shows now (:class:`ar.rig.ProjectedLight`), set by the UI side
        self.light: ProjectedLight | None = None
        self.on_result = on_result
        self.keep_images = keep_images
        self.opencv_threads = opencv_threads
        self._lock = threading.Lock()
        self._new_frame = threading.Condition(self._lock)
        self._mailbox: tuple[CameraFrame, float] | None = None
        self._latest: RigState | None = None
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
    def latest(self) -> RigState | None:
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

    def _process(self, frame: CameraFrame, arrived: float) -> RigState:
        state = self.rig.step(frame.image, frame.timestamp_s, frame.index, self.light)
        state.latency_ms = (time.perf_counter() - arrived) * 1000
        state.image = frame.image if self.keep_images else None
        return state


__all__ = ["LiveStats", "LiveTracker"]
