"""Voice narration in the real app, by touch (offscreen, one app per subprocess like
tests/app/test_ui.py): record, keep, a refused file, import and trim, the teacher's
switch, and the voice in step with Play and the projector.

The microphone is an array played at real time through the real recorder, and sounds go
to a fake loader that records play/seek/stop (tests/support/narration_scenarios.py)."""
from __future__ import annotations

import wave

import numpy as np
import pytest

from app.story import DEMO_STORY_ID, demo_story
from app.story.storage import ProfileStore
from app.ui.strings import tr
from tests.app.test_ui import _drive

pytestmark = pytest.mark.slow  # drives the real app in a child process


def _wav(path, seconds: float, rate: int) -> None:
    t = np.arange(int(seconds * rate)) / rate
    with wave.open(str(path), "wb") as wf:
        wf.setnchannels(1)
        wf.setsampwidth(2)
        wf.setframerate(rate)
        wf.writeframes(np.round(0.3 * np.sin(2 * np.pi * 440 * t) * 32767).astype("<i2").tobytes())


@pytest.mark.parametrize("lang", ["en", "ja"])
def test_record_import_trim_switch_off_and_play_in_step_by_touch(tmp_path, lang):
    with ProfileStore(tmp_path / "p.db") as store:
        store.save_story(demo_story())
    folder = tmp_path / "import"
    folder.mkdir()
    _wav(folder / "hello.wav", 2.0, 22050)
    _wav(folder / "wrong_rate.wav", 1.0, 12345)
    r, _out = _drive(tmp_path, "narration", lang)

    assert min(r["voice_button"]) >= 48  # a big touch target
    assert r["record_visible"] == 1 and r["status_empty"] == tr("narration_none", lang)
    # recorded through the real recorder: at least the 1.2 s waited for, the .part file gone
    assert 1.2 <= r["recorded_seconds"] <= 30
    assert r["leftover_recordings"] == []
    assert r["kept"]["seconds"] == pytest.approx(r["recorded_seconds"], abs=1e-3)
    assert r["kept_saved"] == r["kept"] and r["assets"] == [r["kept"]["asset"]]
    # a wrong-rate file: refused with a picture and one sentence (spoken), never the
    # exception's text or the file's path; nothing stored
    assert r["files"] == ["hello.wav", "wrong_rate.wav"]
    assert r["refused_notice"] == "sound_broken" and r["refused"] == tr("notice_sound_broken", lang)
    assert str(folder) not in r["refused"] and "12345" not in r["refused"]
    assert r["spoken"][-1] == [r["refused"], lang]
    assert r["after_refused"] == r["kept"] and r["assets_after_refused"] == r["assets"]
    # imported and trimmed by a tap on the end slider's middle: about half of the 2 s
    assert r["import_seconds"] == pytest.approx(2.0)
    assert 0.6 < r["end_slider"] < 1.4
    assert r["trimmed"]["seconds"] == pytest.approx(r["end_slider"], abs=0.01)
    assert r["trimmed"]["asset"] != r["kept"]["asset"]
    assert r["duration_after"] == pytest.approx(r["duration_before"])  # the demo scene is longer than 1.4 s
    # the teacher's switch hides the record button and says why
    assert r["teacher_label"] == f"{tr('recording_setting', lang)}: {tr('off', lang)}"
    assert r["off_record_visible"] == 0 and r["off_reason"] == tr("notice_recording_off", lang)
    # Play: the voice starts at the scene's start and stops at its end, in step with the clock
    voice = r["voice_file"]
    calls = [tuple(c) for c in r["play_calls"]]
    assert calls[0] == ("play", voice, 0.0)
    assert ("stop", voice, 0.0) in calls and not any(c[0] == "seek" for c in calls)
    # the player's own record: started at scene time 0, ended by the time line passing the
    # voice's end ("end" at a scene time past it) or -- when one clock tick under load
    # jumped past the whole scene -- by the next scene beginning ("next"); never by a pause
    # (the story was still playing). Wall-clock timing is not asserted: under load one
    # clock tick can take seconds.
    events = [tuple(e) for e in r["play_events"]]
    assert events[0] == ("play", voice, 0.0) and events[1][1] == voice and r["still_playing"]
    assert events[1][0] in ("end", "next")
    if events[1][0] == "end":
        assert events[1][2] >= r["trimmed"]["seconds"]
    # started mid-voice: it seeks to the time line
    scrub = [tuple(c) for c in r["scrub_calls"]]
    assert scrub[0] == ("play", voice, 0.0) and scrub[1][:2] == ("seek", voice)
    assert scrub[1][2] == pytest.approx(0.4, abs=0.05)
    assert r["after_pause"][0] == "stop"
    # the projector plays it too
    assert [tuple(c) for c in r["projector_calls"]] == [("play", voice, 0.0)]
    with ProfileStore(tmp_path / "p.db") as store:
        assert store.load_story(DEMO_STORY_ID).scenes[0].narration.to_dict() == r["trimmed"]
