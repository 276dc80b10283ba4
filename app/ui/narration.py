"""A scene's voice in the app: the record / import / trim panel of the editor, and the
player that keeps the voice in step with the scene's time line in Play and on the
projector.

* :class:`NarrationPanel` -- opened by the editor's *Voice* button (:func:`voice_button`):
  *Record* (when this device can -- :func:`app.services.recording.find_recorder` -- and the
  teacher has not switched recording off; otherwise the button is hidden and the reason
  shown), *Sound file* (big tiles of the WAV/OGG files in the profile's inbox, its import
  folder and downloads: no typing, no file dialog), then two big sliders to trim the new
  voice and *Keep* -- :func:`app.story.narration.store_narration` through the story editor,
  so it is undoable and autosaved, crash-safely. A sound longer than a scene's voice may
  be is imported whole, its end slider set at the longest a voice may be. A refused file
  is shown as a notice -- a picture and one sentence (:mod:`app.ui.notices`), spoken where
  the device can speak -- its reason logged, and nothing is stored.
* :class:`NarrationPlayback` -- driven by the play screens' clock with (scene, time in the
  scene, playing?): starts the scene's voice with Kivy's ``SoundLoader`` at the scene's
  start, seeks to the scene time when playback starts mid-scene or the child scrubs
  (where the audio provider can seek), stops it on pause, at the end of the voice and
  when the next scene begins.

The teacher's switch is the profile setting :data:`RECORDING_SETTING` (``on``/``off``).
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

from kivy.app import App
from kivy.clock import Clock
from kivy.core.audio import SoundLoader
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.label import Label
from kivy.uix.modalview import ModalView
from kivy.uix.slider import Slider

from app.services.recording import ChunkRecorder, discard_stale, find_recorder
from app.story import MAX_NARRATION_SECONDS, Audio, Scene, encode_wav, read_audio, store_narration, trim
from app.ui.import_picker import package_folders
from app.ui.notices import NoticePicture, log_notice, notice_for, notice_sentence
from app.ui.widgets import BUTTON_DP, IconButton, big_label, file_tiles, filled, newest_files
from retrieval.errors import StoryBeamError

#: Profile setting: the teacher's switch for recording (``on`` unless set to ``off``).
RECORDING_SETTING = "narration_recording"
AUDIO_SUFFIXES = (".wav", ".ogg")
MAX_LISTED = 60
#: How far the voice may drift from the time line before it is sought back (seconds).
DRIFT_S = 0.25

#: The recorder finder and sound loader, module attributes so a test can swap in a
#: microphone made of a WAV file and a loader that records what it was asked to play.
recorder_finder: Callable = find_recorder
sound_loader: Callable = SoundLoader.load


def recording_allowed(store) -> bool:
    return store.get_setting(RECORDING_SETTING, "on") != "off"


def recording_folder(db_path: str | Path) -> Path:
    """Unfinished recordings live here, beside the profile (never inside a story's assets)."""
    db_path = Path(db_path)
    return db_path.with_name(db_path.name + ".recording")


def find_audio_files(folders: list[Path]) -> list[Path]:
    """WAV and OGG files in ``folders`` (not recursive), newest first."""
    return newest_files(folders, AUDIO_SUFFIXES, MAX_LISTED)


def scene_voice_path(scene: Scene) -> str | None:
    """The file of ``scene``'s narration: in the open story's assets, else (the teacher's
    *Present all* plays scenes of every story as one) in any saved story's assets --
    narration files are named by their content, so any copy is the right one. None: the
    scene has no narration or its file is gone."""
    app = App.get_running_app()
    if scene.narration is None or app is None or app.store is None or app.editor is None:
        return None
    try:
        owners = [app.editor.story.id] + [s.id for s in app.store.list_stories() if s.id != app.editor.story.id]
        for story_id in owners:
            path = app.store.asset_path(story_id, scene.narration.asset)
            if path.is_file():
                return str(path)
    except StoryBeamError:
        return None
    return None


class NarrationPlayback:
    """Keeps a scene's voice in step with the play screens' time line.

    ``update(scene, t, playing)`` is called on every clock tick and seek: while playing,
    the voice of ``scene`` plays from ``t`` (loaded once per file, started when the scene
    changes, sought back when it drifts more than :data:`DRIFT_S` from ``t`` where the
    provider reports its position); otherwise, or past the voice's end, it is stopped."""

    def __init__(self, path_of: Callable[[Scene], str | None] = scene_voice_path):
        self.path_of = path_of
        self._sounds: dict[str, object] = {}
        self._paths: dict[str, str | None] = {}
        self.current: tuple[str, object] | None = None  # (file, sound)
        #: (play|seek|stop|next|missing|end, file, scene time): what happened, for tests and the log
        self.events: list[tuple[str, str, float]] = []

    def _load(self, path: str):
        if path not in self._sounds:
            self._sounds[path] = sound_loader(path)
        return self._sounds[path]

    def update(self, scene: Scene, t: float, playing: bool) -> None:
        voice = scene.narration
        if not playing or voice is None:
            self.stop(t, "stop" if not playing else "next")
            return
        if t >= voice.seconds:
            self.stop(t, "end")
            return
        if voice.asset not in self._paths:  # looked up once per voice, not on every tick
            self._paths[voice.asset] = self.path_of(scene)
        path = self._paths[voice.asset]
        if path is None:
            self.stop(t, "missing")
            return
        if self.current is not None and self.current[0] == path:
            sound = self.current[1]
            pos = sound.get_pos() if hasattr(sound, "get_pos") else 0.0
            if pos > 0 and abs(pos - t) > DRIFT_S:
                sound.seek(t)
                self.events.append(("seek", path, t))
            return
        self.stop(t, "next")
        sound = self._load(path)
        if sound is None:  # no audio provider here: the story plays silently
            return
        sound.play()
        if t > 0.05:
            sound.seek(t)
        self.current = (path, sound)
        self.events.append(("play", path, t))

    def stop(self, t: float = 0.0, why: str = "stop") -> None:
        """Stop the voice playing (``t``, ``why``: the scene time and reason, for
        :attr:`events`: ``stop`` -- paused; ``next`` -- another scene or voice; ``missing``
        -- its file is gone; ``end`` -- the time line passed the voice's end)."""
        if self.current is not None:
            path, sound = self.current
            sound.stop()
            self.current = None
            self.events.append((why, path, t))


class NarrationPanel(ModalView):
    """Record, import, trim, listen to and remove the voice of the editor's scene."""

    def __init__(self, scene_id: str, on_done: Callable[[], None] | None = None, **kwargs):
        kwargs.setdefault("size_hint", (0.86, 0.9))
        super().__init__(**kwargs)
        app = App.get_running_app()
        self.scene_id = scene_id
        self.on_done = on_done
        self.pending: Audio | None = None  # a new voice waiting to be trimmed and kept
        self.message = ""  # the sentence of the notice shown, if any
        self.notice: str | None = None  # the notice shown in the status line (app.ui.notices)
        self.recorder: ChunkRecorder | None = None
        self.file_tiles: dict[str, IconButton] = {}
        self.listening = None
        self.closed = False  # set when dismissed (the view stays on the window while it fades out)
        self.folder = recording_folder(app.db_path)
        discard_stale(self.folder)  # what a crash during an earlier recording left behind
        make_source, self.record_reason = recorder_finder()
        self.make_source = make_source
        self.record_notice: str | None = None  # why there is no Record button, as a notice
        if not recording_allowed(app.store):
            self.make_source, self.record_notice = None, "recording_off"
        elif make_source is None:
            log_notice("no_microphone", self.record_reason)
            self.record_notice = "no_microphone"
        self.bind(on_dismiss=lambda *_: self._closing())
        self.refresh()

    @property
    def scene(self) -> Scene:
        return App.get_running_app().editor.story.scene(self.scene_id)

    # -- layout ------------------------------------------------------------------------
    def refresh(self, files: bool = False) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        box = filled(BoxLayout(orientation="vertical", padding=dp(14), spacing=dp(8)), (1, 0.97, 0.9, 1))
        box.add_widget(big_label(t("narration_title"), 22))
        status_row = BoxLayout(size_hint_y=None, height=dp(72), spacing=dp(8))
        self.status_picture = NoticePicture(self.notice or "oops", size_hint_x=None,
                                            width=dp(72) if self.notice else 0, opacity=1 if self.notice else 0)
        status_row.add_widget(self.status_picture)
        self.status = Label(text=self._status_text(), color=(0.1, 0.1, 0.15, 1), font_size=dp(17),
                            halign="center", valign="middle")
        self.status.bind(size=lambda lbl, s: setattr(lbl, "text_size", s))
        status_row.add_widget(self.status)
        box.add_widget(status_row)
        row = BoxLayout(size_hint_y=None, height=dp(BUTTON_DP + 20), spacing=dp(10))
        recording = self.recorder is not None
        self.record_button = IconButton("stop" if recording else "record",
                                        t("stop_recording") if recording else t("record"),
                                        on_press=self.toggle_recording, font_size=dp(18),
                                        background=[1, 0.75, 0.75, 1])
        self.record_button.opacity = 1.0 if self.make_source is not None else 0.0
        self.record_button.disabled = self.make_source is None
        row.add_widget(self.record_button)
        self.file_button = IconButton("add", t("import_audio"), on_press=lambda: self.refresh(files=True),
                                      font_size=dp(15))
        self.listen_button = IconButton("play", t("listen"), on_press=self.listen, font_size=dp(15))
        self.remove_button = IconButton("delete", t("remove_voice"), on_press=self.remove, font_size=dp(15))
        has_voice = self.pending is not None or self.scene.narration is not None
        for b, usable in ((self.file_button, not recording), (self.listen_button, has_voice and not recording),
                          (self.remove_button, self.scene.narration is not None and not recording)):
            b.disabled, b.opacity = not usable, 1.0 if usable else 0.4
            row.add_widget(b)
        box.add_widget(row)
        reason = BoxLayout(size_hint_y=None, height=dp(40) if self.record_notice else 0, spacing=dp(6),
                           opacity=1 if self.record_notice else 0)
        if self.record_notice:  # no Record button: why, as a small notice
            reason.add_widget(NoticePicture(self.record_notice, size_hint_x=None, width=dp(40)))
        self.reason_label = Label(text=notice_sentence(t, self.record_notice) if self.record_notice else "",
                                  color=(0.55, 0.25, 0.1, 1), font_size=dp(14), halign="left", valign="middle")
        self.reason_label.bind(size=lambda lbl, s: setattr(lbl, "text_size", s))
        reason.add_widget(self.reason_label)
        box.add_widget(reason)
        self.start_slider = self.end_slider = self.keep_button = None
        if files:
            box.add_widget(self._file_list())
        elif self.pending is not None:
            box.add_widget(self._trimmer())
        else:
            box.add_widget(BoxLayout())
        self.close_button = IconButton("home", t("back"), on_press=self.dismiss, size_hint_y=None, height=dp(72))
        box.add_widget(self.close_button)
        self.add_widget(box)

    def _status_text(self) -> str:
        t = App.get_running_app().t
        if self.message:
            return self.message
        if self.recorder is not None:
            return t("recording_now", s=f"{self.recorder.seconds:.1f}")
        if self.pending is not None:
            return t("narration_new", s=f"{self.pending.seconds:.1f}")
        voice = self.scene.narration
        return t("narration_length", s=f"{voice.seconds:.1f}") if voice is not None else t("narration_none")

    def _file_list(self):
        t = App.get_running_app().t
        folders = package_folders(App.get_running_app().db_path)
        files = find_audio_files(folders)
        box = BoxLayout(orientation="vertical", spacing=dp(6))
        box.add_widget(big_label(t("audio_pick"), 16))
        scroll, self.file_tiles = file_tiles(files, lambda p: p.name, self.pick_file, t("audio_none_here"))
        box.add_widget(scroll)
        return box

    def _trimmer(self):
        t = App.get_running_app().t
        length = self.pending.seconds
        end = min(length, MAX_NARRATION_SECONDS)  # a long sound: its first part, as long as a voice may be
        box = BoxLayout(orientation="vertical", spacing=dp(6))
        self.start_label = big_label(t("trim_start", s="0.0"), 16)
        self.start_slider = Slider(min=0, max=length, value=0, cursor_size=(dp(56), dp(56)), size_hint_y=None,
                                   height=dp(64))
        self.end_label = big_label(t("trim_end", s=f"{end:.1f}"), 16)
        self.end_slider = Slider(min=0, max=length, value=end, cursor_size=(dp(56), dp(56)), size_hint_y=None,
                                 height=dp(64))
        self.start_slider.bind(value=self._trimmed)
        self.end_slider.bind(value=self._trimmed)
        for w in (self.start_label, self.start_slider, self.end_label, self.end_slider):
            box.add_widget(w)
        self.keep_button = IconButton("keep", t("keep_voice"), on_press=self.keep, size_hint_y=None,
                                      height=dp(BUTTON_DP), font_size=dp(18), background=[0.75, 0.95, 0.75, 1])
        box.add_widget(self.keep_button)
        return box

    def _trimmed(self, *_: object) -> None:
        t = App.get_running_app().t
        self.start_label.text = t("trim_start", s=f"{self.start_slider.value:.1f}")
        self.end_label.text = t("trim_end", s=f"{self.end_slider.value:.1f}")

    def _say(self, text: str) -> None:
        self.message, self.notice = text, None
        self.status.text = self._status_text()

    def _notify(self, notice: str, detail: object = None, redraw: bool = False, files: bool = False) -> None:
        """Show ``notice`` in the status line (its picture and sentence), say it, log ``detail``."""
        app = App.get_running_app()
        log_notice(notice, detail)
        self.notice, self.message = notice, notice_sentence(app.t, notice)
        app.speaker.say(self.message, app.lang)
        if redraw:
            self.refresh(files=files)
        else:
            self.status.text = self._status_text()
            self.status_picture.notice = notice
            self.status_picture.width, self.status_picture.opacity = dp(72), 1
            self.status_picture._redraw()

    def _clear_notice(self) -> None:
        self.notice, self.message = None, ""

    # -- actions -------------------------------------------------------------------------
    def toggle_recording(self) -> None:
        if self.recorder is None:
            self.start_recording()
        else:
            self.stop_recording()

    def start_recording(self) -> None:
        if self.make_source is None:
            return
        self._stop_listening()
        self.message = ""
        try:
            recorder = ChunkRecorder(self.make_source(), self.folder,
                                     on_limit=lambda: Clock.schedule_once(lambda dt: self._limit_reached(), 0))
            recorder.start()
        except (StoryBeamError, OSError, RuntimeError) as exc:
            self._notify("no_microphone", exc)
            return
        self.recorder = recorder
        self.pending = None
        Clock.schedule_interval(self._tick, 0.2)
        self.refresh()

    def _tick(self, _dt) -> None:
        if self.recorder is not None:
            self.status.text = self._status_text()

    def _limit_reached(self) -> None:
        if self.recorder is not None:
            self.stop_recording()
            self._say(App.get_running_app().t("recording_limit"))

    def stop_recording(self) -> None:
        recorder, self.recorder = self.recorder, None
        Clock.unschedule(self._tick)
        if recorder is None:
            return
        try:
            path = recorder.stop()
            try:
                self.pending = read_audio(path)
            finally:
                path.unlink(missing_ok=True)
            self._clear_notice()
        except StoryBeamError as exc:
            self._notify(notice_for(exc), exc)
        self.refresh()

    def pick_file(self, path: Path) -> None:
        """Check an audio file; a refused one is a notice (its reason in the log), nothing kept."""
        try:
            self.pending = read_audio(path)
        except StoryBeamError as exc:
            self.pending = None
            self._notify(notice_for(exc), exc, redraw=True, files=True)
            return
        self._clear_notice()
        self.refresh()

    def keep(self) -> None:
        """Trim the new voice to the sliders and store it as the scene's narration."""
        app = App.get_running_app()
        if self.pending is None:
            return
        try:
            audio = trim(self.pending, self.start_slider.value, self.end_slider.value)
            store_narration(app.store, app.editor.story, self.scene_id, audio, app.editor)
        except StoryBeamError as exc:
            self._notify(notice_for(exc), exc)
            return
        self.pending = None
        self._clear_notice()
        self.refresh()
        if self.on_done:
            self.on_done()

    def remove(self) -> None:
        app = App.get_running_app()
        self._stop_listening()
        try:
            app.editor.set_narration(self.scene_id, None)
        except StoryBeamError as exc:
            self._notify(notice_for(exc), exc)
            return
        self._clear_notice()
        self.refresh()
        if self.on_done:
            self.on_done()

    def listen(self) -> None:
        """Play the new voice (as trimmed), else the scene's stored one."""
        self._stop_listening()
        path: str | None
        if self.pending is not None:
            audio = self.pending
            if self.start_slider is not None:
                try:
                    audio = trim(audio, self.start_slider.value, self.end_slider.value)
                except StoryBeamError as exc:
                    self._notify(notice_for(exc), exc)
                    return
            self.folder.mkdir(parents=True, exist_ok=True)
            preview = self.folder / f"listen-{int(time.time() * 1000)}.wav"
            preview.write_bytes(encode_wav(audio))
            path = str(preview)
        else:
            path = scene_voice_path(self.scene)
        sound = sound_loader(path) if path else None
        if sound is not None:
            sound.play()
            self.listening = sound

    def _stop_listening(self) -> None:
        if self.listening is not None:
            self.listening.stop()
            self.listening = None
        for old in self.folder.glob("listen-*.wav") if self.folder.is_dir() else []:
            old.unlink(missing_ok=True)

    def _closing(self) -> None:
        self.closed = True
        if self.recorder is not None:
            recorder, self.recorder = self.recorder, None
            Clock.unschedule(self._tick)
            recorder.cancel()
        self._stop_listening()


def voice_button(screen, **kwargs) -> IconButton:
    """The editor's *Voice* button: opens the :class:`NarrationPanel` of its scene."""
    app = App.get_running_app()
    scene = screen.scene
    has_voice = scene is not None and scene.narration is not None

    def open_panel() -> None:
        if screen.scene is None:
            return
        screen.narration_panel = NarrationPanel(screen.scene.id, on_done=screen.refresh)
        screen.narration_panel.open()
    kwargs.setdefault("size_hint_x", None)
    kwargs.setdefault("width", dp(90))
    return IconButton("voice", app.t("narration"), on_press=open_panel, background=[1, 0.85, 0.75, 1],
                      selected=has_voice, **kwargs)


__all__ = ["RECORDING_SETTING", "NarrationPanel", "NarrationPlayback", "voice_button", "recording_allowed",
           "recording_folder", "find_audio_files", "scene_voice_path", "AUDIO_SUFFIXES"]
