"""Home: big tiles of saved stories and a "new story" tile that asks for the arc.

Each tile shows the story's first place and cast, its cover (the name by picture, when
it has one) and two small picture buttons: *name* (:class:`app.ui.story_bin.RenameView`)
and *bin* (the story moves to the teacher's bin: :meth:`app.story.ProfileStore.bin_story`;
nothing is deleted for good from here)."""
from __future__ import annotations

from kivy.app import App
from kivy.graphics import Color, Ellipse, RoundedRectangle, StencilPop, StencilPush, StencilUnUse, StencilUse
from kivy.metrics import dp
from kivy.uix.behaviors import ButtonBehavior
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.gridlayout import GridLayout
from kivy.uix.label import Label
from kivy.uix.modalview import ModalView
from kivy.uix.screenmanager import Screen
from kivy.uix.scrollview import ScrollView

from app.story import COVER_COLOURS, Cover, Scene, StorageError, StorySummary
from app.ui.art import draw_background, draw_character_badge, draw_icon
from app.ui.story_bin import RenameView, play_asset
from app.ui.widgets import BUTTON_DP, IconButton, big_label, filled


class StoryTile(ButtonBehavior, BoxLayout):
    """A saved story: a picture of its first scene, its title and scene count."""

    def __init__(self, summary: StorySummary, title: str, subtitle: str, first_scene: Scene | None,
                 cover: Cover | None = None, on_rename=None, on_bin=None, **kwargs):
        super().__init__(orientation="vertical", padding=dp(8), spacing=dp(4), **kwargs)
        self.story_id = summary.id
        self.first_scene = first_scene
        self.cover = cover
        self.picture = BoxLayout()
        self.add_widget(self.picture)
        tools = BoxLayout(size_hint=(1, None), height=dp(52), spacing=dp(8))
        self.rename_button = IconButton("rename", "", on_press=on_rename, size_hint_x=None, width=dp(64),
                                        background=[0.85, 0.93, 1.0, 1])
        self.bin_button = IconButton("bin", "", on_press=on_bin, size_hint_x=None, width=dp(64),
                                     background=[1.0, 0.88, 0.85, 1])
        tools.add_widget(Label())
        self.name_button = None
        if cover is not None and cover.voice is not None:  # the name said aloud
            self.name_button = IconButton("play", "", on_press=lambda: play_asset(summary.id, cover.voice.asset),
                                          size_hint_x=None, width=dp(64), background=[0.85, 1.0, 0.85, 1])
            tools.add_widget(self.name_button)
        tools.add_widget(self.rename_button)
        tools.add_widget(self.bin_button)
        self.add_widget(Label(text=title, font_size=dp(20), color=(0.1, 0.1, 0.15, 1), size_hint_y=None,
                              height=dp(30), shorten=True, text_size=(dp(200), None), halign="center"))
        self.add_widget(Label(text=subtitle, font_size=dp(15), color=(0.3, 0.3, 0.35, 1), size_hint_y=None,
                              height=dp(22)))
        self.add_widget(tools)
        self.bind(pos=self._redraw, size=self._redraw, state=self._redraw)
        self.picture.bind(pos=self._redraw, size=self._redraw)

    def _redraw(self, *_: object) -> None:
        self.canvas.before.clear()
        k = 0.88 if self.state == "down" else 1.0
        with self.canvas.before:
            Color(k, k, k, 1)
            RoundedRectangle(pos=self.pos, size=self.size, radius=[dp(18)])
            p = self.picture
            StencilPush()
            RoundedRectangle(pos=p.pos, size=p.size, radius=[dp(12)])
            StencilUse()
            if self.first_scene is not None:
                draw_background(self.first_scene.background, p.x, p.y, p.width, p.height)
                for i, c in enumerate(self.first_scene.characters[:4]):
                    draw_character_badge(c.kind, p.x + dp(30) + i * dp(44), p.y + dp(30), dp(17))
            else:  # the story could not be read: a grey tile, still deletable by a teacher
                Color(0.7, 0.7, 0.7, 1)
                RoundedRectangle(pos=p.pos, size=p.size)
            if self.cover is not None:  # the name by picture, on its colour, in the corner
                r = min(p.height * 0.42, dp(40))
                cx, cy = p.right - r - dp(6), p.top - r - dp(6)
                Color(*(c / 255 for c in COVER_COLOURS[self.cover.colour]))
                Ellipse(pos=(cx - r, cy - r), size=(2 * r, 2 * r))
                draw_icon(self.cover.picture, cx - 0.65 * r, cy - 0.65 * r, 1.3 * r)
            StencilUnUse()
            RoundedRectangle(pos=p.pos, size=p.size, radius=[dp(12)])
            StencilPop()


