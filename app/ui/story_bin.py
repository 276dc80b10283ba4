"""Managing stories: the bin (teacher mode) and naming a story by picture.

* :class:`RenameView` -- a child names a story without typing: one of the cover pictures
  (:data:`app.story.COVER_PICTURES`: the characters and the places) on one of the cover
  colours, and the name said aloud (the microphone button records at most
  :data:`VOICE_NAME_SECONDS`, through the narration recorder -- :mod:`app.services.recording`
  -- into a story asset named like a narration, so packages carry it and pruning keeps
  it); in teacher mode a text field for a typed title too. Saved through
  :meth:`app.story.ProfileStore.rename_story` (one transaction).
* :class:`BinView` -- the teacher's bin: every binned story as a tile with *bring back*,
  and *empty the bin* (deletes for good: rows, then assets).

A child's *delete* on the home screen only moves the story to the bin
(:meth:`app.story.ProfileStore.bin_story`), so nothing a child taps is final.
"""
from __future__ import annotations

from kivy.app import App
from kivy.clock import Clock
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.gridlayout import GridLayout
from kivy.uix.label import Label
from kivy.uix.modalview import ModalView
from kivy.uix.scrollview import ScrollView
from kivy.uix.textinput import TextInput

import app.ui.narration as narration
from app.services.recording import ChunkRecorder
from app.story import COVER_COLOURS, COVER_PICTURES, Cover, Narration, StorageError, encode_wav, read_audio
from app.story.narration import asset_name
from app.ui.widgets import IconButton, big_label, filled
from retrieval.errors import StoryBeamError

#: the longest name said aloud (seconds)
VOICE_NAME_SECONDS = 5.0


def play_asset(story_id: str, asset: str) -> None:
    """Play a story's recorded asset (a name said aloud) through the narration's sound loader."""
    app = App.get_running_app()
    sound = narration.sound_loader(str(app.store.asset_path(story_id, asset)))
    if sound is not None:
        sound.play()


class RenameView(ModalView):
    """Pick a picture and a colour (and, in teacher mode, type a title); OK saves."""

    def __init__(self, story_id: str, on_done=None, **kwargs):
        super().__init__(size_hint=(0.9, 0.85), auto_dismiss=True, **kwargs)
        app = App.get_running_app()
        t = app.t
        self.story_id, self.on_done = story_id, on_done
        story = app.store.load_story(story_id)
        self.picture = story.cover.picture if story.cover else COVER_PICTURES[0]
        self.colour = story.cover.colour if story.cover else 0
        self.voice = story.cover.voice if story.cover else None
        box = filled(BoxLayout(orientation="vertical", padding=dp(16), spacing=dp(12)), (1, 0.97, 0.9, 1))
        pictures = GridLayout(cols=6, spacing=dp(8))
        self.picture_buttons = {}
        for name in COVER_PICTURES:
            b = IconButton(name, "", on_press=lambda name=name: self.choose_picture(name),
                           selected=name == self.picture)
            self.picture_buttons[name] = b
            pictures.add_widget(b)
        box.add_widget(pictures)
        colours = BoxLayout(size_hint_y=None, height=dp(76), spacing=dp(8))
        self.colour_buttons = []
        for k, rgb in enumerate(COVER_COLOURS):
            b = IconButton("", "", on_press=lambda k=k: self.choose_colour(k), selected=k == self.colour,
                           background=[c / 255 for c in rgb] + [1])
            self.colour_buttons.append(b)
            colours.add_widget(b)
        box.add_widget(colours)
        voice_row = BoxLayout(size_hint_y=None, height=dp(76), spacing=dp(12))
        self.recorder: ChunkRecorder | None = None
        self.make_source, _why = narration.recorder_finder()
        self.mic_button = IconButton("mic", t("say_name"), on_press=self.toggle_voice,
                                     background=[1.0, 0.85, 0.85, 1])
        self.listen_button = IconButton("play", t("listen"), on_press=self.listen, disabled=self.voice is None)
        if self.make_source is not None:  # no microphone here: no button (the reason is in the log)
            voice_row.add_widget(self.mic_button)
        voice_row.add_widget(self.listen_button)
        box.add_widget(voice_row)
        self.title_input = None
        if app.teacher_unlocked:  # typing is for grown-ups
            self.title_input = TextInput(text=story.title, multiline=False, font_size=dp(20), size_hint_y=None,
                                         height=dp(48))
            box.add_widget(self.title_input)
        row = BoxLayout(size_hint_y=None, height=dp(76), spacing=dp(12))
        row.add_widget(IconButton("home", t("back"), on_press=self.dismiss))
        self.ok_button = IconButton("tick", t("ok"), on_press=self.save, background=[0.75, 0.95, 0.75, 1])
        row.add_widget(self.ok_button)
        box.add_widget(row)
        self.add_widget(box)

    def choose_picture(self, name: str) -> None:
        self.picture = name
        for n, b in self.picture_buttons.items():
            b.selected = n == name

    def choose_colour(self, k: int) -> None:
        self.colour = k
        for i, b in enumerate(self.colour_buttons):
            b.selected = i == k

    def toggle_voice(self) -> None:
        """Start recording the name, or stop and keep it as a story asset."""
        app = App.get_running_app()
        if self.recorder is None:
            try:
                self.recorder = ChunkRecorder(self.make_source(), narration.recording_folder(app.db_path),
                                              limit_seconds=VOICE_NAME_SECONDS,
                                              on_limit=lambda: Clock.schedule_once(lambda dt: self.toggle_voice(), 0))
                self.recorder.start()
            except (StoryBeamError, OSError, RuntimeError) as exc:
                self.recorder = None
                app.show_message(app.t("error", why=str(exc)))
                return
            self.mic_button.icon, self.mic_button.selected = "pause", True
            return
        recorder, self.recorder = self.recorder, None
        self.mic_button.icon, self.mic_button.selected = "mic", False
        try:
            path = recorder.stop()
            try:
                audio = read_audio(path)
            finally:
                path.unlink(missing_ok=True)
            wav = encode_wav(audio)
            name = asset_name(wav)
            app.store.put_asset(self.story_id, name, wav)
        except StoryBeamError as exc:
            app.show_message(app.t("error", why=str(exc)))
            return
        self.voice = Narration(name, round(audio.seconds, 6))
        self.listen_button.disabled = False

    def listen(self) -> None:
        if self.voice is not None:
            play_asset(self.story_id, self.voice.asset)

    def on_dismiss(self) -> None:
        if self.recorder is not None:
            self.recorder.cancel()
            self.recorder = None

    def save(self) -> None:
        if self.recorder is not None:
            self.toggle_voice()
        app = App.get_running_app()
        title = self.title_input.text.strip() if self.title_input is not None else None
        try:
            app.store.rename_story(self.story_id, title=title, cover=Cover(self.picture, self.colour, self.voice))
        except StorageError as exc:
            app.show_message(app.t("error", why=str(exc)))
            return
        self.dismiss()
        if self.on_done:
            self.on_done()


