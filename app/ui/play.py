"""Play: preview the scene or the whole story with a scrubber, and the projector output.

The preview is the top-down animation of each character along its path. When a 3-D
renderer is available, frames come from :class:`app.render_bridge.RenderThread` (pyrender
must render on its own long-lived thread; two GL contexts on the Kivy thread crash) and
are shown as a texture in the same view.
"""
from __future__ import annotations

from kivy.app import App
from kivy.clock import Clock
from kivy.graphics.texture import Texture
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.floatlayout import FloatLayout
from kivy.uix.screenmanager import Screen
from kivy.uix.slider import Slider
from kivy.uix.widget import Widget

from app.story import Story
from app.ui.table_view import TableView
from app.ui.widgets import BUTTON_DP, IconButton, filled

FPS = 30


def locate(story: Story, t: float, scene_id: str | None = None) -> tuple[int, float]:
    """(scene index, time inside that scene) for story time ``t``; with ``scene_id`` only
    that scene plays."""
    if scene_id is not None:
        return story.scene_index(scene_id), t
    for i, scene in enumerate(story.scenes):
        if t < scene.duration or i == len(story.scenes) - 1:
            return i, min(t, scene.duration)
        t -= scene.duration
    return 0, 0.0


class _Player:
    """Clock-driven playback state shared by the play and projector screens."""

    def __init__(self, screen: Screen, table: TableView, use_3d: bool = False):
        self.screen, self.table = screen, table
        self.use_3d = use_3d
        self.t = 0.0
        self.playing = False
        self.scene_only: str | None = None
        self._event = None
        self.on_time = None

    @property
    def story(self) -> Story:
        return App.get_running_app().editor.story

    @property
    def duration(self) -> float:
        if self.scene_only is not None:
            return self.story.scene(self.scene_only).duration
        return self.story.duration

    def seek(self, t: float) -> None:
        story = self.story
        if not story.scenes:
            return
        self.t = min(max(t, 0.0), self.duration)
        index, local = locate(story, self.t, self.scene_only)
        if self.table.scene is not story.scenes[index]:
            self.table.frame_texture = None  # a frame of the previous scene must not linger
            self.table.scene = story.scenes[index]
        self.table.time = local
        if self.use_3d:
            App.get_running_app().request_frame(story.scenes[index], local, self._show_frame)
        if self.on_time:
            self.on_time(self.t)

    def _show_frame(self, rgb) -> None:
        """Show a rendered frame (HxWx3 uint8) from the render thread as a texture."""
        h, w = rgb.shape[:2]
        texture = Texture.create(size=(w, h), colorfmt="rgb")
        texture.blit_buffer(rgb[::-1].tobytes(), colorfmt="rgb", bufferfmt="ubyte")
        self.table.frame_texture = texture

    def play(self) -> None:
        if self.t >= self.duration:
            self.t = 0.0
        self.playing = True
        if self._event is None:
            self._event = Clock.schedule_interval(self._tick, 1.0 / FPS)

    def pause(self) -> None:
        self.playing = False
        if self._event is not None:
            self._event.cancel()
            self._event = None

    def _tick(self, dt: float) -> None:
        self.seek(self.t + dt)
        if self.t >= self.duration:
            self.pause()


class PlayScreen(Screen):
    """Preview with play/pause, a scrubber and scene / whole-story choice."""

    def on_pre_enter(self, *args):
        self.refresh()

    def on_leave(self, *args):
        if getattr(self, "player", None):
            self.player.pause()

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        root = filled(BoxLayout(orientation="vertical", padding=dp(8), spacing=dp(8)), (0.15, 0.15, 0.2, 1))
        self.table = TableView(mode="preview")
        self.player = _Player(self, self.table, use_3d=True)
        bar = BoxLayout(size_hint_y=None, height=dp(BUTTON_DP), spacing=dp(8))
        bar.add_widget(IconButton("home", t("back"), on_press=lambda: app.go("editor"), size_hint_x=None,
                                  width=dp(100)))
        self.play_button = IconButton("play", t("play"), on_press=self.toggle, size_hint_x=None, width=dp(100),
                                      background=[0.75, 0.95, 0.75, 1])
        bar.add_widget(self.play_button)
        self.scrubber = Slider(min=0, max=max(self.player.duration, 0.01), value=0, cursor_size=(dp(56), dp(56)))
        self.scrubber.bind(value=self._scrubbed)
        self.player.on_time = self._time_changed
        bar.add_widget(self.scrubber)
        self.scene_button = IconButton("walk", t("play_scene"), on_press=lambda: self.set_scope(True),
                                       size_hint_x=None, width=dp(120))
        self.story_button = IconButton("dance", t("play_story"), on_press=lambda: self.set_scope(False),
                                       size_hint_x=None, width=dp(120), selected=True)
        bar.add_widget(self.scene_button)
        bar.add_widget(self.story_button)
        root.add_widget(self.table)
        root.add_widget(bar)
        self.add_widget(root)
        self.player.seek(0.0)

    def set_scope(self, scene_only: bool) -> None:
        app = App.get_running_app()
        self.player.scene_only = app.current_scene_id if scene_only else None
        self.scene_button.selected, self.story_button.selected = scene_only, not scene_only
        self.scrubber.max = max(self.player.duration, 0.01)
        self.player.seek(0.0)

    def toggle(self) -> None:
        t = App.get_running_app().t
        if self.player.playing:
            self.player.pause()
        else:
            self.player.play()
        self.play_button.icon = "pause" if self.player.playing else "play"
        self.play_button.text = t("pause") if self.player.playing else t("play")

    def _scrubbed(self, slider: Slider, value: float) -> None:
        if abs(value - self.player.t) > 1e-3:
            self.player.seek(value)

    def _time_changed(self, t: float) -> None:
        self.scrubber.value = t
        if not self.player.playing:
            app = App.get_running_app()
            self.play_button.icon, self.play_button.text = "play", app.t("play")


class ProjectorScreen(Screen):
    """What the projector shows: black background, characters only; "preview" shows the
    scene picture underneath so a child can check it on the tablet."""

    def on_pre_enter(self, *args):
        self.refresh()

    def on_leave(self, *args):
        if getattr(self, "player", None):
            self.player.pause()

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        root = FloatLayout()
        self.table = TableView(mode="projector", size_hint=(1, 1), pos_hint={"x": 0, "y": 0})
        root.add_widget(filled(Widget(size_hint=(1, 1)), (0, 0, 0, 1)))
        root.add_widget(self.table)
        self.player = _Player(self, self.table)
        bar = BoxLayout(size_hint=(None, None), size=(dp(3 * 110), dp(BUTTON_DP)), pos_hint={"x": 0.01, "y": 0.01},
                        spacing=dp(6), opacity=0.85)
        bar.add_widget(IconButton("home", t("back"), on_press=lambda: app.go(app.projector_return)))
        bar.add_widget(IconButton("play", t("play"), on_press=self.restart))
        self.preview_button = IconButton("projector", t("preview"), on_press=self.toggle_preview)
        bar.add_widget(self.preview_button)
        root.add_widget(bar)
        self.add_widget(root)
        self.player.seek(0.0)
        self.player.play()

    def restart(self) -> None:
        self.player.seek(0.0)
        self.player.play()

    def toggle_preview(self) -> None:
        self.table.mode = "preview" if self.table.mode == "projector" else "projector"
        self.preview_button.selected = self.table.mode == "preview"


__all__ = ["PlayScreen", "ProjectorScreen", "locate"]
