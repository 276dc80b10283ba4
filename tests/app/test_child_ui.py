"""A child who cannot read, in the real app by touch (offscreen, one app per subprocess as
tests/app/test_ui.py): a line drawn before there is anyone to walk it is kept, the notice
is a picture with one spoken sentence, and the next character added takes the line."""
from __future__ import annotations

import pytest

import json
import subprocess
import sys

from app.ui.strings import tr
from tests.app.test_ui import DRIVER, _drive, _env

pytestmark = pytest.mark.slow  # drives the real app in a child process


@pytest.mark.parametrize("lang", ["en", "ja"])
def test_a_line_drawn_before_any_character_is_kept_for_the_next_one(tmp_path, lang):
    r, out = _drive(tmp_path, "stroke_first", lang)
    assert r["cast_before"] == 0 and r["cast_after_stroke"] == 0
    assert r["notice"] == "add_someone" and r["message"] == tr("notice_add_someone", lang)
    assert r["spoken"] == [[r["message"], lang]]
    pending = r["pending"]
    assert len(pending) >= 2 and pending[0][0] == pytest.approx(0.15, abs=0.02)
    assert (out / "stroke_first.png").is_file()
    # the robot added next walks the kept line, saved at once; the dashed line is gone
    path = r["path"]
    assert len(path) >= 2 and r["saved_path"] == path and r["pending_after"] == []
    assert path[0][:2] == pytest.approx([0.15, 0.4], abs=0.02)
    assert path[-1][:2] == pytest.approx([0.79, 0.4], abs=0.02)


@pytest.mark.parametrize("device,lang", [("ja_JP.UTF-8", "ja"), ("en_GB.UTF-8", "en"), ("de_DE.UTF-8", "en")])
def test_the_first_launch_speaks_the_device_language(tmp_path, device, lang):
    env = _env(tmp_path, "device")
    for name in ("LANGUAGE", "LC_ALL", "LC_MESSAGES"):
        env.pop(name, None)
    env["LANG"] = device
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(DRIVER), "first_launch", str(tmp_path / "p.db"), str(out)],
                          env=env, capture_output=True, text=True, timeout=240)
    assert (out / "result.json").is_file(), proc.stderr[-3000:]
    r = json.loads((out / "result.json").read_text())
    assert r["lang"] == lang and r["title"] == tr("my_stories", lang)