class BinView(ModalView):
    """The teacher's bin: bring a story back, or empty the bin."""

    def __init__(self, on_change=None, **kwargs):
        super().__init__(size_hint=(0.85, 0.8), auto_dismiss=True, **kwargs)
        self.on_change = on_change
        self.rebuild()

    def rebuild(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        box = filled(BoxLayout(orientation="vertical", padding=dp(16), spacing=dp(12)), (1, 0.97, 0.9, 1))
        box.add_widget(big_label(t("story_bin"), 26, size_hint_y=None, height=dp(40)))
        grid = GridLayout(cols=1, spacing=dp(8), size_hint_y=None)
        grid.bind(minimum_height=grid.setter("height"))
        self.restore_buttons = {}
        for summary in app.store.binned_stories():
            row = BoxLayout(size_hint_y=None, height=dp(64), spacing=dp(8))
            row.add_widget(Label(text=summary.title or summary.id, font_size=dp(18), color=(0.1, 0.1, 0.15, 1)))
            b = IconButton("undo", t("restore"), on_press=lambda sid=summary.id: self.restore(sid), size_hint_x=None,
                           width=dp(150))
            self.restore_buttons[summary.id] = b
            row.add_widget(b)
            grid.add_widget(row)
        scroll = ScrollView(do_scroll_x=False)
        scroll.add_widget(grid)
        box.add_widget(scroll)
        row = BoxLayout(size_hint_y=None, height=dp(76), spacing=dp(12))
        row.add_widget(IconButton("home", t("back"), on_press=self.dismiss))
        self.empty_button = IconButton("bin", t("empty_bin"), on_press=self.empty, background=[1, 0.8, 0.8, 1])
        row.add_widget(self.empty_button)
        box.add_widget(row)
        self.add_widget(box)

    def restore(self, story_id: str) -> None:
        App.get_running_app().store.restore_story(story_id)
        self.rebuild()
        if self.on_change:
            self.on_change()

    def empty(self) -> None:
        app = App.get_running_app()
        n = app.store.empty_bin()
        app.store.log_activity("empty bin", detail=str(n))
        app.show_message(app.t("bin_emptied", n=n))
        self.rebuild()
        if self.on_change:
            self.on_change()


__all__ = ["RenameView", "BinView", "VOICE_NAME_SECONDS", "play_asset"]
