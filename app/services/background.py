"""Work done once on a background thread, with callbacks when it has ended.

The app builds its search indexes (the pose search and groups, the "Act it out" library)
off the UI thread: a subclass implements :meth:`BackgroundLoad._work`, which always ends
the load (``ready``) whatever it raises; :meth:`BackgroundLoad.when_ready` runs a callback
once loading has ended, through :meth:`BackgroundLoad._deliver` (here: on the calling or
loading thread; a UI subclass posts it to its own thread)."""
from __future__ import annotations

import threading
from typing import Callable


class BackgroundLoad:
    """One background load: :meth:`start` (idempotent), ``ready``, :meth:`wait`,
    :meth:`when_ready`."""

    #: The loading thread's name (a subclass names its own).
    thread_name = "storybeam-background-load"

    def __init__(self) -> None:
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._waiting: list[Callable[[], object]] = []
        self._thread: threading.Thread | None = None

    @property
    def ready(self) -> bool:
        """Loading has ended (well or not)."""
        return self._done.is_set()

    def start(self) -> None:
        """Start loading, once."""
        with self._lock:
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self.thread_name, daemon=True)
                self._thread.start()

    def wait(self, timeout: float | None = None) -> bool:
        """Start loading if need be and wait for its end; False when ``timeout`` ran out."""
        self.start()
        return self._done.wait(timeout)

    def when_ready(self, callback: Callable[[], object]) -> None:
        """Run ``callback`` once loading has ended (at once if it has)."""
        self.start()
        with self._lock:
            if not self._done.is_set():
                self._waiting.append(callback)
                return
        self._deliver(callback)

    def _deliver(self, callback: Callable[[], object]) -> None:
        """Run one waiting callback (a UI subclass moves it onto its own thread)."""
        callback()

    def _work(self) -> None:
        """The load itself, on the background thread (a subclass's)."""
        raise NotImplementedError

    def _run(self) -> None:
        try:
            self._work()
        finally:
            with self._lock:
                self._done.set()
                waiting, self._waiting = self._waiting, []
            for cb in waiting:
                self._deliver(cb)


__all__ = ["BackgroundLoad"]
