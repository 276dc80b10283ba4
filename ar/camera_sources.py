"""Where the rig's camera frames come from: one interface over a device, a video, a folder.

A :class:`CameraSource` hands out BGR uint8 frames one at a time (:meth:`CameraSource.read`
returns a :class:`CameraFrame`, or ``None`` when a recording has ended). The sources:

* :class:`OpenCVDeviceSource` -- a camera OpenCV can open by index (V4L2 on Linux, the
  desktop's webcam or a USB camera on the rig);
* :class:`VideoFileSource` -- a recorded rig session (``.mp4``, ``.avi``, ...);
* :class:`ImageFolderSource` -- a folder of numbered images (``.png``, ``.jpg``), read in
  name order (``frame_00000.png`` ...);
* :class:`FrameListSource` -- frames already in memory (the synthetic rig, tests).

The Kivy camera (Android) cannot live here (``ar`` never imports Kivy): it is in
:mod:`app.ui` and follows the same interface.

A recording can be *paced* (``paced=True``): :meth:`read` then waits until the frame's
time on the recording's clock (frame ``i`` at ``i / fps`` after the first read), as a
camera would deliver it, so a slow consumer falls behind and has to drop frames exactly
as it would with a live camera. Unpaced, frames come as fast as they are read.

:func:`open_camera_source` turns the ``--camera`` text into a source: an integer is a
device index, a folder is an image folder, a file is a video; anything else raises
:class:`CameraSourceError` naming the source and the problem.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from retrieval.errors import StoryBeamError

#: image files an :class:`ImageFolderSource` reads, in name order
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
#: files a :class:`VideoFileSource` accepts
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm")


class CameraSourceError(StoryBeamError):
    """A camera source cannot be opened or read; the message names the source."""

    def __init__(self, source: str, problem: str):
        self.source = source
        self.problem = problem
        super().__init__(f"camera {source}: {problem}")


@dataclass
class CameraFrame:
    """One frame: ``image`` BGR uint8 (H, W, 3), its number in the stream, and when it was taken
    (seconds on the source's clock: the device's arrival time, or ``index / fps`` of a recording)."""

    image: np.ndarray
    index: int
    timestamp_s: float


class CameraSource:
    """Base of every camera source; subclasses implement :meth:`_grab`."""

    #: frames per second of a recording (``None``: a device, timed by arrival)
    fps: float | None = None
    #: a live camera (frames are dropped by the camera when not read in time)
    live: bool = False

    def __init__(self, name: str, paced: bool = False, loop: bool = False):
        self.name = name
        self.paced = paced
        self.loop = loop
        self._index = 0
        self._t0: float | None = None

    def read(self) -> CameraFrame | None:
        """The next frame, or ``None`` when a recording has ended (never for a device)."""
        image = self._grab()
        if image is None and self.loop and self._index > 0:
            self._rewind()
            image = self._grab()
        if image is None:
            return None
        i = self._index
        self._index += 1
        now = time.monotonic()
        if self._t0 is None:
            self._t0 = now
        if self.fps is None:
            stamp = now - self._t0
        else:
            stamp = i / self.fps
            if self.paced:
                wait = self._t0 + stamp - now
                if wait > 0:
                    time.sleep(wait)
        return CameraFrame(image, i, stamp)

    def _grab(self) -> np.ndarray | None:
        raise NotImplementedError

    def _rewind(self) -> None:
        raise CameraSourceError(self.name, "cannot loop")

    def close(self) -> None:
        """Release the device or file (safe to call twice)."""

    def __enter__(self) -> "CameraSource":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


def _as_bgr(image: np.ndarray, name: str) -> np.ndarray:
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.ndim == 3 and image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise CameraSourceError(name, f"frame of shape {image.shape} and type {image.dtype} is not a BGR image")
    return image


class OpenCVDeviceSource(CameraSource):
    """Camera ``index`` through ``cv2.VideoCapture``; ``size`` asks the driver for a resolution."""

    live = True

    def __init__(self, index: int, size: tuple[int, int] | None = None):
        super().__init__(str(index))
        self._cap = cv2.VideoCapture(int(index))
        if not self._cap.isOpened():
            self._cap.release()
            raise CameraSourceError(self.name, "no camera with this number can be opened")
        if size is not None:
            self._cap.set(cv2.CAP_PROP_FRAME_WIDTH, size[0])
            self._cap.set(cv2.CAP_PROP_FRAME_HEIGHT, size[1])
        self._cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # the newest frame, not a queue of old ones

    def _grab(self) -> np.ndarray | None:
        ok, frame = self._cap.read()
        if not ok or frame is None:
            raise CameraSourceError(self.name, "the camera stopped sending frames")
        return _as_bgr(frame, self.name)

    def close(self) -> None:
        self._cap.release()


class VideoFileSource(CameraSource):
    """A video file, frame by frame at its own frame rate (``fps`` overrides a missing one)."""

    def __init__(self, path: str | Path, paced: bool = False, loop: bool = False, fps: float | None = None):
        path = Path(path)
        super().__init__(str(path), paced, loop)
        if not path.is_file():
            raise CameraSourceError(self.name, "no such video file")
        self._cap = cv2.VideoCapture(str(path))
        if not self._cap.isOpened():
            self._cap.release()
            raise CameraSourceError(self.name, "not a video OpenCV can read")
        rate = float(self._cap.get(cv2.CAP_PROP_FPS) or 0.0)
        self.fps = fps or (rate if np.isfinite(rate) and 1.0 <= rate <= 1000.0 else 30.0)
        self.frame_count = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)

    def _grab(self) -> np.ndarray | None:
        ok, frame = self._cap.read()
        return _as_bgr(frame, self.name) if ok and frame is not None else None

    def _rewind(self) -> None:
        self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)

    def close(self) -> None:
        self._cap.release()


class ImageFolderSource(CameraSource):
    """The images of a folder in name order, as a recording at ``fps``."""

    def __init__(self, folder: str | Path, fps: float = 30.0, paced: bool = False, loop: bool = False):
        folder = Path(folder)
        super().__init__(str(folder), paced, loop)
        if not folder.is_dir():
            raise CameraSourceError(self.name, "no such folder")
        self.files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
        if not self.files:
            raise CameraSourceError(self.name, f"no images ({', '.join(IMAGE_SUFFIXES)}) in this folder")
        if not (0 < fps <= 1000):
            raise CameraSourceError(self.name, f"frame rate {fps} must be between 0 and 1000")
        self.fps = float(fps)
        self._next = 0

    def _grab(self) -> np.ndarray | None:
        if self._next >= len(self.files):
            return None
        path = self.files[self._next]
        self._next += 1
        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if image is None:
            raise CameraSourceError(self.name, f"{path.name} is not an image OpenCV can read")
        return image

    def _rewind(self) -> None:
        self._next = 0


class FrameListSource(CameraSource):
    """Frames held in memory (BGR uint8), as a recording at ``fps``."""

    def __init__(self, frames, fps: float = 30.0, paced: bool = False, loop: bool = False, name: str = "<frames>"):
        super().__init__(name, paced, loop)
        self.frames = list(frames)
        self.fps = float(fps)
        self._next = 0

    def _grab(self) -> np.ndarray | None:
        if self._next >= len(self.frames):
            return None
        self._next += 1
        return _as_bgr(np.asarray(self.frames[self._next - 1]), self.name)

    def _rewind(self) -> None:
        self._next = 0


def open_camera_source(spec: str | int | Path, paced: bool = True, loop: bool = False,
                       fps: float | None = None) -> CameraSource:
    """``0`` / ``"1"``: a device; a folder: its images; a file: a video. Recordings are paced by default
    (they stand in for a camera); ``fps`` sets a folder's rate (default 30) or overrides a video's."""
    text = str(spec).strip()
    if not text:
        raise CameraSourceError("''", "empty camera source (expected a number, a video file or a folder)")
    if text.isdigit():
        return OpenCVDeviceSource(int(text))
    path = Path(text).expanduser()
    if path.is_dir():
        return ImageFolderSource(path, fps=fps or 30.0, paced=paced, loop=loop)
    if path.is_file():
        if path.suffix.lower() not in VIDEO_SUFFIXES:
            raise CameraSourceError(text, f"not a video file (expected one of {', '.join(VIDEO_SUFFIXES)}) "
                                          "or a folder of images")
        return VideoFileSource(path, paced=paced, loop=loop, fps=fps)
    raise CameraSourceError(text, "no such file or folder (a camera is given by its number, e.g. 0)")


__all__ = ["CameraSourceError", "CameraFrame", "CameraSource", "OpenCVDeviceSource", "VideoFileSource",
           "ImageFolderSource", "FrameListSource", "open_camera_source", "IMAGE_SUFFIXES", "VIDEO_SUFFIXES"]
