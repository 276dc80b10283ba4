"""Issue 29 in the real app (offscreen, driven by touches in a child process): Play's
ending and controls, saving the story film from Play into the videos folder, the
teacher's switch, naming a story by picture, the bin and its way back."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
from PIL import Image

pytestmark = pytest.mark.slow  # drives the real app in a child process and exports a (small) film

REPO = Path(__file__).resolve().parents[2]
DRIVER = REPO / "tests" / "support" / "ui_driver.py"


def test_the_end_of_a_story_and_managing_stories(tmp_path):
    pytest.importorskip("pyrender")
    videos = tmp_path / "home" / "Videos"
    videos.mkdir(parents=True)
    env = dict(os.environ, SDL_VIDEODRIVER="offscreen", KIVY_NO_ARGS="1", KIVY_HOME=str(tmp_path / "kivy"),
               STORYBEAM_TEST_LANG="en", PYTHONPATH=str(REPO), HOME=str(tmp_path / "home"),
               XDG_VIDEOS_DIR=str(videos))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(DRIVER), "story_end", str(tmp_path / "p.db"), str(out)],
                          env=env, capture_output=True, text=True, timeout=600)
    result_file = out / "result.json"
    assert result_file.is_file(), f"driver produced no result (rc {proc.returncode}):\n{proc.stderr[-3000:]}"
    r = json.loads(result_file.read_text())
    assert "error" not in r, r["error"]
    # the Play/Pause button shows what a tap does, at every moment
    assert r["icon_start"] == "play" and r["icon_playing"] == "pause" and r["text_playing"] == "Pause"
    assert r["icon_end"] == "play" and r["text_end"] == "Play"
    assert r["icon_replay"] == "pause" and r["end_gone"] and r["icon_paused"] == "play"
    # the celebration: the chime was played, confetti drawn over the table
    assert len(r["sounds"]) == 1 and r["sounds"][0].endswith(".wav")
    shot = np.asarray(Image.open(out / "celebration.png").convert("RGB")).astype(int)
    confetti = np.all(np.abs(shot - [255, 202, 58]) < 12, axis=-1) | np.all(np.abs(shot - [25, 130, 196]) < 12, axis=-1)
    assert confetti.sum() > 200
    # saving: offered, progress shown, the film in the videos folder, a tick for the child
    assert r["save_offered"] and r["progress_seen"][0] > 0
    assert r["busy_after_close"] and r["exports_started"] == 1  # back while saving: the save goes on
    assert r["save_error"] is None and r["saved_icon"] == "tick"
    saved = Path(r["saved"])
    assert saved.parent == videos / "StoryBeam" and saved.is_file()
    reader = imageio.get_reader(saved)
    assert reader.get_meta_data()["size"] == (320, 180) and reader.get_meta_data().get("audio_codec") == "aac"
    # the teacher's switch removes *save*
    assert r["save_offered_when_forbidden"] is False and r["switch_selected_after"] is False
    # named by picture (no typing for a child), binned, and brought back by the teacher
    assert r["title_input_for_child"] is False
    cover = r["cover"]
    assert cover["picture"] == "animal" and cover["colour"] == 5
    assert cover["voice"]["asset"].startswith("narration-") and 0.8 < cover["voice"]["seconds"] < 3.0
    assert r["name_heard"]  # the tile says the name back
    assert r["binned"] == ["demo-robot-cat"] and r["tiles_after_bin"] == 0
    assert r["restored"] == ["demo-robot-cat"] and r["tiles_after_restore"] == 1
