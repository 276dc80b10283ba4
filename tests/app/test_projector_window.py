"""The projector image on its own display (issue 13, part 3): a second process with one
Kivy window, fed the light frames through shared memory, newest frame wins.

The window's process runs offscreen here (no second display on this machine); what it
drew is read back from its own screenshot."""
from __future__ import annotations

import time
from multiprocessing import shared_memory

import cv2
import numpy as np
import pytest

from app.ui.projector_window import (DISPLAY_ENV, HEADER_WORDS, ProjectorWindow, ProjectorWindowError, read_newest,
                                     second_display)

W, H = 320, 240


def _solid(rgb) -> np.ndarray:
    return np.broadcast_to(np.array(rgb, np.uint8), (H, W, 3)).copy()


def _wait(cond, timeout_s=90.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.05)
    return False


def test_the_display_override_names_the_projectors_display(monkeypatch):
    monkeypatch.setenv(DISPLAY_ENV, "1920,0,1280,800")
    assert second_display() == (1920, 0, 1280, 800)
    monkeypatch.setenv(DISPLAY_ENV, "none")
    assert second_display() is None
    monkeypatch.setenv(DISPLAY_ENV, "1920,0,wide")
    with pytest.raises(ProjectorWindowError, match=f"{DISPLAY_ENV}='1920,0,wide': expected x,y,width,height"):
        second_display()
    monkeypatch.setenv(DISPLAY_ENV, "0,0,0,800")
    with pytest.raises(ProjectorWindowError, match="must be positive"):
        second_display()
    monkeypatch.delenv(DISPLAY_ENV)
    assert second_display() is None  # no window (no SDL video) in this process: no second display known


@pytest.mark.slow  # a Kivy window process
def test_the_window_process_exits_cleanly_when_closed_while_its_stdin_watcher_reads():
    """The screen closed (CLOSED in the shared header) while the app's pipe stays open: the
    window's process stops with its stdin watcher still inside a read. A watcher blocked in
    ``sys.stdin.buffer.read()`` holds the buffered reader's lock, and CPython aborts at
    shutdown ("could not acquire lock for <stdin> at interpreter shutdown", exit -6) — what
    happened in 8 of 80 ordinary closes under load, where CLOSED and EOF arrive together."""
    import app.ui.projector_window as pw

    window = ProjectorWindow((0, 0, W, H), max_size=(W, H), headless=True)
    try:
        window.show(_solid((200, 30, 30)))
        assert _wait(lambda: window.shown == 1)
        window._header[pw._CLOSED] = 1  # no EOF: the watcher stays in its read
        window._proc.wait(60)
        assert window._proc.returncode == 0
    finally:
        window.close()


