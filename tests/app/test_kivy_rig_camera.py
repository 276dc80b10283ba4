"""The Kivy camera (Android's camera) as the rig's camera (issue 13, part 3).

A camera choice ``kivy`` / ``kivy:N`` (``storybeam app --camera kivy``, the teacher's
setting, Android's default once the rig is calibrated) makes the app open
:class:`app.ui.kivy_camera.KivyCameraSource` on Kivy's main thread when the projector
screen opens, hand it to the stage's live rig on the render thread (in each
:class:`app.player.app_renderer.StageJob`), and close it when the screen is left.

The app test runs the whole app offscreen in a fresh interpreter with a stand-in Kivy
camera that delivers a recorded handheld rig session (:func:`ar.synthetic.record_rig_session`,
with its calibration files) as RGBA textures on Kivy's clock, as a camera provider does.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from app.player.app_renderer import (DEFAULT_CAMERA, KIVY_CAMERA, app_renderer_factory, check_camera_choice,
                                    default_camera_choice, has_calibration, kivy_camera_index, saved_camera_choice)
from ar.camera_sources import CameraSourceError

REPO = Path(__file__).resolve().parents[2]


def _calibrate(folder: Path) -> None:
    for name in ("camera.json", "projector.json"):
        (folder / name).write_text("{}")  # presence is what the choice looks at; LiveRig validates the content


@pytest.mark.parametrize("text, index", [("kivy", 0), (" KIVY ", 0), ("kivy:2", 2), ("kivy:", None),
                                         ("kivy:x", None), ("0", None), ("kivyx", None), ("", None)])
def test_kivy_camera_index_names_only_the_kivy_camera(text, index):
    assert kivy_camera_index(text) == index
    assert kivy_camera_index(0) is None and kivy_camera_index(None) is None


def test_a_kivy_choice_is_saved_without_opening_anything(tmp_path):
    assert check_camera_choice(" Kivy ") == KIVY_CAMERA
    assert check_camera_choice("kivy:1") == "kivy:1"
    assert check_camera_choice("kivy:0") == KIVY_CAMERA
    with pytest.raises(CameraSourceError, match="no such file or folder"):
        check_camera_choice("kivy:one")  # not a Kivy camera: a file name, and there is none


def test_android_defaults_to_the_kivy_camera_once_calibrated(tmp_path):
    assert default_camera_choice(tmp_path, android=False) == DEFAULT_CAMERA
    assert default_camera_choice(tmp_path, android=True) is None  # not calibrated: the synthetic rig
    (tmp_path / "camera.json").write_text("{}")
    assert not has_calibration(tmp_path) and default_camera_choice(tmp_path, android=True) is None
    _calibrate(tmp_path)
    assert has_calibration(tmp_path) and default_camera_choice(tmp_path, android=True) == KIVY_CAMERA


def test_the_teachers_setting_wins_over_the_default(tmp_path, capsys):
    from app.player.app_renderer import CAMERA_SETTING
    from app.story.storage import ProfileStore

    db = tmp_path / "profile.db"
    assert saved_camera_choice(db, KIVY_CAMERA) == KIVY_CAMERA  # no profile yet
    with ProfileStore(db) as store:
        store.set_setting(CAMERA_SETTING, "kivy:1")
    assert saved_camera_choice(db, None) == "kivy:1"
    with ProfileStore(db) as store:
        store.set_setting(CAMERA_SETTING, str(tmp_path / "gone.mp4"))
    assert saved_camera_choice(db, KIVY_CAMERA) == KIVY_CAMERA
    assert "the saved rig camera cannot be used" in capsys.readouterr().out
    assert app_renderer_factory(tmp_path, camera="kivy").camera == "kivy"


SCRIPT = r"""
import json, shutil, sys, time
from pathlib import Path
from app.ui.env import prepare_kivy_env
prepare_kivy_env(headless=True, width=640, height=400)
import numpy as np
from kivy.clock import Clock
from ar.boards import DEFAULT_BOARD_SPEC, Board
from ar.synthetic import SessionConfig, record_rig_session
from app.player.app_renderer import app_renderer_factory
from app.ui.app import StoryBeamApp

profile = Path(sys.argv[1])
rec = record_rig_session(Board(DEFAULT_BOARD_SPEC), 60, cfg=SessionConfig(supersample=1, seed=3))
written = rec.write(profile / "session")
for name in ("camera.json", "projector.json"):  # the rig is calibrated: the files in the profile folder
    shutil.copy(written["folder"] / name, profile / name)
alpha = np.full(rec.frames[0].shape[:2] + (1,), 255, np.uint8)
textures = [np.ascontiguousarray(np.concatenate([f[..., ::-1], alpha], 2)[::-1]).tobytes() for f in rec.frames]


class Texture:
    def __init__(self, pixels):
        self.size, self.pixels = (640, 480), pixels


