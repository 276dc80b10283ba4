"""The projector image on its own display: a second process with one Kivy window.

Kivy opens one window per process, so on a desktop with two displays the projector's
light is shown by a child process (``python -m app.ui.projector_window``) whose only
window, borderless, covers the second display; the app keeps its own window on the first.

The light frames travel through one block of shared memory
(:class:`multiprocessing.shared_memory.SharedMemory`), newest frame wins, no copies
through pipes. Layout: a header of four uint64 -- ``seq`` (a sequence lock: odd while
the app writes a frame, even when it is whole), ``width``, ``height``, ``closed`` -- and
``shown`` (the ``seq`` the window last put on screen), then room for one RGB frame of up
to ``max_size``. The app (:class:`ProjectorWindow`, the only writer) bumps ``seq`` to odd,
writes the size and the pixels, bumps it to even; the window polls at 60 Hz, copies the
frame when ``seq`` is even and newer than what it shows, and keeps the copy only if
``seq`` did not move meanwhile (else it takes the next whole one on its next poll): a
torn frame is never shown, and the app never waits for the window.

The window's process ends when the app sets ``closed`` or when the app's end of its
stdin pipe closes (the app died): it never outlives the app.

Displays: :func:`second_display` asks SDL2 (the library Kivy's window runs on) for the
displays' bounds; ``STORYBEAM_PROJECTOR_DISPLAY=x,y,w,h`` names the projector's display
instead (tests, or a desktop SDL does not report), ``none`` turns the second window off.
"""
from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

from app.paths import REPO_ROOT
from retrieval.errors import StoryBeamError

#: the environment override of the projector's display: ``x,y,w,h`` or ``none``
DISPLAY_ENV = "STORYBEAM_PROJECTOR_DISPLAY"
HEADER_WORDS = 5  # seq, width, height, closed, shown
_SEQ, _W, _H, _CLOSED, _SHOWN = range(HEADER_WORDS)
HEADER_BYTES = 8 * HEADER_WORDS
POLL_HZ = 60.0

Rect = tuple[int, int, int, int]


class ProjectorWindowError(StoryBeamError):
    """The projector window cannot be started or fed."""


# ---------------------------------------------------------------------------- displays
def _parse_rect(text: str) -> Rect:
    try:
        x, y, w, h = (int(v) for v in text.split(","))
    except ValueError:
        raise ProjectorWindowError(f"{DISPLAY_ENV}={text!r}: expected x,y,width,height or none") from None
    if w < 1 or h < 1:
        raise ProjectorWindowError(f"{DISPLAY_ENV}={text!r}: width and height must be positive")
    return x, y, w, h


def _loaded_sdl2() -> ctypes.CDLL | None:
    """The SDL2 library this process already runs Kivy's window on (Linux: from
    /proc/self/maps; elsewhere the system's), or None."""
    path = None
    try:
        with open("/proc/self/maps") as fh:
            for line in fh:
                name = line.rsplit(None, 1)[-1]
                if "/libSDL2-" in name or name.endswith("/libSDL2.so") or "/libSDL2-2.0.so" in name:
                    path = name
                    break
    except OSError:
        pass
    path = path or ctypes.util.find_library("SDL2")
    if path is None:
        return None
    try:
        return ctypes.CDLL(path)
    except OSError:
        return None


class _SDLRect(ctypes.Structure):
    _fields_ = [("x", ctypes.c_int), ("y", ctypes.c_int), ("w", ctypes.c_int), ("h", ctypes.c_int)]


def second_display() -> Rect | None:
    """The projector's display as ``(x, y, width, height)`` in desktop coordinates: the
    :data:`DISPLAY_ENV` override, else SDL's second display (``SDL_GetDisplayBounds(1)``)
    when SDL reports two or more; None with one display (a tablet: use full-screen
    projector mode) or when SDL cannot be asked. Call after Kivy's window exists."""
    env = os.environ.get(DISPLAY_ENV, "").strip()
    if env:
        return None if env.lower() == "none" else _parse_rect(env)
    sdl = _loaded_sdl2()
    if sdl is None:
        return None
    try:
        if sdl.SDL_GetNumVideoDisplays() < 2:
            return None
        rect = _SDLRect()
        if sdl.SDL_GetDisplayBounds(1, ctypes.byref(rect)) != 0:
            return None
    except AttributeError:
        return None
    return rect.x, rect.y, rect.w, rect.h