class HomeScreen(Screen):
    """Saved stories as tiles, most recent first; the first tile makes a new story."""

    def on_pre_enter(self, *args):
        self.refresh()

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        root = filled(BoxLayout(orientation="vertical", padding=dp(16), spacing=dp(12)), (0.98, 0.95, 0.86, 1))
        bar = BoxLayout(size_hint_y=None, height=dp(BUTTON_DP), spacing=dp(12))
        self.title_label = big_label(t("my_stories"), 30, halign="left", size_hint_y=1)
        bar.add_widget(self.title_label)
        self.language_button = IconButton("language", t("language"), on_press=app.toggle_language,
                                          size_hint_x=None, width=dp(110))
        bar.add_widget(self.language_button)
        self.teacher_button = IconButton("teacher", t("teacher"), on_press=lambda: app.go("pin"),
                                         size_hint_x=None, width=dp(110))
        bar.add_widget(self.teacher_button)
        root.add_widget(bar)
        grid = GridLayout(cols=4, spacing=dp(16), size_hint_y=None, row_default_height=dp(220),
                          row_force_default=True, col_default_width=dp(290), col_force_default=True)
        grid.bind(minimum_height=grid.setter("height"))
        new_tile = IconButton("add", t("new_story"), on_press=self.ask_arc, font_size=dp(20),
                              background=[1.0, 0.82, 0.35, 1])
        new_tile.story_id = None
        self.new_tile = new_tile
        grid.add_widget(new_tile)
        self.tiles: list[StoryTile] = []
        for n, summary in enumerate(app.store.list_stories() if app.store else []):
            first_scene, cover = None, None
            try:
                story = app.store.load_story(summary.id)
                first_scene = story.scenes[0] if story.scenes else Scene()
                cover = story.cover
            except StorageError:
                pass
            title = summary.title or t("story_n", n=len(app.store.list_stories()) - n)
            tile = StoryTile(summary, title, t("scenes_n", n=summary.scene_count), first_scene, cover,
                             on_rename=lambda sid=summary.id: self.rename(sid),
                             on_bin=lambda sid=summary.id: self.to_bin(sid))
            tile.bind(on_release=lambda tile_: app.open_story(tile_.story_id))
            grid.add_widget(tile)
            self.tiles.append(tile)
        self.grid = grid
        scroll = ScrollView(do_scroll_x=False)
        scroll.add_widget(grid)
        root.add_widget(scroll)
        self.add_widget(root)

    def rename(self, story_id: str) -> None:
        """Name the story by picture (typed too, in teacher mode)."""
        try:
            self.rename_view = RenameView(story_id, on_done=self.refresh)
        except StorageError as exc:
            App.get_running_app().show_message(App.get_running_app().t("error", why=str(exc)))
            return
        self.rename_view.open()

    def to_bin(self, story_id: str) -> None:
        """Move the story to the teacher's bin (a way back: teacher mode, *Bin*)."""
        app = App.get_running_app()
        app.store.bin_story(story_id)
        app.store.log_activity("bin story", story_id)
        self.refresh()

    def ask_arc(self) -> None:
        """Pick the story's shape with three big buttons (no typing)."""
        app = App.get_running_app()
        t = app.t
        view = ModalView(size_hint=(0.8, 0.55), auto_dismiss=True)
        box = filled(BoxLayout(orientation="vertical", padding=dp(20), spacing=dp(16)), (1, 0.97, 0.9, 1))
        box.add_widget(big_label(t("choose_arc"), 26))
        row = BoxLayout(spacing=dp(16))
        for arc, icon in (("short", "walk"), ("classic", "jump"), ("free", "dance")):
            def choose(arc=arc):
                view.dismiss()
                app.new_story(arc)
            row.add_widget(IconButton(icon, t(f"arc_{arc}"), on_press=choose, font_size=dp(18),
                                      background=[0.85, 0.93, 1.0, 1]))
        box.add_widget(row)
        view.add_widget(box)
        self.arc_view = view
        view.open()
