"""Pictures before words (issue 29): the notices a child meets, the speech that says them,
the first launch's language, motion tiles' names and icons that do not repeat."""
from __future__ import annotations

import subprocess

import pytest

from app.services.speech import EspeakSpeaker, SilentSpeaker, find_speaker
from app.story import NarrationError, StorageError, StoryError
from app.services import ActItOutError, RecordingError
from ar.camera_sources import CameraSourceError
from app.ui.clip_tiles import clip_tile_name, numbered_names
from app.ui.strings import LANGUAGES, STRINGS, device_language, tr


def _signature(draw) -> tuple:
    """What a drawing function puts on a canvas: each instruction's type and geometry."""
    from kivy.graphics import Color  # deferred: Kivy after the test environment
    from kivy.uix.widget import Widget
    w = Widget()
    with w.canvas:
        draw()
    sig = []
    for ins in w.canvas.children:
        if isinstance(ins, Color):
            sig.append(("Color", tuple(round(c, 3) for c in ins.rgba)))
            continue
        geometry = [getattr(ins, a, None) for a in ("points", "pos", "size", "circle", "ellipse", "rectangle")]
        sig.append((type(ins).__name__, repr([g if not isinstance(g, list) else [round(v, 2) for v in g]
                                               for g in geometry])))
    return tuple(sig)


def test_every_notice_has_a_distinct_picture_and_a_sentence_in_both_languages():
    from app.ui.notice_art import PICTURES, draw_notice
    signatures = {name: _signature(lambda name=name: draw_notice(name, 0, 0, 100)) for name in PICTURES}
    assert len(set(signatures.values())) == len(PICTURES), "two notices draw the same picture"
    for name in PICTURES:
        for lang in LANGUAGES:
            sentence = tr(f"notice_{name}", lang)
            assert sentence and sentence != f"notice_{name}", (name, lang)
            assert len(sentence) <= 80, (name, lang, "one short sentence")


def test_errors_become_notices_never_their_text():
    from app.ui.notices import notice_for, notice_sentence
    cases = {
        NarrationError("/home/x/a.wav: sample rate 12345 Hz is not supported"): "sound_broken",
        NarrationError("/x/long.wav: 130.0 s long", "too_long"): "sound_long",
        NarrationError("/x/s.wav: silence only", "silent"): "sound_silent",
        NarrationError("/x/big.wav: 70 MB", "too_big"): "file_big",
        NarrationError("story full", "story_full"): "story_full",
        RecordingError("No module named 'sounddevice'"): "no_microphone",
        ImportError("No module named 'sounddevice'"): "no_microphone",
        StorageError("/data/profile.db: disk I/O error"): "storage",
        ActItOutError("camera 1 cannot be opened"): "no_camera",
        CameraSourceError("kivy:1", "Kivy cannot open this camera"): "no_camera",
        StoryError("story.json, scene 2: bad path"): "file_broken",
        ValueError("anything else"): "oops",
    }
    for exc, notice in cases.items():
        assert notice_for(exc) == notice, exc
        for lang in LANGUAGES:
            sentence = notice_sentence(lambda key: tr(key, lang), notice_for(exc))
            assert str(exc) not in sentence and "/" not in sentence and "sounddevice" not in sentence


def test_a_new_button_icon_for_each_finder():
    """*More like this*, *Pose*, *Groups* and *Voice* each have their own icon, not a
    neighbour's (they were ••• twice, the jump figure, the copy icon, and none)."""
    from app.ui.art import draw_icon
    names = ["similar", "more", "pose", "jump", "groups", "duplicate", "voice", "record", "stop", "keep", "play",
             "add", "delete"]
    sigs = {n: _signature(lambda n=n: draw_icon(n, 0, 0, 100)) for n in names}
    assert len(set(sigs.values())) == len(names)
    unknown = _signature(lambda: draw_icon("no-such-icon", 0, 0, 100))
    assert all(sig != unknown for sig in sigs.values()), "an icon name fell back to the plain dot"


def test_editor_finders_use_their_own_icons():
    source = open("app/ui/editor.py", encoding="utf-8").read()
    assert 'IconButton("similar", t("more_like_this")' in source
    assert 'IconButton("pose", t("pose_button")' in source
    assert 'IconButton("groups", t("groups_button")' in source
    assert 'IconButton("voice", app.t("narration")' in open("app/ui/narration.py", encoding="utf-8").read()