class StandInCamera:
    # kivy.core.camera.Camera's surface: bind/unbind on_texture, start/stop, .texture (RGBA, bottom-up)
    def __init__(self, index):
        self.index, self.texture, self.callbacks, self.started, self.shown, self._ev = index, None, [], False, 0, None
        self.main_thread_calls = []

    def bind(self, on_texture):
        self.callbacks.append(on_texture)

    def unbind(self, on_texture):
        self.callbacks.remove(on_texture)

    def start(self):
        import threading
        self.main_thread_calls.append(threading.current_thread() is threading.main_thread())
        self.started = True
        self._ev = Clock.schedule_interval(self._next, 1 / 30)

    def stop(self):
        import threading
        self.main_thread_calls.append(threading.current_thread() is threading.main_thread())
        self.started = False
        self._ev.cancel()

    def _next(self, _dt):  # a new camera frame, delivered on Kivy's main thread as a provider does
        self.texture = Texture(textures[self.shown % len(textures)])
        self.shown += 1
        for cb in list(self.callbacks):
            cb(self)


made = []
app = StoryBeamApp(profile / "profile.db", demo=True, start_screen="projector",
                   renderer_factory=app_renderer_factory(profile, camera="kivy", renderer="kivy-gl"))
app.kivy_camera_factory = lambda index: made.append(StandInCamera(index)) or made[-1]
out = {"phases": []}
state = {"phase": "live1", "t0": time.monotonic(), "live_frames": 0}


def live_frames(screen):
    f = screen.last_stage_frame
    return f is not None and f.live and f.state == "tracking"


def check(_dt):
    screen = app.sm.get_screen("projector")
    phase = state["phase"]
    if time.monotonic() - state["t0"] > 150:
        out["timeout_in"] = phase
        return app.stop()
    if phase in ("live1", "live2"):
        if app.sm.current != "projector" or not live_frames(screen):
            return
        state["live_frames"] += 1
        if state["live_frames"] < 3:  # three checks in a row with live tracked frames
            return
        cam = app.rig_camera
        out["projector_window"] = app.projector_window is not None  # one (offscreen) display: none
        out[phase] = {"cameras_made": len(made), "camera_index": made[-1].index, "started": made[-1].started,
                      "frames_read": cam._index, "shown": made[-1].shown, "source": cam.name,
                      "drawn_by": screen.drawn_by, "frame_live": screen.last_stage_frame.live,
                      "state": screen.last_stage_frame.state}
        state["live_frames"] = 0
        state["phase"] = "left" + phase[-1]
        app.go("editor")
        return
    # leaving the projector screen (its on_leave runs when the screen manager has switched)
    if app.sm.current_screen.name != "editor" or app.sm.transition.is_active:
        return
    out["live" + phase[-1]]["after_leave"] = {"started": made[-1].started, "callbacks": len(made[-1].callbacks),
                                             "rig_camera": app.rig_camera is not None,
                                             "main_thread": list(made[-1].main_thread_calls)}
    if phase == "left1":
        state["phase"] = "live2"
        app.go("projector")  # back again: a new camera, the stage's rig reopened on it
    else:
        app.stop()


Clock.schedule_interval(check, 0.2)
app.run()
out["render_error"] = app.renderer.error if app.renderer is not None else None
print("RESULT " + json.dumps(out))
"""


@pytest.mark.slow  # starts the app in a child process
def test_the_projector_screen_runs_a_live_rig_on_the_kivy_camera_and_releases_it(tmp_path):
    pytest.importorskip("cv2")
    env = {**os.environ, "KIVY_HOME": str(tmp_path / "kivy"), "PYTHONPATH": str(REPO)}
    env.pop("STORYBEAM_PROJECTOR_DISPLAY", None)
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path)], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=240)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stderr[-3000:]
    r = json.loads(lines[-1][len("RESULT "):])
    assert "timeout_in" not in r and r["render_error"] is None, (r, proc.stderr[-3000:])
    assert r["projector_window"] is False  # SDL reports one display: no second window
    for phase, n_made in (("live1", 1), ("live2", 2)):
        live = r[phase]
        # one Kivy camera per visit to the projector screen, opened on the main thread and running
        assert live["cameras_made"] == n_made and live["camera_index"] == 0 and live["started"]
        assert live["source"] == "kivy:0"
        # the stage's live rig read the stand-in's frames and tracked the board in them
        assert live["frame_live"] and live["state"] == "tracking" and live["drawn_by"] == "kivy-gl"
        assert 0 < live["frames_read"] <= live["shown"]
        # leaving the screen released the camera (stopped, unbound), on the main thread
        assert live["after_leave"] == {"started": False, "callbacks": 0, "rig_camera": False,
                                       "main_thread": [True, True]}, (phase, r)


@pytest.mark.parametrize("calibrated, saved, expected", [(True, None, "kivy"), (False, None, "None"),
                                                         (False, "kivy:1", "kivy:1"), (True, "0", "0")])
@pytest.mark.slow  # Kivy in a child process
def test_the_android_entry_point_picks_the_kivy_camera_once_calibrated(tmp_path, calibrated, saved, expected):
    """main.py on the tablet profile (numba, pyrender, OpenGL, ... blocked): the teacher's
    saved camera, else the Kivy camera when the rig is calibrated, else the synthetic rig."""
    private = tmp_path / "private"
    private.mkdir()
    if calibrated:
        _calibrate(private)
    if saved is not None:
        from app.player.app_renderer import CAMERA_SETTING
        from app.story.storage import ProfileStore

        with ProfileStore(private / "profile.db") as store:
            store.set_setting(CAMERA_SETTING, saved)
    code = ("import sys; sys.path.insert(0, 'tests/support'); from tablet_profile import Blocker; "
            "sys.meta_path.insert(0, Blocker()); import main; app = main.make_app(); "
            "print('CAMERA', app.renderer_factory.camera)")
    env = dict(os.environ, SDL_VIDEODRIVER="offscreen", KIVY_NO_ARGS="1", KIVY_HOME=str(tmp_path / "kivy"),
               PYTHONPATH=str(REPO), ANDROID_PRIVATE=str(private))
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120,
                          env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-2:] == ["CAMERA", expected]


FAILING_SCRIPT = r"""
import json, sys, time
from pathlib import Path
from app.ui.env import prepare_kivy_env
prepare_kivy_env(headless=True, width=640, height=400)
from kivy.clock import Clock
from app.player.app_renderer import app_renderer_factory
from app.ui.app import StoryBeamApp

