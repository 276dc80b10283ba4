"""Run a 3-D renderer on its own long-lived thread and hand frames to the UI.

pyrender and Kivy each want an OpenGL context; rendering on the Kivy thread crashes, so
the renderer lives on one worker thread for its whole life (its context is created,
used and destroyed there). The UI asks for frames with :meth:`RenderThread.request`;
only the newest request is kept (a slow renderer skips frames instead of lagging), and
the finished frame is passed to ``deliver(callback, frame)``, which the app sets to a
``Clock.schedule_once`` wrapper so the callback runs on the UI thread.
"""
from __future__ import annotations

import logging
import threading
from typing import Any, Callable

import numpy as np

log = logging.getLogger(__name__)

RenderFn = Callable[[Any, float], np.ndarray]
FrameCallback = Callable[[np.ndarray], None]


class RenderThread:
    """One worker thread that owns the renderer; newest request wins."""

    def __init__(self, make_renderer: Callable[[], RenderFn],
                 deliver: Callable[[FrameCallback, np.ndarray], None]):
        self._make_renderer = make_renderer
        self._deliver = deliver
        self._cond = threading.Condition()
        self._pending: tuple[Any, float, FrameCallback] | None = None
        self._stopped = False
        self.error: str | None = None
        self.frames_rendered = 0
        self._thread = threading.Thread(target=self._run, name="storybeam-render", daemon=True)
        self._thread.start()

    def request(self, scene: Any, t: float, callback: FrameCallback) -> None:
        """Ask for the frame of ``scene`` at time ``t`` (replaces an unserved request)."""
        with self._cond:
            self._pending = (scene, t, callback)
            self._cond.notify()

    def stop(self, timeout: float = 2.0) -> None:
        with self._cond:
            self._stopped = True
            self._cond.notify()
        self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive() and self.error is None

    def _run(self) -> None:
        try:
            render = self._make_renderer()  # the GL context is created on this thread
        except Exception as exc:  # a missing or broken renderer must not take the UI down
            self.error = f"{type(exc).__name__}: {exc}"
            log.warning("3-D renderer unavailable, using the 2-D preview: %s", self.error)
            return
        while True:
            with self._cond:
                while self._pending is None and not self._stopped:
                    self._cond.wait()
                if self._stopped:
                    return
                scene, t, callback = self._pending
                self._pending = None
            try:
                frame = render(scene, t)
            except Exception as exc:
                self.error = f"{type(exc).__name__}: {exc}"
                log.warning("3-D render failed, using the 2-D preview: %s", self.error)
                return
            self.frames_rendered += 1
            self._deliver(callback, frame)
