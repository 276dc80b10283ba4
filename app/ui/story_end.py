"""The end of a story in Play: a celebration, then three big choices -- again, home, save.

* :class:`Celebration` -- confetti bursting over the table
  (:func:`app.player.celebration.confetti`, the same as the film's ending card) for
  :data:`app.player.celebration.CELEBRATION_SECONDS`, and the chime
  (:func:`app.player.celebration.chime`, written once as a WAV beside the profile and
  played with Kivy's SoundLoader; silently skipped where there is no audio output).
* :class:`EndPanel` -- *replay* (the play picture), *home*, and *save* (the export picture)
  when the teacher's switch allows it (:func:`app.services.video_saving_allowed`) and this
  device can make videos.
* :class:`VideoSaver` -- the save: the story film exported on a worker thread
  (``app.video_exporter``: a child process with its own GL context, so the UI never
  blocks), its progress as a bar under a film picture, then the video handed to the
  platform's gallery (:func:`app.services.gallery_for`: the desktop's videos folder, or
  Android's Movies collection and the share sheet). Only pictures reach the child: a
  tick when saved, a cross when not (the reason goes to the log and the grown-ups' line).
"""
from __future__ import annotations

import logging
import math
import threading
from pathlib import Path

from kivy.app import App
from kivy.clock import Clock
from kivy.core.audio import SoundLoader
from kivy.graphics import Color, PopMatrix, PushMatrix, Rectangle, Rotate
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.label import Label
from kivy.uix.modalview import ModalView
from kivy.uix.progressbar import ProgressBar
from kivy.uix.widget import Widget
from kivy.utils import platform

from app.player.celebration import CELEBRATION_SECONDS, chime_wav, confetti
from app.services.gallery import GalleryError, gallery_for, video_saving_allowed
from app.ui.widgets import IconButton, IconView, filled
from retrieval.errors import StoryBeamError

log = logging.getLogger(__name__)
#: loads a sound file (Kivy's SoundLoader; the UI tests put a recorder here)
sound_loader = SoundLoader.load


class Celebration(Widget):
    """Confetti over the widget's area for ``CELEBRATION_SECONDS``, then ``on_done()``."""

    def __init__(self, on_done=None, **kwargs):
        super().__init__(**kwargs)
        self.on_done = on_done
        self.t = 0.0
        self.frames = 0
        self._event = Clock.schedule_interval(self._tick, 1 / 30)
        self.bind(pos=lambda *_: self.draw_at(self.t), size=lambda *_: self.draw_at(self.t))
        self.sound_played = play_chime()

    def _tick(self, dt: float) -> None:
        self.t += dt
        self.frames += 1
        self.draw_at(self.t)
        if self.t >= CELEBRATION_SECONDS:
            self.finish()

    def finish(self) -> None:
        """Stop the animation and go on (to the end choices)."""
        self.stop()
        if self.on_done:
            self.on_done()

    def draw_at(self, t: float) -> None:
        """Draw the confetti as it is ``t`` seconds after the burst (real time: a slow
        frame skips ahead rather than slowing the celebration down)."""
        self.t = t
        self.canvas.clear()
        bits = confetti(t)
        with self.canvas:
            for (x, y), colour, angle, s in zip(bits["xy"], bits["colour"], bits["angle"], bits["size"]):
                px, py, a = self.x + x * self.width, self.y + y * self.height, s * self.height
                Color(*(c / 255 for c in colour))
                PushMatrix()
                Rotate(angle=math.degrees(angle), origin=(px, py))
                Rectangle(pos=(px - a, py - 0.45 * a), size=(2 * a, 0.9 * a))
                PopMatrix()

    def stop(self) -> None:
        if self._event is not None:
            self._event.cancel()
            self._event = None


_chime_path: list[Path] = []


def play_chime() -> bool:
    """Play the celebration sound; False where it cannot (no audio output, no writable folder)."""
    try:
        if not _chime_path:
            path = App.get_running_app().export_dir.parent / "storybeam-chime.wav"
            if not path.is_file():
                path.write_bytes(chime_wav(44100))
            _chime_path.append(path)
        sound = sound_loader(str(_chime_path[0]))
        if sound is None:
            return False
        sound.play()
        return True
    except (OSError, AttributeError) as exc:
        log.info("no celebration sound: %s", exc)
        return False


