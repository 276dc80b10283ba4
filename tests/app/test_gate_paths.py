"""No way into teacher mode without the PIN, from any screen, and a damaged profile that
is never a fresh install (issue 29). By touch, offscreen, in a child process
(tests/support/ui_driver.py with tests/support/gate_scenarios.py)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from app.story.storage import ProfileStore
from lab.stress.gate import KEY_PITCH_OVER_WIDTH, PAD
from tests.app.test_ui import DRIVER, _env


def _run(tmp_path: Path, scenario: str, out_name: str, **env: str) -> dict:
    out = tmp_path / out_name
    proc = subprocess.run([sys.executable, str(DRIVER), scenario, str(tmp_path / "p.db"), str(out)],
                          env={**_env(tmp_path), **env}, capture_output=True, text=True, timeout=240)
    result_file = out / "result.json"
    assert result_file.is_file(), f"driver produced no result (rc {proc.returncode}):\n{proc.stderr[-3000:]}"
    result = json.loads(result_file.read_text())
    assert "error" not in result, result["error"]
    return result


@pytest.mark.slow  # starts the app in a child process
def test_every_path_into_teacher_mode_asks_for_the_pin(tmp_path):
    r = _run(tmp_path, "gate_paths", "out", STORYBEAM_TEST_START="teacher")
    locked = ["pin", False, 0]  # the PIN pad shown, locked, nothing drawn on the teacher screen
    assert r["start"] == locked  # started with the teacher screen asked for
    assert r["direct_teacher"] == locked and r["direct_calibration"] == locked  # screen names set directly
    assert r["go_teacher"] == locked
    assert r["unlocked"][:2] == ["teacher", True] and r["unlocked"][2] > 0  # the PIN opens it
    assert r["presenting"][:2] == ["projector", False]  # Present all leaves teacher mode locked behind it
    assert r["present_back"][:2] == ["pin", False] and r["present_back_mode"] == "enter"  # Back: the PIN again
    assert r["after_pin"][:2] == ["teacher", True]
    assert r["calibration_back"][:2] == ["teacher", True]  # within teacher mode, Back stays in it
    assert r["after_leaving"] == locked  # any other screen locks it
    assert r["after_pause"][:2] == ["pin", False]  # the app sent to the background and back
    assert r["after_home_button"] == locked
    assert r["after_idle"] == ["home", False, 0]  # 10 minutes untouched: locked, home
    assert r["code_shown"] == ["code", 12]
    where, mode, has_code, shown = r["code_left"]  # 2 minutes untouched on the recovery code
    assert where == locked and mode == "enter" and not has_code and shown == ""
    assert r["code_again"] == ["code", 12]  # the PIN first, then a new code
    # the pad the grown-up model of `storybeam stress gate` taps on: its grid and key pitch
    pad = r["pad"]
    for row, keys in enumerate(PAD):
        for col, key in enumerate(keys):
            name = {"c": "clear", "k": "ok"}.get(key, key)
            x, y, w, h = pad[name]
            assert x == pytest.approx(pad["1"][0] + col * (pad["2"][0] - pad["1"][0]), abs=2)
            assert y == pytest.approx(pad["1"][1] - row * (pad["1"][1] - pad["4"][1]), abs=2)
    assert (pad["2"][0] - pad["1"][0]) / pad["1"][2] == pytest.approx(KEY_PITCH_OVER_WIDTH, rel=0.03)


@pytest.mark.slow  # starts the app in a child process, twice
def test_a_damaged_profile_says_so_keeps_the_file_and_puts_back_the_copy_with_its_pin(tmp_path):
    damaged_bytes = None
    first = _run(tmp_path, "gate_damaged", "out1")
    assert first["first"] == "damaged" and first["restore_offered"]
    assert "damaged" in first["sentence"] and "1 stories and the teacher PIN" in first["sentence"]
    assert "p.db.backup" in first["files"]
    assert first["rescue_mode"] == "enter"  # the teacher's PIN, not a first-run check a child could face
    assert first["rescue_unlocked"] == "teacher" and first["rescue_db"].endswith("p.recovered.db")
    damaged_bytes = (tmp_path / "p.db").read_bytes()
    second = _run(tmp_path, "gate_damaged", "out2")
    assert second["first"] == "damaged"  # still there at the next start: nothing was overwritten
    screen, db, has_pin, pin_ok, stories = second["after_restore"]
    assert screen == "home" and db == str(tmp_path / "p.db") and has_pin and pin_ok
    assert sorted(stories) == sorted(["demo-robot-cat", first["meanwhile"]])  # the copy's, and the one made meanwhile
    kept = [n for n in second["files_after"] if n.startswith("p.db.damaged-") and not n.endswith(("-wal", "-shm"))]
    assert len(kept) == 1 and kept[0] in second["message"]
    assert (tmp_path / kept[0]).read_bytes() == damaged_bytes  # the damaged file, kept byte for byte
    with ProfileStore(tmp_path / "p.db") as store:
        assert store.verify_pin("2468") and store.has_story("demo-robot-cat")
