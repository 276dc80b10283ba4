"""Voice narration scenarios for tests/support/ui_driver.py (issue 14), in their own file.

The driver runs as ``__main__``; its helpers (``tap``, ``touching``, ``result``,
``finish``, ``OUT``) are taken from there. The microphone is a WAV-like array played at
real time through the real recorder (:class:`app.services.recording.ArraySource`), and the
sound loader is a fake that records what it was asked to play, seek and stop -- the
offscreen test machine has no audio device.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from app.services.recording import ArraySource

drv = sys.modules["__main__"]

#: What the fake sound loader was asked: (call, file, argument, wall-clock time).
SOUND_CALLS: list = []


class FakeSound:
    def __init__(self, path: str):
        self.path = path

    def play(self):
        SOUND_CALLS.append(("play", self.path, 0.0, time.monotonic()))

    def stop(self):
        SOUND_CALLS.append(("stop", self.path, 0.0, time.monotonic()))

    def seek(self, t):
        SOUND_CALLS.append(("seek", self.path, float(t), time.monotonic()))

    def get_pos(self):
        return 0.0  # like Kivy's SDL2 provider: no position reported


def waiting(check, what: str, seconds: float = 30.0):
    """A step that returns "again" until ``check()`` is true (failing after ``seconds``)."""
    deadline = []

    def step():
        if not deadline:
            deadline.append(time.monotonic() + seconds)
        if check():
            return None
        if time.monotonic() > deadline[0]:
            raise AssertionError(f"waited {seconds:.0f} s for {what}")
        return "again"
    return step


def tone(seconds: float, rate: int) -> np.ndarray:
    t = np.arange(int(seconds * rate)) / rate
    return np.round(0.3 * np.sin(2 * np.pi * 330 * t) * 32767).astype(np.int16)


def narration_steps(app):
    """Record (a 1.5 s "microphone"), keep; a refused file; import and trim by touch;
    the teacher switches recording off; Play and the projector play the voice in step."""
    import app.ui.narration as narration
    from app.story import DEMO_STORY_ID

    tap, touching, result = drv.tap, drv.touching, drv.result
    narration.recorder_finder = lambda: (lambda: ArraySource(tone(1.5, 22050), 22050), "")
    narration.sound_loader = FakeSound
    editor = lambda: app.sm.get_screen("editor")  # noqa: E731
    panel = lambda: editor().narration_panel  # noqa: E731
    scene0 = lambda: app.editor.story.scenes[0]  # noqa: E731
    stored0 = lambda: app.store.load_story(DEMO_STORY_ID).scenes[0].narration  # noqa: E731

    def open_story():
        app.open_story(DEMO_STORY_ID)
        app.current_scene_id = scene0().id
        app.go("editor")
    yield open_story
    yield lambda: result.update(duration_before=scene0().duration, voice_button=[editor().voice_button.width,
                                                                                 editor().voice_button.height])
    yield touching(lambda: tap(editor().voice_button),
                   until=lambda: getattr(editor(), "narration_panel", None) is not None
                   and panel() in drv.Window.children)
    yield lambda: result.update(record_visible=panel().record_button.opacity, status_empty=panel().status.text)
    # -- record, stop, keep ---------------------------------------------------------------------
    yield touching(lambda: tap(panel().record_button), until=lambda: panel().recorder is not None)
    yield waiting(lambda: panel().recorder.seconds >= 1.2, "the recording to reach 1.2 s")
    yield touching(lambda: tap(panel().record_button), until=lambda: panel().pending is not None)
    yield lambda: result.update(recorded_seconds=panel().pending.seconds,
                                leftover_recordings=sorted(p.name for p in panel().folder.iterdir()))
    yield touching(lambda: tap(panel().keep_button), until=lambda: scene0().narration is not None)
    yield lambda: result.update(kept=scene0().narration.to_dict(), kept_saved=stored0().to_dict(),
                                assets=app.store.asset_names(DEMO_STORY_ID))
    # -- a refused file, then an imported one trimmed by touch ------------------------------------
    yield touching(lambda: tap(panel().file_button), until=lambda: len(panel().file_tiles) >= 2)
    yield lambda: result.update(files=sorted(k.rsplit("/", 1)[-1] for k in panel().file_tiles))

    def tile(name):
        return next(t for k, t in panel().file_tiles.items() if k.endswith("/" + name))
    yield touching(lambda: tap(tile("wrong_rate.wav")), until=lambda: panel().notice is not None)
    yield lambda: result.update(refused=panel().message, refused_notice=panel().notice,
                                spoken=list(getattr(app.speaker, "said", [])), after_refused=stored0().to_dict(),
                                assets_after_refused=app.store.asset_names(DEMO_STORY_ID))
    yield touching(lambda: tap(tile("hello.wav")), until=lambda: panel().pending is not None
                   and panel().end_slider is not None)
    yield lambda: result.update(import_seconds=panel().pending.seconds)
    yield lambda: drv.shot("narration_trim")
    yield touching(lambda: tap(panel().end_slider), changes=lambda: panel().end_slider.value)
    yield lambda: result.update(end_slider=panel().end_slider.value)
    yield touching(lambda: tap(panel().keep_button), changes=lambda: scene0().narration)
    yield lambda: result.update(trimmed=stored0().to_dict(), duration_after=scene0().duration)
    yield touching(lambda: tap(panel().close_button), until=lambda: panel().closed)
    # -- the teacher switches recording off ---------------------------------------------------------
    teacher = lambda: app.sm.get_screen("teacher")  # noqa: E731

    def to_teacher():
        app.teacher_unlocked = True
        app.go("teacher")
    yield to_teacher
    yield touching(lambda: tap(teacher().action_buttons["recording"]),
                   until=lambda: app.store.get_setting(narration.RECORDING_SETTING) == "off")
    yield lambda: result.update(teacher_label=teacher().action_buttons["recording"].text)
    yield lambda: app.go("editor")
    yield touching(lambda: tap(editor().voice_button),
                   until=lambda: panel() in drv.Window.children and panel().make_source is None)
    yield lambda: drv.shot("narration_off")
    yield lambda: result.update(off_record_visible=panel().record_button.opacity,
                                off_reason=panel().reason_label.text)
    yield touching(lambda: tap(panel().close_button), until=lambda: panel().closed)
    # -- Play: the voice starts with its scene and stops at its end -----------------------------------
    play = lambda: app.sm.get_screen("play")  # noqa: E731
    yield lambda: app.go("play")
    yield lambda: SOUND_CALLS.clear()
    yield touching(lambda: tap(play().play_button), until=lambda: play().player.playing)
    voice = lambda: str(app.store.asset_path(DEMO_STORY_ID, scene0().narration.asset))  # noqa: E731
    yield waiting(lambda: any(c[0] == "stop" for c in SOUND_CALLS), "the voice to stop at its end")
    yield lambda: result.update(play_calls=[c[:3] for c in SOUND_CALLS], voice_file=voice(),
                                play_events=list(play().player.narration.events),
                                still_playing=play().player.playing)
    # pause, scrub into the voice, play: it starts where the time line is

    def pause_and_scrub():
        if play().player.playing:
            tap(play().play_button)
        SOUND_CALLS.clear()
        play().scrubber.value = 0.4
    yield pause_and_scrub
    yield touching(lambda: tap(play().play_button), until=lambda: any(c[0] == "seek" for c in SOUND_CALLS))
    yield lambda: result.update(scrub_calls=[c[:3] for c in SOUND_CALLS])
    yield touching(lambda: tap(play().play_button), until=lambda: not play().player.playing)
    yield lambda: result.update(after_pause=[c[:3] for c in SOUND_CALLS][-1])
    # -- the projector plays the voice too -------------------------------------------------------------
    yield lambda: SOUND_CALLS.clear()
    yield lambda: app.go("projector")
    yield waiting(lambda: any(c[0] == "play" for c in SOUND_CALLS), "the projector to play the voice")
    yield lambda: result.update(projector_calls=[c[:3] for c in SOUND_CALLS][:1])
    yield lambda: app.go("editor")
    yield drv.finish


SCENARIOS = {"narration": narration_steps}
