"""Issue 29 scenarios for tests/support/ui_driver.py, in their own file: the end of a story
in Play (celebration, controls, saving the video), and managing stories on the home screen
(bin, name by picture) and in teacher mode (the bin, the video-saving switch).

The driver runs as ``__main__``; its helpers are taken from there. The sound loader is a
recorder (the offscreen machine has no audio device); the video is the real story film,
exported by the app's exporter in a child process, at 320x180 and 5 fps to stay short.
"""
from __future__ import annotations

import sys
import threading

from narration_scenarios import SOUND_CALLS, FakeSound, tone, waiting  # the sound recorder and the waiting step

drv = sys.modules["__main__"]
def story_end_steps(app):
    import app.ui.narration as narration
    import app.ui.story_end as story_end
    from app.services.recording import ArraySource
    from app.player.video_export import app_exporter
    from app.services import video_saving_allowed
    from app.story import DEMO_STORY_ID

    tap, touching, result = drv.tap, drv.touching, drv.result
    story_end.sound_loader = narration.sound_loader = FakeSound
    narration.recorder_finder = lambda: (lambda: ArraySource(tone(3.0, 22050), 22050), "")
    film = app_exporter("story", fps=5.0, size=(320, 180))
    gate = threading.Event()  # the export waits for it: the steps below need it still running

    def gated_export(story, path, progress=None):
        gate.wait(120)
        return film(story, path, progress)
    app.video_exporter = gated_export
    play = lambda: app.sm.get_screen("play")  # noqa: E731

    def open_play():
        app.open_story(DEMO_STORY_ID)
        app.go("play")
    yield open_play
    yield lambda: result.update(icon_start=play().play_button.icon)
    # each state is read in the step that sees it (a loaded machine may take longer than the story between steps)
    yield touching(lambda: tap(play().play_button), until=lambda: play().player.playing and not result.update(
        icon_playing=play().play_button.icon, text_playing=play().play_button.text))
    yield lambda: play().player.seek(play().player.duration - 0.2)  # near the end

    def celebrating():
        """Seen: hold the confetti at 0.5 s for the screenshot (frames come slowly under load)."""
        c = play().celebration
        if c is None:
            return False
        c.stop()
        c.draw_at(0.5)
        result.update(icon_end=play().play_button.icon, text_end=play().play_button.text, celebration_frames=c.frames,
                      sounds=[path for call, path, *_ in SOUND_CALLS if call == "play"])
        return True
    yield waiting(celebrating, "the celebration", 20.0)
    yield lambda: drv.shot("celebration")
    yield lambda: play().celebration.finish()  # what the end of its 2.5 s does
    yield waiting(lambda: play().end_panel is not None, "the end choices", 20.0)
    yield lambda: result.update(save_offered=play().end_panel.save_button is not None)
    yield lambda: drv.shot("end_panel")
    yield touching(lambda: tap(play().end_panel.save_button), until=lambda: play().saver is not None
                   and play().saver.showing)
    # never stuck: *back* closes the progress while the film is made; *save* again shows it (no second export)
    yield touching(lambda: tap(play().saver.close_button), until=lambda: not play().saver.showing)
    yield lambda: result.update(busy_after_close=play().saver.busy)
    yield touching(lambda: tap(play().end_panel.save_button), until=lambda: play().saver.showing)
    yield lambda: result.update(exports_started=play().saver.starts) or gate.set()
    yield waiting(lambda: play().saver.bar.value > 0, "export progress", 180.0)
    yield lambda: result.update(progress_seen=[play().saver.bar.value, play().saver.bar.max])
    yield waiting(lambda: not play().saver.busy and (play().saver.saved or play().saver.error), "the saved video",
                  240.0)
    yield lambda: result.update(saved=play().saver.saved.location if play().saver.saved else None,
                                save_error=play().saver.error, saved_icon=play().saver.picture.icon)
    yield lambda: drv.shot("saved")
    yield touching(lambda: tap(play().saver.close_button), until=lambda: not play().saver.showing)
    yield touching(lambda: tap(play().end_panel.replay_button), until=lambda: play().player.playing and not result.update(
        icon_replay=play().play_button.icon, end_gone=play().end_panel is None))
    yield lambda: play().player.seek(1.0)  # far from the end, whatever the load
    yield touching(lambda: tap(play().play_button), until=lambda: not play().player.playing and not result.update(
        icon_paused=play().play_button.icon))
    # the teacher forbids saving (teacher mode's switch; the PIN is tested elsewhere): again and home only
    teacher = lambda: app.sm.get_screen("teacher")  # noqa: E731

    def to_teacher():
        app.teacher_unlocked = True
        app.go("teacher")
    yield to_teacher
    yield touching(lambda: tap(teacher().video_saving_button), until=lambda: not video_saving_allowed(app.store))
    yield lambda: result.update(switch_selected_after=teacher().video_saving_button.selected)
    yield lambda: drv.shot("teacher_switch")
    yield lambda: teacher().leave()  # out of teacher mode (locked again), as its Home button does
    yield lambda: app.go("play")
    yield lambda: play().show_end_choices()
    yield lambda: result.update(save_offered_when_forbidden=play().end_panel.save_button is not None)
    yield touching(lambda: tap(play().end_panel.home_button), until=lambda: app.sm.current == "home")
    # home: name the story by picture, then move it to the bin
    home = lambda: app.sm.get_screen("home")  # noqa: E731
    tile = lambda: next(t for t in home().tiles if t.story_id == DEMO_STORY_ID)  # noqa: E731
    yield touching(lambda: tap(tile().rename_button), until=lambda: getattr(home(), "rename_view", None) is not None
                   and home().rename_view.parent is not None)
    yield lambda: result.update(title_input_for_child=home().rename_view.title_input is not None)
    yield touching(lambda: tap(home().rename_view.picture_buttons["animal"]),
                   until=lambda: home().rename_view.picture == "animal")
    yield touching(lambda: tap(home().rename_view.colour_buttons[5]), until=lambda: home().rename_view.colour == 5)
    # the name said aloud: the microphone (a 3 s tone played in real time), stopped after about 1 s
    yield touching(lambda: tap(home().rename_view.mic_button), until=lambda: home().rename_view.recorder is not None)
    yield waiting(lambda: home().rename_view.recorder.seconds >= 1.0, "a second of voice", 10.0)
    yield lambda: drv.shot("rename")
    yield touching(lambda: tap(home().rename_view.mic_button), until=lambda: home().rename_view.voice is not None)
    yield touching(lambda: tap(home().rename_view.ok_button),
                   until=lambda: app.store.load_story(DEMO_STORY_ID).cover is not None)
    yield lambda: result.update(cover=app.store.load_story(DEMO_STORY_ID).to_dict()["cover"])
    yield waiting(lambda: home().rename_view.parent is None, "the rename view to close", 10.0)
    yield lambda: drv.shot("home_named")
    yield touching(lambda: tap(tile().name_button), until=lambda: any(
        call == "play" and path.endswith(app.store.load_story(DEMO_STORY_ID).cover.voice.asset)
        for call, path, *_ in SOUND_CALLS))
    yield lambda: result.update(name_heard=True)
    yield touching(lambda: tap(tile().bin_button), until=lambda: not app.store.list_stories())
    yield lambda: result.update(binned=[s.id for s in app.store.binned_stories()], tiles_after_bin=len(home().tiles))
    # the teacher's bin brings it back
    yield to_teacher
    yield touching(lambda: tap(teacher().bin_button), until=lambda: getattr(teacher(), "bin_view", None) is not None
                   and teacher().bin_view.parent is not None)
    yield lambda: drv.shot("bin")
    yield touching(lambda: tap(teacher().bin_view.restore_buttons[DEMO_STORY_ID]),
                   until=lambda: bool(app.store.list_stories()))
    yield lambda: teacher().bin_view.dismiss()
    yield lambda: teacher().leave()
    yield lambda: result.update(restored=[s.id for s in app.store.list_stories()], tiles_after_restore=len(home().tiles))
    yield drv.finish


SCENARIOS = {"story_end": story_end_steps}
