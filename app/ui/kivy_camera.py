"""The Kivy camera (Android's camera, or whatever camera provider Kivy has) as a rig camera source.

:class:`KivyCameraSource` follows :class:`ar.camera_sources.CameraSource` (``ar`` may not
import Kivy, so it lives here): Kivy delivers each camera frame as a texture update on its
main thread; :meth:`KivyCameraSource._on_texture` copies the pixels into a one-frame
mailbox (RGBA bottom-up rows -> BGR top-down, the order OpenCV and the tracker use), and
:meth:`KivyCameraSource.read`, called by :class:`ar.live.LiveTracker`'s grabber thread,
waits for the next new frame. A frame the grabber has not collected when the next one
arrives is replaced (the newest wins) and counted in :attr:`KivyCameraSource.replaced`.

Create and close it on Kivy's main thread (the camera provider's callbacks run there):
for a ``kivy`` / ``kivy:N`` camera choice the app does so when the projector screen opens
and leaves (:meth:`app.ui.app.StoryBeamApp.open_rig_camera`), and the stage's live rig
reads it on the render thread.
"""
from __future__ import annotations

import threading
import time

import numpy as np

from ar.camera_sources import CameraSource, CameraSourceError


class KivyCameraSource(CameraSource):
    """Camera ``index`` through ``kivy.core.camera.Camera`` at ``resolution`` (width, height)."""

    live = True

    def __init__(self, index: int = 0, resolution: tuple[int, int] = (640, 480), timeout_s: float = 5.0,
                 camera=None):
        """``camera``: an already made Kivy ``Camera``-like object (tests); else one is opened."""
        super().__init__(f"kivy:{index}")
        self.timeout_s = timeout_s
        self._cond = threading.Condition()
        self._pending: np.ndarray | None = None
        self._closed = False
        self.replaced = 0
        try:
            if camera is None:
                from kivy.core.camera import Camera as CoreCamera  # deferred: the camera provider loads on first use

                camera = CoreCamera(index=index, resolution=resolution, stopped=True)
            self._camera = camera
            camera.bind(on_texture=self._on_texture)
            camera.start()
        except Exception as exc:  # noqa: BLE001 - every provider fails its own way; one clear error
            raise CameraSourceError(self.name, f"Kivy cannot open this camera ({exc})") from None

    def _on_texture(self, camera, *_args) -> None:
        """On Kivy's main thread: copy the new frame into the mailbox."""
        texture = camera.texture
        if texture is None:
            return
        w, h = texture.size
        rgba = np.frombuffer(texture.pixels, np.uint8)
        if rgba.size != w * h * 4:
            return  # a provider mid-resize; the next frame will do
        bgr = np.ascontiguousarray(rgba.reshape(h, w, 4)[::-1, :, 2::-1])
        with self._cond:
            if self._pending is not None:
                self.replaced += 1
            self._pending = bgr
            self._cond.notify_all()

    def _grab(self) -> np.ndarray | None:
        deadline = time.monotonic() + self.timeout_s
        with self._cond:
            while self._pending is None and not self._closed:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise CameraSourceError(self.name, f"no frame from the camera in {self.timeout_s:g} s")
                self._cond.wait(left)
            if self._closed:
                raise CameraSourceError(self.name, "the camera was closed")
            frame, self._pending = self._pending, None
        return frame

    def close(self) -> None:
        """Stop the camera. Safe from any thread and twice: off Kivy's main thread (the
        rig's threads, the render thread when a stage closes) the reader is woken at once
        and the camera itself is stopped on the main thread's next clock tick."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._pending = None  # an uncollected frame goes with the camera (nothing of a picture is kept)
            self._cond.notify_all()
        if threading.current_thread() is threading.main_thread():
            self._stop_camera()
        else:
            from kivy.clock import Clock  # deferred: Kivy is configured by the app before this runs

            Clock.schedule_once(lambda _dt: self._stop_camera(), 0)  # Kivy's clock takes events from any thread

    def _stop_camera(self) -> None:
        self._camera.unbind(on_texture=self._on_texture)
        self._camera.stop()


__all__ = ["KivyCameraSource"]