@pytest.mark.slow  # a Kivy window process
def test_the_window_process_shows_the_newest_frame_and_ends_with_the_app(tmp_path):
    shot = tmp_path / "shown.png"
    window = ProjectorWindow((0, 0, W, H), max_size=(W, H), headless=True, screenshot=shot)
    name = window._shm.name
    try:
        colours = [(200, 30, 30), (30, 200, 30), (30, 30, 200), (220, 220, 40), (40, 220, 220)]
        for c in colours:  # back to back: the window may skip some, never shows an older one last
            window.show(_solid(c))
        assert window.sent == 5
        assert _wait(lambda: window.shown == 5), f"the window showed {window.shown} of 5 (alive={window.alive})"
        last = _solid((250, 120, 10))
        last[H // 2:] = (10, 60, 250)  # top half orange, bottom half blue: rows go top down
        window.show(last)
        assert _wait(lambda: window.shown == 6)
        with pytest.raises(ProjectorWindowError, match="larger than the window's 320x240"):
            window.show(np.zeros((H, W + 1, 3), np.uint8))
        with pytest.raises(ProjectorWindowError, match=r"must be \(H, W, 3\) uint8"):
            window.show(np.zeros((H, W), np.uint8))
        assert window.alive
    finally:
        window.close()
    assert not window.alive and window._proc.returncode == 0
    with pytest.raises(FileNotFoundError):
        shared_memory.SharedMemory(name=name)  # freed
    drawn = cv2.imread(str(shot))[..., ::-1]
    assert drawn.shape[:2] == (H, W)
    np.testing.assert_allclose(drawn[H // 2 - 5, W // 2], (250, 120, 10), atol=2)  # the newest frame
    np.testing.assert_allclose(drawn[10, 10], (250, 120, 10), atol=2)  # all of the window, the right way up
    np.testing.assert_allclose(drawn[H - 10, W - 10], (10, 60, 250), atol=2)
    window.close()  # twice: harmless


@pytest.mark.slow  # a Kivy window process
def test_the_window_never_outlives_the_app(tmp_path):
    window = ProjectorWindow((0, 0, W, H), max_size=(W, H), headless=True)
    try:
        window.show(_solid((10, 20, 30)))
        assert _wait(lambda: window.shown == 1)
        window._proc.stdin.close()  # what the app's death does to the pipe
        assert _wait(lambda: not window.alive, 30)
    finally:
        window.close()


def test_the_window_reads_only_whole_frames_newer_than_its_own():
    header = np.zeros(HEADER_WORDS, np.uint64)
    pixels = np.arange(2 * 3 * 3, dtype=np.uint8)
    assert read_newest(header, pixels, 0) is None  # nothing sent yet
    header[:3] = (2, 3, 2)  # frame 1: 3x2, whole
    seq, w, h, frame = read_newest(header, pixels, 0)
    assert (seq, w, h) == (2, 3, 2) and frame.tobytes() == pixels.tobytes()
    assert read_newest(header, pixels, 2) is None  # already shown
    header[0] = 3  # frame 2 being written
    assert read_newest(header, pixels, 2) is None


class _MovingHeader(np.ndarray):
    """A header whose sequence moves on between the window's two looks (the app wrote over the frame)."""

    def __getitem__(self, i):
        value = super().__getitem__(i)
        if i == 0:
            self[0] = int(value) + 2
        return value


def test_the_window_drops_a_frame_written_over_while_it_copied():
    header = np.array([2, 1, 1, 0, 0], np.uint64).view(_MovingHeader)
    assert read_newest(header, np.zeros(3, np.uint8), 0) is None


APP_SCRIPT = r"""
import json, sys, time
from pathlib import Path
from app.ui.env import prepare_kivy_env
prepare_kivy_env(headless=True, width=640, height=400)
from kivy.clock import Clock
from app.player.app_renderer import app_renderer_factory
from app.ui.app import StoryBeamApp

profile = Path(sys.argv[1])
app = StoryBeamApp(profile / "profile.db", demo=True, start_screen="projector",
                   renderer_factory=app_renderer_factory(profile, camera=None, renderer="kivy-gl"))
t0 = time.monotonic()
out = {}
state = {"phase": "showing"}


def check(_dt):
    if time.monotonic() - t0 > 150:
        out["timeout_in"] = state["phase"]
        return app.stop()
    window = app.projector_window
    if state["phase"] == "showing":
        if window is None or window.shown < 3:
            return
        out.update(display=list(window.display), alive=window.alive, shown=window.shown, sent=window.sent,
                   frames_shown_here=app.sm.get_screen("projector").frames_shown)
        state["phase"], state["window"] = "leaving", window
        app.go("editor")
    elif app.sm.current_screen.name == "editor" and not app.sm.transition.is_active:
        old = state["window"]
        out.update(after_leave={"window": app.projector_window is not None, "alive": old.alive,
                                "returncode": old._proc.returncode})
        app.stop()


Clock.schedule_interval(check, 0.2)
app.run()
print("RESULT " + json.dumps(out))
"""


@pytest.mark.slow  # starts the app in a child process
def test_the_projector_screen_opens_a_window_on_the_second_display_and_feeds_it(tmp_path):
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "KIVY_HOME": str(tmp_path / "kivy"), "PYTHONPATH": str(repo), DISPLAY_ENV: "0,0,320,240"}
    proc = subprocess.run([sys.executable, "-c", APP_SCRIPT, str(tmp_path)], cwd=repo, env=env,
                          capture_output=True, text=True, timeout=240)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stderr[-3000:]
    r = json.loads(lines[-1][len("RESULT "):])
    assert "timeout_in" not in r, (r, proc.stderr[-3000:])
    assert r["display"] == [0, 0, 320, 240] and r["alive"]
    assert 3 <= r["shown"] <= r["sent"] <= r["frames_shown_here"]  # the light of the stage frames, newest first
    assert r["after_leave"] == {"window": False, "alive": False, "returncode": 0}  # closed with the screen


def test_sdl_names_the_second_display(monkeypatch):
    import app.ui.projector_window as pw

    class TwoDisplays:  # SDL2's answers on a desktop with a projector right of the screen
        def __init__(self, n):
            self.n = n

        def SDL_GetNumVideoDisplays(self):
            return self.n

        def SDL_GetDisplayBounds(self, index, ref):
            rect = ref._obj
            rect.x, rect.y, rect.w, rect.h = (1920 * index, 0, 1280, 800)
            return 0

    monkeypatch.delenv(DISPLAY_ENV, raising=False)
    monkeypatch.setattr(pw, "_loaded_sdl2", lambda: TwoDisplays(2))
    assert second_display() == (1920, 0, 1280, 800)
    monkeypatch.setattr(pw, "_loaded_sdl2", lambda: TwoDisplays(1))
    assert second_display() is None
