"""Play: preview the scene or the whole story with a scrubber, and the projector output.

The preview is the top-down animation of each character along its path. When a 3-D
renderer is available, frames come from :class:`app.player.render_thread.RenderThread`: with
Kivy GL (the default, every device) the thread answers scene descriptions
(:class:`ar.scene.SceneDescription`: retargeting, path following, tracking run there) and
this module draws them on the UI thread with :class:`app.ui.gl.KivyGLRenderer`, whose
offscreen texture is shown; with pyrender (desktop) the thread answers images (pyrender
must render on its own long-lived thread; two GL contexts on the Kivy thread crash).

The projector screen shows :mod:`app.player.stage`: the scene's 3-D characters rendered from the
projector's viewpoint through the tracked rig (a live camera with the profile's
calibration files, else the synthetic rig), with the tracking state in a corner;
*Preview* switches to the camera view (the light on the table, what the audience sees).
Without a 3-D renderer it falls back to the 2-D characters on black and says so.
"""
from __future__ import annotations

import numpy as np
from kivy.app import App
from kivy.clock import Clock
from kivy.graphics.texture import Texture
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.floatlayout import FloatLayout
from kivy.uix.image import Image
from kivy.uix.label import Label
from kivy.uix.screenmanager import Screen
from kivy.uix.slider import Slider
from kivy.uix.widget import Widget

from app.story import Story
from app.ui.gl import PROJECTOR_SUPERSAMPLE, KivyGLRenderer
from app.ui.narration import NarrationPlayback
from app.ui.story_end import Celebration, EndPanel, VideoSaver, can_save_video
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


def rgb_texture(rgb) -> Texture:
    """A Kivy texture of an (H, W, 3) uint8 image (rows top to bottom)."""
    h, w = rgb.shape[:2]
    texture = Texture.create(size=(w, h), colorfmt="rgb")
    texture.blit_buffer(rgb[::-1].tobytes(), colorfmt="rgb", bufferfmt="ubyte")
    return texture


class _Player:
    """Clock-driven playback state shared by the play and projector screens."""

    def __init__(self, screen: Screen, table: TableView, use_3d: bool = False, on_scene_time=None):
        self.screen, self.table = screen, table
        self.use_3d = use_3d
        self.on_scene_time = on_scene_time  # (scene, local time): the projector stage's request
        self.t = 0.0
        self.playing = False
        self.scene_only: str | None = None
        self._event = None
        self.on_time = None
        self.on_state = None  # called after every play / pause (the controls follow the state)
        self.on_end = None  # called when playing reaches the end
        self.narration = NarrationPlayback()  # the scene's voice, in step with the time line
        self.gl: KivyGLRenderer | None = None  # draws scene descriptions (made on the first)
        self.drawn_by: str | None = None  # "kivy-gl" / "pyrender": who drew the last 3-D frame

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
        if self.on_scene_time:
            self.on_scene_time(story.scenes[index], local)
        self.narration.update(story.scenes[index], local, self.playing)
        if self.on_time:
            self.on_time(self.t)

    def _show_frame(self, frame) -> None:
        """Show the render thread's answer: an (H, W, 3) uint8 image (pyrender) or an
        :class:`ar.scene.SceneDescription`, drawn here with Kivy GL (:mod:`app.ui.gl`)."""
        if isinstance(frame, np.ndarray):
            texture, self.drawn_by = rgb_texture(frame), "pyrender"
        else:
            if self.gl is None:
                self.gl = KivyGLRenderer()
            texture, self.drawn_by = self.gl.draw(frame), "kivy-gl"
        if texture is self.table.frame_texture:
            self.table.redraw()  # the same texture, new pixels
        else:
            self.table.frame_texture = texture


    def play(self) -> None:
        if self.t >= self.duration:
            self.t = 0.0
        self.playing = True
        story = self.story
        if story.scenes:
            index, local = locate(story, self.t, self.scene_only)
            self.narration.update(story.scenes[index], local, True)
        if self._event is None:
            self._event = Clock.schedule_interval(self._tick, 1.0 / FPS)
        if self.on_state:
            self.on_state()

    def pause(self) -> None:
        self.playing = False
        self.narration.stop()
        if self._event is not None:
            self._event.cancel()
            self._event = None
        if self.on_state:
            self.on_state()

    def _tick(self, dt: float) -> None:
        self.seek(self.t + dt)
        if self.t >= self.duration:
            self.pause()
            if self.on_end:
                self.on_end()


