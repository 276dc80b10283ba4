"""Managing stories: the bin (teacher mode) and naming a story by picture.

* :class:`RenameView` -- a child names a story without typing: one of the cover pictures
  (:data:`app.story.COVER_PICTURES`: the characters and the places) on one of the cover
  colours; in teacher mode a text field for a typed title too. Saved through
  :meth:`app.story.ProfileStore.rename_story` (one transaction).
* :class:`BinView` -- the teacher's bin: every binned story as a tile with *bring back*,
  and *empty the bin* (deletes for good: rows, then assets).

A child's *delete* on the home screen only moves the story to the bin
(:meth:`app.story.ProfileStore.bin_story`), so nothing a child taps is final.
"""
from __future__ import annotations

from kivy.app import App
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.gridlayout import GridLayout
from kivy.uix.label import Label
from kivy.uix.modalview import ModalView
from kivy.uix.scrollview import ScrollView
from kivy.uix.textinput import TextInput

from app.story import COVER_COLOURS, COVER_PICTURES, Cover, StorageError
from app.ui.widgets import IconButton, big_label, filled


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

    def save(self) -> None:
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


__all__ = ["RenameView", "BinView"]