class EndPanel(BoxLayout):
    """Replay, home and (when allowed) save: three big picture buttons."""

    def __init__(self, replay, home, save=None, **kwargs):
        super().__init__(spacing=dp(24), padding=dp(16), **kwargs)
        t = App.get_running_app().t
        self.replay_button = IconButton("play", t("play_again"), on_press=replay, background=[0.75, 0.95, 0.75, 1])
        self.home_button = IconButton("home", t("home"), on_press=home, background=[1.0, 0.9, 0.6, 1])
        self.add_widget(self.replay_button)
        self.add_widget(self.home_button)
        self.save_button = None
        if save is not None:
            self.save_button = IconButton("export", t("save_video"), on_press=save, background=[0.8, 0.9, 1.0, 1])
            self.add_widget(self.save_button)


def can_save_video(app) -> bool:
    return app.video_exporter is not None and app.store is not None and video_saving_allowed(app.store)


class VideoSaver:
    """Export the open story as the film on a worker thread, showing a progress bar, then
    save it into the gallery (and offer the share sheet on Android)."""

    def __init__(self, app):
        self.app = app
        self.thread: threading.Thread | None = None
        self.saved = None
        self.error: str | None = None
        self.view: ModalView | None = None
        self.starts = 0  # exports started (a second tap while one runs starts none)

    @property
    def busy(self) -> bool:
        return self.thread is not None and self.thread.is_alive()

    def start(self) -> None:
        """Save the open story's film; while a save runs, only show its progress again."""
        if self.busy:
            self.show()
            return
        app = self.app
        story = app.editor.story
        self.saved, self.error = None, None
        self.starts += 1
        self._build_view()
        self.show()
        out = app.export_dir / f"story_{story.id}.mp4"
        exporter, gallery_dir = app.video_exporter, app.export_dir

        def progress(done: int, total: int) -> None:
            Clock.schedule_once(lambda dt: self._progress(done, total), 0)

        def work() -> None:
            try:
                result = exporter(story, out, progress)
                saved = gallery_for(platform, gallery_dir).save(result.path, story.title or "story")
                Clock.schedule_once(lambda dt: self._done(saved, None), 0)
            except (StoryBeamError, GalleryError, OSError) as exc:
                log.error("saving the video failed: %s", exc)
                Clock.schedule_once(lambda dt, why=str(exc): self._done(None, why), 0)
        self.thread = threading.Thread(target=work, name="storybeam-save-video", daemon=True)
        self.thread.start()

    def _build_view(self) -> None:
        """The film picture, the bar, a line for grown-ups and *back* (always there: a
        child is never stuck here; the save goes on behind, and its tick comes back)."""
        self.view = ModalView(size_hint=(0.6, 0.45), auto_dismiss=False)
        box = filled(BoxLayout(orientation="vertical", padding=dp(24), spacing=dp(16)), (1, 0.97, 0.9, 1))
        self.picture = IconView(icon="export")
        box.add_widget(self.picture)
        self.bar = ProgressBar(max=1, value=0, size_hint_y=None, height=dp(48))
        box.add_widget(self.bar)
        self.note = Label(text="", font_size=dp(14), color=(0.3, 0.3, 0.35, 1), size_hint_y=None, height=dp(24))
        box.add_widget(self.note)
        self.close_button = IconButton("home", self.app.t("back"), on_press=self.hide, size_hint_y=None,
                                       height=dp(64))
        box.add_widget(self.close_button)
        self.view.add_widget(box)

    @property
    def showing(self) -> bool:
        return self.view is not None and self.view.parent is not None

    def show(self) -> None:
        if self.view is not None and not self.showing:
            self.view.open()

    def hide(self) -> None:
        if self.showing:
            self.view.dismiss(animation=False)  # gone at once: a tap on *save* right after shows it again

    def _progress(self, done: int, total: int) -> None:
        self.bar.max = max(total, 1)
        self.bar.value = min(done, total)

    def _done(self, saved, error: str | None) -> None:
        self.saved, self.error = saved, error
        self.bar.value = self.bar.max
        self.picture.icon = "tick" if saved is not None else "delete"
        # one short sentence for the grown-ups (where to find it, no path); the child sees the picture
        where = "video_saved_android" if platform == "android" else "video_saved"
        self.note.text = self.app.t(where) if saved is not None else self.app.t("video_not_saved")
        self.show()  # the tick (or the cross) comes back if the child had closed the progress
        if saved is not None and platform == "android":
            try:
                gallery_for(platform, self.app.export_dir).share(saved)
            except Exception as exc:  # noqa: BLE001 - a share sheet that cannot open: the video is saved anyway
                log.warning("share sheet: %s", exc)


__all__ = ["Celebration", "EndPanel", "VideoSaver", "can_save_video", "play_chime"]