@pytest.mark.parametrize("env,lang", [({"LANG": "ja_JP.UTF-8"}, "ja"), ({"LANG": "en_GB.UTF-8"}, "en"),
                                      ({"LANG": "fr_FR.UTF-8"}, "en"), ({}, "en"), ({"LANG": "C"}, "en"),
                                      ({"LANGUAGE": "ja:en", "LANG": "en_US.UTF-8"}, "ja"),
                                      ({"LC_ALL": "en_US.UTF-8", "LANG": "ja_JP.UTF-8"}, "en")])
def test_the_first_launch_follows_the_device_language(env, lang):
    assert device_language("linux", env) == lang


def test_espeak_says_each_prompt_in_the_language_and_stops_the_one_before():
    started = []

    class Proc:
        def __init__(self, cmd, **kw):
            self.cmd, self.done, self.stopped = cmd, False, False
            started.append(self)

        def poll(self):
            return 0 if self.done else None

        def terminate(self):
            self.stopped = True

    speaker = EspeakSpeaker("/usr/bin/espeak-ng", popen=Proc)
    speaker.say("Add a character first.", "en")
    speaker.say("さきに だれかを えらんでね。", "ja")
    assert started[0].cmd[:3] == ["/usr/bin/espeak-ng", "-v", "en-us"] and started[0].cmd[-1] == "Add a character first."
    assert started[1].cmd[2] == "ja" and started[0].stopped and not started[1].stopped

    def broken(cmd, **kw):
        raise OSError("exec format error")
    EspeakSpeaker("/bin/espeak", popen=broken).say("hello", "en")  # never raises


def test_find_speaker_prefers_espeak_ng_and_is_silent_without_any():
    assert isinstance(find_speaker("linux", which=lambda p: None), SilentSpeaker)
    ng = find_speaker("linux", which=lambda p: f"/usr/bin/{p}")
    assert isinstance(ng, EspeakSpeaker) and ng.program.endswith("espeak-ng")
    old = find_speaker("linux", which=lambda p: "/usr/bin/espeak" if p == "espeak" else None)
    assert old.program == "/usr/bin/espeak"


def test_espeak_really_speaks_where_it_is_installed(tmp_path):
    speaker = find_speaker("linux")
    if not isinstance(speaker, EspeakSpeaker):
        pytest.skip("espeak-ng is not installed here (the app stays silent, as designed)")
    out = subprocess.run([speaker.program, "-v", "en-us", "-w", str(tmp_path / "s.wav"), "hello"], timeout=30)
    assert out.returncode == 0 and (tmp_path / "s.wav").stat().st_size > 1000


def test_motion_tiles_are_named_by_class_and_number_never_by_capture_id():
    numbers = {"02_03": 3, "10_01": 1}
    t = lambda key: tr(key, "en")  # noqa: E731
    assert clip_tile_name(t, "run", "02_03", numbers.get) == "Run 3"
    assert clip_tile_name(t, "kick", "99_99", numbers.get) == "Kick"
    assert "02_03" not in clip_tile_name(lambda k: tr(k, "ja"), "run", "02_03", numbers.get)
    assert numbered_names(["Kick", "Walk", "Kick", "Group 4"]) == ["Kick 1", "Walk", "Kick 2", "Group 4"]


def test_the_catalog_numbers_clips_within_their_class(tmp_path):
    from app.services.catalog import MotionCatalog
    (tmp_path / "labels.csv").write_text("trial,label\n01_01,walk\n02_03,run\n02_04,run\n05_01,walk\n")
    catalog = MotionCatalog(tmp_path, build_index=False)
    assert [catalog.number_of(t) for t in ("01_01", "02_03", "02_04", "05_01")] == [1, 1, 2, 2]
    assert catalog.number_of("02_04@52") == 2 and catalog.number_of("77_77") is None


def test_no_child_string_carries_a_placeholder_for_an_error_text():
    """The old "Oops: {why}" style put exception text on a child's screen."""
    child_keys = [k for k in STRINGS if k.startswith("notice_") or k in ("audio_none_here",)]
    assert child_keys
    for key in child_keys:
        for lang in LANGUAGES:
            assert "{" not in STRINGS[key][lang], key