# ---------------------------------------------------------------------------- the app's side
class ProjectorWindow:
    """The app's handle on the projector window: starts the window's process on
    ``display`` and feeds it (:meth:`show`); :meth:`close` ends it."""

    def __init__(self, display: Rect, max_size: tuple[int, int] = (1920, 1200), headless: bool = False,
                 screenshot: Path | None = None):
        """``max_size``: the largest light image (width, height) :meth:`show` takes;
        ``headless``: the window's process draws offscreen (tests); ``screenshot``: it
        saves what it drew there after each new frame, before it counts it as shown (tests)."""
        self.display = display
        self.max_size = max_size
        w, h = max_size
        # deferred: _posixshmem needs shm_open, which Android's libc lacks (the tablet never gets here)
        from multiprocessing import shared_memory
        try:
            self._shm = shared_memory.SharedMemory(create=True, size=HEADER_BYTES + w * h * 3)
        except OSError as exc:
            raise ProjectorWindowError(f"no shared memory for the projector window ({exc})") from None
        self._header = np.ndarray((HEADER_WORDS,), np.uint64, self._shm.buf[:HEADER_BYTES])
        self._header[:] = 0
        self._pixels = np.ndarray((w * h * 3,), np.uint8, self._shm.buf[HEADER_BYTES:])
        cmd = [sys.executable, "-m", "app.ui.projector_window", "--shm", self._shm.name,
               "--rect", ",".join(str(v) for v in display)]
        if headless:
            cmd.append("--headless")
        if screenshot is not None:
            cmd += ["--screenshot", str(screenshot)]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(
            [str(REPO_ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p])}
        try:
            self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, env=env)
        except OSError as exc:
            self._release()
            raise ProjectorWindowError(f"cannot start the projector window ({exc})") from None

    @property
    def alive(self) -> bool:
        return self._proc.poll() is None

    @property
    def sent(self) -> int:
        """Frames handed to the window so far."""
        return int(self._header[_SEQ]) // 2

    @property
    def shown(self) -> int:
        """The number of the newest frame the window has put on screen (0: none yet)."""
        return int(self._header[_SHOWN]) // 2

    def show(self, rgb: np.ndarray) -> None:
        """Hand the window the newest light image (H, W, 3 uint8, rows top down); returns at once."""
        rgb = np.asarray(rgb)
        h, w = rgb.shape[:2]
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ProjectorWindowError(f"a light image must be (H, W, 3) uint8, got {rgb.shape} {rgb.dtype}")
        if w > self.max_size[0] or h > self.max_size[1]:
            raise ProjectorWindowError(f"light image {w}x{h} larger than the window's {self.max_size[0]}x"
                                       f"{self.max_size[1]}")
        seq = int(self._header[_SEQ])
        self._header[_SEQ] = seq + 1  # odd: being written
        self._header[_W], self._header[_H] = w, h
        self._pixels[:w * h * 3] = rgb.reshape(-1)
        self._header[_SEQ] = seq + 2  # even: whole

    def close(self, timeout_s: float = 5.0) -> None:
        """End the window's process and free the shared memory (safe to call twice)."""
        if self._shm is None:
            return
        self._header[_CLOSED] = 1
        try:
            self._proc.stdin.close()
        except OSError:
            pass
        try:
            self._proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        self._release()

    def _release(self) -> None:
        self._header = self._pixels = None
        self._shm.close()
        self._shm.unlink()
        self._shm = None


# ---------------------------------------------------------------------------- the window's process
def read_newest(header: np.ndarray, pixels: np.ndarray, last_seq: int) -> tuple[int, int, int, np.ndarray] | None:
    """The window's read of the shared frame: ``(seq, width, height, RGB bytes)`` of a
    whole frame newer than ``last_seq``, or None (nothing new, a frame being written, or
    one written over while it was copied: the next poll takes the next whole one)."""
    seq = int(header[_SEQ])
    if seq % 2 or seq <= last_seq:
        return None
    w, h = int(header[_W]), int(header[_H])
    frame = pixels[:w * h * 3].copy()
    if int(header[_SEQ]) != seq:
        return None
    return seq, w, h, frame