class _PlayerScreen(Screen):
    """A screen that rebuilds itself on entry and pauses its player on leaving."""

    def on_pre_enter(self, *args):
        self.refresh()

    def on_leave(self, *args):
        if getattr(self, "player", None):
            self.player.pause()

    def refresh(self) -> None:
        raise NotImplementedError


class PlayScreen(_PlayerScreen):
    """Preview with play/pause, a scrubber and scene / whole-story choice. The Play/Pause
    button always shows what a tap will do (the picture and word follow the player's
    state); the end of the story brings the celebration and then *again*, *home* and
    (when the teacher allows it) *save the video* (:mod:`app.ui.story_end`)."""

    celebration: Celebration | None = None
    end_panel: EndPanel | None = None
    saver: VideoSaver | None = None

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        self.celebration = self.end_panel = None
        self.layer = FloatLayout()
        root = filled(BoxLayout(orientation="vertical", padding=dp(8), spacing=dp(8), size_hint=(1, 1),
                                pos_hint={"x": 0, "y": 0}), (0.15, 0.15, 0.2, 1))
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
        self.player.on_state = self.sync_controls
        self.player.on_end = self.celebrate
        bar.add_widget(self.scrubber)
        self.scene_button = IconButton("walk", t("play_scene"), on_press=lambda: self.set_scope(True),
                                       size_hint_x=None, width=dp(120))
        self.story_button = IconButton("dance", t("play_story"), on_press=lambda: self.set_scope(False),
                                       size_hint_x=None, width=dp(120), selected=True)
        bar.add_widget(self.scene_button)
        bar.add_widget(self.story_button)
        root.add_widget(self.table)
        root.add_widget(bar)
        self.layer.add_widget(root)
        self.add_widget(self.layer)
        self.player.seek(0.0)
        self.sync_controls()

    def on_leave(self, *args):
        self.clear_end()
        return super().on_leave(*args)

    def set_scope(self, scene_only: bool) -> None:
        app = App.get_running_app()
        self.clear_end()
        self.player.scene_only = app.current_scene_id if scene_only else None
        self.scene_button.selected, self.story_button.selected = scene_only, not scene_only
        self.scrubber.max = max(self.player.duration, 0.01)
        self.player.seek(0.0)

    def toggle(self) -> None:
        if self.player.playing:
            self.player.pause()
        else:
            self.clear_end()
            self.player.play()

    def sync_controls(self) -> None:
        """The Play/Pause button shows what a tap does now."""
        t = App.get_running_app().t
        playing = self.player.playing
        self.play_button.icon = "pause" if playing else "play"
        self.play_button.text = t("pause") if playing else t("play")

    # -- the end -----------------------------------------------------------------------
    def celebrate(self) -> None:
        """The story (or scene) has ended: confetti and the chime, then the three choices."""
        self.clear_end()
        self.celebration = Celebration(on_done=self.show_end_choices, size_hint=(1, 1), pos_hint={"x": 0, "y": 0})
        self.layer.add_widget(self.celebration)

    def show_end_choices(self) -> None:
        app = App.get_running_app()
        if self.celebration is not None:
            self.layer.remove_widget(self.celebration)
            self.celebration = None
        save = self.save_video if can_save_video(app) and self.player.scene_only is None else None
        self.end_panel = filled(EndPanel(self.replay, app.go_home, save, size_hint=(0.7, 0.32),
                                         pos_hint={"center_x": 0.5, "center_y": 0.55}), (1, 0.97, 0.9, 0.95))
        self.layer.add_widget(self.end_panel)

    def clear_end(self) -> None:
        if self.celebration is not None:
            self.celebration.stop()
            self.layer.remove_widget(self.celebration)
            self.celebration = None
        if self.end_panel is not None:
            self.layer.remove_widget(self.end_panel)
            self.end_panel = None

    def replay(self) -> None:
        self.clear_end()
        self.player.seek(0.0)
        self.player.play()

    def save_video(self) -> None:
        app = App.get_running_app()
        if self.saver is None:
            self.saver = VideoSaver(app)
        self.saver.start()

    def _scrubbed(self, slider: Slider, value: float) -> None:
        if abs(value - self.player.t) > 1e-3:
            self.player.seek(value)

    def _time_changed(self, t: float) -> None:
        self.scrubber.value = t


