"""The projector screen's full-screen projector mode (issue 13): only the light, taps do
nothing, a finger held down for LONG_PRESS_S leaves it. Runs Kivy offscreen in a fresh
interpreter (Kivy must be configured before it is imported)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # starts the app in a child process

REPO = Path(__file__).resolve().parents[2]

SCRIPT = r"""
import json, time
from app.ui.env import prepare_kivy_env
prepare_kivy_env(headless=True, width=640, height=400)
from kivy.clock import Clock
from kivy.core.window import Window
from kivy.uix.label import Label
from kivy.uix.widget import Widget
from kivy.tests.common import UnitTestTouch
from app.ui.play import ProjectorScreen

screen = ProjectorScreen(name="projector")
screen.controls, screen.state_label = Widget(), Label()
pressed = []
screen.controls.on_touch_down = lambda touch: pressed.append(touch) or True
out = {}

def run_clock(seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        Clock.tick()
        time.sleep(0.01)

run_clock(0.05)  # the clock's time is now (it has not ticked since Kivy was imported)
screen.enter_projector_mode()
out["entered"] = [screen.projector_mode, Window.fullscreen, screen.controls.opacity, screen.controls.disabled,
                  screen.state_label.opacity]
tap = UnitTestTouch(100, 100)
screen.on_touch_down(tap)
run_clock(0.3)
screen.on_touch_up(tap)
run_clock(screen.LONG_PRESS_S + 0.3)
out["after_tap"] = [screen.projector_mode, len(pressed)]
hold = UnitTestTouch(100, 100)
screen.on_touch_down(hold)
run_clock(screen.LONG_PRESS_S + 0.3)
out["after_hold"] = [screen.projector_mode, Window.fullscreen, screen.controls.opacity, screen.controls.disabled]
out["lift_swallowed"] = screen.on_touch_up(hold) is True
print("RESULT " + json.dumps(out))
"""


def test_projector_mode_hides_controls_ignores_taps_and_leaves_on_a_long_press(tmp_path):
    env = {**os.environ, "KIVY_HOME": str(tmp_path / "kivy"), "PYTHONPATH": str(REPO)}
    proc = subprocess.run([sys.executable, "-c", SCRIPT], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=120)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, proc.stderr[-2000:]
    r = json.loads(lines[-1][len("RESULT "):])
    assert r["entered"] == [True, "auto", 0, True, 0]
    assert r["after_tap"] == [True, 0]  # a short tap: still projecting, the controls got nothing
    assert r["after_hold"] == [False, False, 0.85, False]  # held 1 s: back, controls shown
    assert r["lift_swallowed"]  # lifting that finger is not a tap on what is now under it