profile = Path(sys.argv[1])
tried = []


class BrokenCamera:  # a provider that fails when started (no such camera, permission refused)
    def bind(self, on_texture):
        pass

    def start(self):
        tried.append(1)
        raise RuntimeError("camera service refused")


app = StoryBeamApp(profile / "profile.db", demo=True, start_screen="projector",
                   renderer_factory=app_renderer_factory(profile, camera="kivy:1", renderer="kivy-gl"))
app.kivy_camera_factory = lambda index: BrokenCamera()
t0 = time.monotonic()
out = {}


def check(_dt):
    frame = app.sm.get_screen("projector").last_stage_frame
    if frame is None and time.monotonic() - t0 < 150:
        return
    out.update(frame=frame is not None and {"live": frame.live, "state": frame.state}, tried=len(tried),
               rig_camera=app.rig_camera is not None, message=getattr(app, "last_message", None),
               notice=getattr(app, "last_notice", None))
    app.stop()


Clock.schedule_interval(check, 0.2)
app.run()
print("RESULT " + json.dumps(out))
"""


@pytest.mark.slow  # starts the app in a child process
def test_a_kivy_camera_that_does_not_open_is_said_once_and_the_show_goes_on(tmp_path):
    _calibrate(tmp_path)
    env = {**os.environ, "KIVY_HOME": str(tmp_path / "kivy"), "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-c", FAILING_SCRIPT, str(tmp_path)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=240)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stderr[-3000:]
    r = json.loads(lines[-1][len("RESULT "):])
    assert r["frame"] and r["frame"]["live"] is False  # the synthetic rig keeps the projector going
    assert r["tried"] == 1 and not r["rig_camera"]  # tried once on entry, not on every refresh
    # said as a picture (a camera, crossed) and one sentence; the reason goes to the log
    assert r["notice"] == "no_camera" and r["message"] and "kivy:1" not in r["message"]
    assert "Traceback" not in proc.stderr


CLOSE_SCRIPT = r"""
import json, threading
from app.ui.env import prepare_kivy_env
prepare_kivy_env(headless=True, width=320, height=240)
from kivy.clock import Clock
from app.ui.kivy_camera import KivyCameraSource

calls = []


class StandIn:
    def bind(self, on_texture):
        pass

    def unbind(self, on_texture):
        calls.append(("unbind", threading.current_thread() is threading.main_thread()))

    def start(self):
        pass

    def stop(self):
        calls.append(("stop", threading.current_thread() is threading.main_thread()))


src = KivyCameraSource(camera=StandIn(), timeout_s=30)
errors = []


def read():
    try:
        src.read()
    except Exception as exc:
        errors.append(str(exc))


reader = threading.Thread(target=read)
reader.start()
closer = threading.Thread(target=src.close)  # as the render thread does when a stage closes
closer.start()
closer.join()
reader.join(5)
before_tick = list(calls)
Clock.tick()
src.close()  # twice: nothing more
print("RESULT " + json.dumps({"before_tick": before_tick, "after_tick": calls, "reader": errors,
                              "reader_done": not reader.is_alive()}))
"""


@pytest.mark.slow  # Kivy in a child process
def test_closing_the_kivy_camera_off_the_main_thread_stops_it_on_the_main_thread(tmp_path):
    env = {**os.environ, "KIVY_HOME": str(tmp_path / "kivy"), "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-c", CLOSE_SCRIPT], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=120)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stderr[-2000:]
    r = json.loads(lines[-1][len("RESULT "):])
    assert r["reader_done"] and r["reader"] == ["camera kivy:0: the camera was closed"]  # woken at once
    assert r["before_tick"] == []  # not stopped from the closing thread ...
    assert r["after_tick"] == [["unbind", True], ["stop", True]]  # ... but on the main thread's next tick