class ProjectorScreen(_PlayerScreen):
    """Full-screen projector output: the scene's 3-D characters from the projector's
    viewpoint through the tracked rig (black = no light), the tracking state small in a
    corner. *Preview* shows the camera view instead (the light on the table). Without a
    3-D renderer: the 2-D characters on black (*Preview*: the place picture under them).

    *Full screen* is the projector mode for a one-display tablet whose screen is mirrored
    to the projector (HDMI, a pico projector): the window goes full screen and everything
    but the light is hidden (buttons would be projected onto the table); a finger held
    down anywhere for :attr:`LONG_PRESS_S` seconds leaves it. Taps do nothing there, so
    a child touching the tablet does not stop the show."""

    drawn_by: str | None = None  # "kivy-gl" / "pyrender": who drew the last light image
    gl = None  # the Kivy GL renderer of the light (made on the first description)
    STATE_COLOURS = {"tracking": (0.3, 0.8, 0.3, 1), "holding": (0.95, 0.7, 0.2, 1), "lost": (0.9, 0.3, 0.3, 1)}
    LONG_PRESS_S = 1.0
    projector_mode = False
    _long_press = None

    def enter_projector_mode(self) -> None:
        """Full screen, only the light: hide the controls and the state; a long press leaves."""
        from kivy.core.window import Window  # deferred: the window exists once the app runs

        self.projector_mode = True
        for w in (self.controls, self.state_label):
            w.opacity, w.disabled = 0, True
        Window.fullscreen = "auto"

    def leave_projector_mode(self) -> None:
        from kivy.core.window import Window  # deferred: as in enter_projector_mode

        if self._long_press is not None:
            self._long_press.cancel()
            self._long_press = None
        self.projector_mode = False
        self.controls.opacity, self.controls.disabled = 0.85, False
        self.state_label.opacity, self.state_label.disabled = 0.8, False
        Window.fullscreen = False

    def on_touch_down(self, touch):
        if not self.projector_mode:
            return super().on_touch_down(touch)
        self._cancel_long_press()
        self._held_touch = touch.uid
        self._long_press = Clock.schedule_once(lambda _dt: self.leave_projector_mode(), self.LONG_PRESS_S)
        return True  # the show goes on: a tap does nothing in projector mode

    def on_touch_up(self, touch):
        if self.projector_mode or touch.uid == getattr(self, "_held_touch", None):
            self._cancel_long_press()  # (the lift of the long press that left the mode is not a tap either)
            self._held_touch = None
            return True
        return super().on_touch_up(touch)

    def _cancel_long_press(self) -> None:
        if self._long_press is not None:
            self._long_press.cancel()
            self._long_press = None

    def on_leave(self, *args):
        if self.projector_mode:
            self.leave_projector_mode()
        App.get_running_app().release_rig_camera()  # the Kivy camera is on only while the stage shows
        App.get_running_app().close_projector_window()
        return super().on_leave(*args)


    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        root = FloatLayout()
        self.stage_view = "projector"
        self.last_stage_frame = None
        self.frames_shown = 0
        self.table = TableView(mode="projector", size_hint=(1, 1), pos_hint={"x": 0, "y": 0})
        root.add_widget(filled(Widget(size_hint=(1, 1)), (0, 0, 0, 1)))
        self.use_stage = app.stage_available()
        if self.use_stage:  # a Kivy camera choice: opened here, on the main thread, for the stage's live rig
            app.open_rig_camera()
            app.open_projector_window()  # a second display: the light in its own window there
        # with the 3-D stage the 2-D table is kept out of the widget tree: redrawing it
        # 30 times a second under the stage image would cost the render thread its CPU
        self.table_holder = FloatLayout(size_hint=(1, 1), pos_hint={"x": 0, "y": 0})
        if not self.use_stage:
            self.table_holder.add_widget(self.table)
        root.add_widget(self.table_holder)
        self.stage_image = Image(size_hint=(1, 1), pos_hint={"x": 0, "y": 0}, fit_mode="contain", opacity=0)
        root.add_widget(self.stage_image)
        self.state_label = Label(text="" if self.use_stage else t("flat_2d"), font_size=dp(13),
                                 color=(0.6, 0.6, 0.6, 1), size_hint=(None, None), size=(dp(260), dp(24)),
                                 pos_hint={"right": 0.99, "top": 0.99}, halign="right", opacity=0.8)
        self.state_label.bind(size=lambda lbl, s: setattr(lbl, "text_size", s))
        root.add_widget(self.state_label)
        self.player = _Player(self, self.table, on_scene_time=self._request_stage if self.use_stage else None)
        bar = BoxLayout(size_hint=(None, None), size=(dp(4 * 110), dp(BUTTON_DP)), pos_hint={"x": 0.01, "y": 0.01},
                        spacing=dp(6), opacity=0.85)
        bar.add_widget(IconButton("home", t("back"), on_press=lambda: app.go(app.projector_return)))
        bar.add_widget(IconButton("play", t("play"), on_press=self.restart))
        self.preview_button = IconButton("projector", t("preview"), on_press=self.toggle_preview)
        bar.add_widget(self.preview_button)
        self.fullscreen_button = IconButton("projector", t("projector_mode"), on_press=self.enter_projector_mode)
        bar.add_widget(self.fullscreen_button)
        self.controls = bar
        self.projector_mode = False
        root.add_widget(bar)
        self.add_widget(root)
        self.player.seek(0.0)
        self.player.play()

    def restart(self) -> None:
        self.player.seek(0.0)
        self.player.play()

    def toggle_preview(self) -> None:
        if self.use_stage:
            self.stage_view = "camera" if self.stage_view == "projector" else "projector"
            self.preview_button.selected = self.stage_view == "camera"
            self.player.seek(self.player.t)
            return
        self.table.mode = "preview" if self.table.mode == "projector" else "projector"
        self.preview_button.selected = self.table.mode == "preview"

    # -- the 3-D stage ----------------------------------------------------------------
    def _request_stage(self, scene, local_t: float) -> None:
        app = App.get_running_app()
        self._stage_at = (scene, local_t)
        if not app.stage_available():  # the renderer failed: back to the 2-D characters, and say so
            self.stage_image.opacity = 0
            if self.table.parent is None:
                self.table_holder.add_widget(self.table)
            self.state_label.text, self.state_label.color = app.t("flat_2d"), (0.6, 0.6, 0.6, 1)
            return
        app.request_stage_frame(scene, local_t, self.stage_view, self._show_stage)

    def _show_stage(self, frame) -> None:
        """A :class:`app.player.stage.StageFrame` from the render thread (on the UI thread)."""
        if self.manager is None or self.manager.current != self.name:
            return
        app = App.get_running_app()
        # the rig keeps moving while the story is paused or over: keep tracking and drawing
        # (newest request wins, so a playing story's own requests take over)
        scene, local_t = self._stage_at
        app.request_stage_frame(scene, local_t, self.stage_view, self._show_stage)
        self.last_stage_frame = frame
        self.frames_shown += 1
        texture = self._stage_texture(frame)
        if texture is self.stage_image.texture:
            self.stage_image.canvas.ask_update()  # the same texture, new pixels
        else:
            self.stage_image.texture = texture
        self.stage_image.opacity = 1
        if frame.projector is not None:  # the light on the projector's own display, when it has one
            app.feed_projector_window(frame.projector)
        rig = app.t("rig_live") if frame.live else app.t("rig_preview")
        self.state_label.text = f"{rig} · {app.t('track_' + frame.state)}"
        self.state_label.color = self.STATE_COLOURS.get(frame.state, (0.6, 0.6, 0.6, 1))


    def _stage_texture(self, frame):
        """The texture to show for ``frame``. A frame that carries a description (the
        Kivy GL path) has its light drawn here; when the stage wants the light back (the
        synthetic rig films it next frame) or a projector window shows it, it is read back
        (handed to the stage), and ``frame.projector`` (and ``frame.rgb`` for the projector
        view) filled in."""
        if frame.projector is not None or frame.description is None:  # drawn already (or nothing to draw)
            if frame.description is not None:
                self.drawn_by = "pyrender"
            return rgb_texture(frame.rgb)
        if self.gl is None:  # the projector's light: one sample per pixel (latency; see PROJECTOR_SUPERSAMPLE)
            self.gl = KivyGLRenderer(PROJECTOR_SUPERSAMPLE)
        self.drawn_by = "kivy-gl"
        if frame.light_sink is not None or App.get_running_app().projector_window is not None:
            light = self.gl.render(frame.description)  # read back: the rig films it, or the projector window shows it
            if frame.light_sink is not None:
                frame.light_sink(light)
            frame.projector = light
            if frame.view == "projector":
                frame.rgb = light
            texture = self.gl.out.texture
        else:
            texture = self.gl.draw(frame.description)
        return rgb_texture(frame.rgb) if frame.view == "camera" else texture


__all__ = ["PlayScreen", "ProjectorScreen", "locate"]