def _window_main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="StoryBeam's projector window (started by the app)")
    p.add_argument("--shm", required=True)
    p.add_argument("--rect", required=True)
    p.add_argument("--headless", action="store_true")
    p.add_argument("--screenshot")
    args = p.parse_args(argv)
    x, y, w, h = _parse_rect(args.rect)

    from app.ui.env import prepare_kivy_env  # deferred: Kivy is configured before it is imported
    prepare_kivy_env(headless=args.headless, width=w, height=h)
    from kivy.config import Config  # deferred: after prepare_kivy_env()
    Config.set("graphics", "position", "custom")
    Config.set("graphics", "left", str(x))
    Config.set("graphics", "top", str(y))
    Config.set("graphics", "borderless", "1")
    from kivy.app import App  # deferred: as above
    from kivy.clock import Clock  # deferred: as above
    from kivy.core.window import Window  # deferred: as above (opens the window)
    from kivy.graphics.texture import Texture  # deferred: as above
    from kivy.uix.image import Image  # deferred: as above

    from multiprocessing import resource_tracker, shared_memory  # deferred: as in ProjectorWindow

    shm = shared_memory.SharedMemory(name=args.shm)
    resource_tracker.unregister(shm._name, "shared_memory")  # the app owns (and unlinks) it
    header = np.ndarray((HEADER_WORDS,), np.uint64, shm.buf[:HEADER_BYTES])
    pixels = np.ndarray((shm.size - HEADER_BYTES,), np.uint8, shm.buf[HEADER_BYTES:])
    parent_gone = threading.Event()

    def watch_stdin() -> None:  # EOF: the app closed us, or died
        # os.read on the descriptor, not sys.stdin.buffer.read(): a daemon thread inside the
        # buffered reader holds its lock, and if the interpreter shuts down at that moment
        # (the app closed the screen: CLOSED and EOF arrive together) CPython aborts
        # ("could not acquire lock for <stdin> at interpreter shutdown"), exit status -6
        try:
            fd = sys.stdin.fileno()
            while os.read(fd, 1 << 16):
                pass
        except (OSError, ValueError):
            pass
        finally:
            parent_gone.set()
    threading.Thread(target=watch_stdin, daemon=True).start()

    class ProjectorWindowApp(App):
        title = "StoryBeam projector"

        def build(self):
            Window.clearcolor = (0, 0, 0, 1)
            self.image = Image(fit_mode="contain")
            self.texture = None
            self.last_seq = 0
            Clock.schedule_interval(self.poll, 1 / POLL_HZ)
            return self.image

        def poll(self, _dt) -> None:
            if header[_CLOSED] or parent_gone.is_set():
                self.stop()
                return
            newest = read_newest(header, pixels, self.last_seq)
            if newest is None:
                return
            seq, fw, fh, frame = newest
            if self.texture is None or tuple(self.texture.size) != (fw, fh):
                self.texture = Texture.create(size=(fw, fh), colorfmt="rgb")
                self.texture.flip_vertical()  # rows arrive top down
                self.image.texture = self.texture
            self.texture.blit_buffer(frame.tobytes(), colorfmt="rgb", bufferfmt="ubyte")
            self.image.canvas.ask_update()
            self.last_seq = seq
            if args.screenshot:  # tests: what the window drew, read back
                self.save_screenshot(args.screenshot)
            header[_SHOWN] = seq

        def save_screenshot(self, path: str) -> None:
            with tempfile.TemporaryDirectory() as tmp:  # Window.screenshot numbers its file: made here, moved
                Window.dispatch("on_draw")
                written = Window.screenshot(name=os.path.join(tmp, "frame.png"))
                os.replace(written, path)

    try:
        ProjectorWindowApp().run()
    finally:
        header = pixels = None  # the views into the block go before the block (else BufferError)
        shm.close()
    return 0


__all__ = ["ProjectorWindow", "ProjectorWindowError", "second_display", "DISPLAY_ENV"]

if __name__ == "__main__":
    sys.exit(_window_main())
