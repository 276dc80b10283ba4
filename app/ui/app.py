"""The StoryBeam Kivy application: screens, the open story and its autosave.

Import this module only after the Kivy environment is set (see
:func:`app.ui.env.prepare_kivy_env`): Kivy reads its settings at import time.
It imports the story, the services and the light part of :mod:`app.player` only: the
3-D renderers are loaded by the render thread (``renderer_factory``), when there is one.
"""
from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Callable

from kivy.app import App
from kivy.clock import Clock
from kivy.core.text import DEFAULT_FONT, LabelBase
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.modalview import ModalView
from kivy.uix.screenmanager import NoTransition, ScreenManager
from kivy.utils import platform

from app.paths import FONT_PATH
from app.player import RenderThread, StageJob, app_exporter, available
from app.player.app_renderer import has_calibration, kivy_camera_index
from app.services import MotionCatalog, ThumbnailCache
from app.story import ProfileStore, Scene, StorageError, Story, StoryEditor, demo_story, prune_narrations
from app.ui.editor import EditorScreen
from app.ui.home import HomeScreen
from app.ui.play import PlayScreen, ProjectorScreen
from app.ui.projector_window import ProjectorWindow, second_display
from app.ui.strings import LANGUAGES, tr
from app.ui.teacher import CalibrationScreen, PinScreen, TeacherScreen
from app.ui.widgets import big_label, filled
from retrieval.errors import StoryBeamError

log = logging.getLogger(__name__)


def register_fonts() -> None:
    """Make the bundled M+ font (Latin + kana + kanji) the default for every label."""
    if FONT_PATH.is_file():
        LabelBase.register(DEFAULT_FONT, str(FONT_PATH))
    else:  # still usable in English with Kivy's own Roboto
        log.warning("font %s missing: Japanese text will not render", FONT_PATH)


class StoryBeamApp(App):
    """Holds the profile store, the open story's editor and the language."""

    title = "StoryBeam"

    def __init__(self, db_path: str | Path, lang: str | None = None, story_id: str | None = None,
                 demo: bool = False, start_screen: str | None = None,
                 catalog: MotionCatalog | None = None, renderer_factory: Callable | None = None,
                 act_camera: str | None = None, **kwargs):
        super().__init__(**kwargs)
        self.db_path = Path(db_path)
        self.requested_lang = lang
        self.requested_story = story_id
        self.demo = demo
        self.start_screen = start_screen
        self.catalog = catalog if catalog is not None else MotionCatalog()
        self.renderer_factory = renderer_factory
        self.renderer = None
        self.video_exporter = None
        self.video_view = "story"  # MP4s: the story film (app.player.story_film); "camera" is the rig's view
        self.store: ProfileStore | None = None
        self.storage_problem: str | None = None
        self.editor: StoryEditor | None = None
        self.current_scene_id: str | None = None
        self.selected_character_id: str | None = None
        self.teacher_unlocked = False
        self.teacher_session_id: int | None = None
        self.projector_return = "editor"
        self.lang = "ja"
        #: the rig's Kivy camera while the projector screen shows (:meth:`open_rig_camera`)
        self.rig_camera = None
        self._rig_camera_failed = False  # said once per visit to the projector screen
        #: ``index -> Kivy Camera-like object`` for :class:`app.ui.kivy_camera.KivyCameraSource`
        #: (tests give a stand-in; None = ``kivy.core.camera.Camera``)
        self.kivy_camera_factory: Callable | None = None
        #: the camera "Act it out" films the child with (:mod:`app.ui.act_view`): the Kivy
        #: camera (``kivy:N``; the tablet's front camera ``kivy:1`` on Android), a device number,
        #: or a video file / image folder played looped (desktop, tests)
        self.act_camera = act_camera or ("kivy:1" if platform == "android" else "0")
        #: the projector's own window on a second display while the projector screen shows
        #: (:mod:`app.ui.projector_window`)
        self.projector_window = None

    # -- set-up ---------------------------------------------------------------------
    @property
    def profile_dir(self) -> Path:
        return self.db_path.parent

    @property
    def export_dir(self) -> Path:
        return self.db_path.with_name(self.db_path.name + ".exports")

    @property
    def inbox_dir(self) -> Path:
        return self.db_path.with_name(self.db_path.name + ".inbox")

    def _open_store(self) -> None:
        """Open the profile; if it is refused, keep the children working in a fresh
        profile beside it and say so (the refused file is left untouched)."""
        try:
            self.store = ProfileStore(self.db_path)
        except StorageError as exc:
            self.storage_problem = str(exc)
            log.error("%s", exc)
            rescue = self.db_path.with_name(self.db_path.stem + ".recovered.db")
            self.store = ProfileStore(rescue)
            self.db_path = rescue

    def build(self):
        register_fonts()
        self._open_store()
        saved_lang = self.store.get_setting("language")
        self.lang = self.requested_lang or (saved_lang if saved_lang in LANGUAGES else "ja")
        if self.renderer_factory is not None:
            self.renderer = RenderThread(self.renderer_factory,
                                         lambda cb, frame: Clock.schedule_once(lambda dt: cb(frame), 0))
        if available() is None:
            self.video_exporter = app_exporter(self.video_view,  # narrated scenes: their voice from the assets
                                               narration_dirs=lambda story: self.store.story_assets_dir(story.id))
        self.sm = ScreenManager(transition=NoTransition())
        for screen in (HomeScreen(name="home"), EditorScreen(name="editor"), PlayScreen(name="play"),
                       ProjectorScreen(name="projector"), PinScreen(name="pin"), TeacherScreen(name="teacher"),
                       CalibrationScreen(name="calibration")):
            self.sm.add_widget(screen)
        if self.demo:
            story = demo_story()
            if not self.store.has_story(story.id):
                self.store.save_story(story)
            self.requested_story = story.id
        if self.requested_story:
            self.open_story(self.requested_story, switch=False)
            self.sm.current = self.start_screen or "editor"
        elif self.start_screen in ("pin", "home"):
            self.sm.current = self.start_screen
        else:
            self.sm.current = "home"
        if hasattr(self.sm.current_screen, "refresh"):  # the first screen gets no on_pre_enter
            self.sm.current_screen.refresh()
        if self.storage_problem:
            Clock.schedule_once(lambda dt: self.show_message(self.t("storage_problem", why=self.storage_problem)), 0)
        return self.sm

    def on_stop(self):
        self.release_rig_camera()
        self.close_projector_window()
        if self.renderer is not None:
            self.renderer.stop()
        if self.store is not None:
            self.store.close()

    # -- language -------------------------------------------------------------------
    def t(self, key: str, **values: object) -> str:
        return tr(key, self.lang, **values)

    def toggle_language(self) -> None:
        self.set_language("en" if self.lang == "ja" else "ja")

    def set_language(self, lang: str) -> None:
        self.lang = lang
        self.store.set_setting("language", lang)
        screen = self.sm.current_screen
        if hasattr(screen, "refresh"):
            screen.refresh()

    # -- navigation -----------------------------------------------------------------
    def go(self, name: str) -> None:
        if name in ("editor", "play", "projector") and self.editor is None:
            name = "home"
        if name == "projector":
            self.projector_return = self.sm.current if self.sm.current != "projector" else "editor"
        self.sm.current = name

    def go_home(self) -> None:
        self.go("home")

    def open_story(self, story_id: str, switch: bool = True) -> bool:
        try:
            story = self.store.load_story(story_id)
        except StorageError as exc:
            self.show_message(self.t("error", why=str(exc)))
            return False
        prune_narrations(self.store, story)  # voices the saved story no longer uses (app.story.narration)
        self._edit(story)
        self.store.log_activity("open story", story.id)
        if switch:
            self.go("editor")
        return True

    def new_story(self, arc: str) -> Story:
        # a stable default title (the home screen must not renumber stories as they change)
        story = Story.new(arc, title=self.t("story_n", n=len(self.store.list_stories()) + 1))
        self.store.save_story(story)
        self.store.log_activity("new story", story.id, arc)
        self._edit(story)
        self.go("editor")
        return story

    def _edit(self, story: Story) -> None:
        self.editor = StoryEditor(story)
        self.editor.add_listener(self._autosave)
        self.current_scene_id = story.scenes[0].id if story.scenes else None
        self.selected_character_id = None

    def _autosave(self, story: Story, label: str) -> None:
        """Every change is committed at once (see app.storage for why this is safe)."""
        try:
            self.store.save_story(story)
            self.store.log_activity("edit", story.id, label)
        except StorageError as exc:
            self.show_message(self.t("error", why=str(exc)))

    def present_all(self) -> None:
        """Teacher: play every story on the projector one after another (newest last)."""
        stories = []
        for summary in reversed(self.store.list_stories()):
            try:
                stories.append(self.store.load_story(summary.id))
            except StorageError:
                continue
        if not stories:
            return
        combined = Story(title="all", arc="free", scenes=[s for story in stories for s in story.scenes][:60])
        self.editor = StoryEditor(combined)  # not autosaved: a read-only show
        self.projector_return = "teacher"
        self.sm.current = "projector"

    # -- feedback and rendering -----------------------------------------------------
    def show_message(self, text: str, seconds: float = 4.0) -> None:
        view = ModalView(size_hint=(0.6, 0.3))
        box = filled(BoxLayout(padding=dp(16)), (1, 0.95, 0.85, 1))
        label = big_label(text, 20, size_hint_y=1)
        label.bind(size=lambda lbl, s: setattr(lbl, "text_size", s))
        label.halign, label.valign = "center", "middle"
        box.add_widget(label)
        view.add_widget(box)
        view.open()
        self.last_message = text
        Clock.schedule_once(lambda dt: view.dismiss(), seconds)

    def request_frame(self, scene, t: float, callback) -> None:
        """Ask the 3-D renderer (if any) for a frame; the 2-D preview is always drawn."""
        if self.renderer is not None and self.renderer.alive:
            self.renderer.request(Scene.from_dict(scene.to_dict()), t, callback)  # a copy: the UI owns the original

    def motion_thumbnails(self):
        """The stick-figure thumbnails of the motion library (made on first use)."""
        if getattr(self, "_thumbnails", None) is None:
            self._thumbnails = ThumbnailCache(self.catalog.motions_dir)
        return self._thumbnails

    def stage_available(self) -> bool:
        """True when the render thread can draw the projector stage (:mod:`app.player.stage`):
        its renderer factory says so (``supports_stage``) and it has not failed."""
        return (self.renderer is not None and self.renderer.alive
                and bool(getattr(self.renderer_factory, "supports_stage", False)))

    def request_stage_frame(self, scene, t: float, view: str, callback) -> None:
        """Ask the render thread for a projector-stage frame (:class:`app.player.stage.StageFrame`);
        the rig's Kivy camera, when open, goes with it (the stage's live rig reads it)."""
        if self.renderer is not None and self.renderer.alive:
            self.renderer.request(StageJob(Scene.from_dict(scene.to_dict()), view, self.rig_camera), t, callback)

    def open_rig_camera(self):
        """On Kivy's main thread (the projector screen's entry): when the rig's camera choice
        names the Kivy camera (``kivy``, ``kivy:N``) and the profile folder holds the
        calibration files, open it (:class:`app.ui.kivy_camera.KivyCameraSource`; the stage's
        live rig reads it on the render thread). Returns the open source, or None (another
        camera choice, no calibration: the stage opens its own rig; a camera that does not
        open is said on screen and the synthetic rig is used)."""
        if self.rig_camera is not None or self._rig_camera_failed:
            return self.rig_camera
        index = kivy_camera_index(getattr(self.renderer_factory, "camera", None))
        if index is None or not self.stage_available() or not has_calibration(self.profile_dir):
            return None
        from app.ui.kivy_camera import KivyCameraSource  # deferred: only for a Kivy camera choice
        try:
            camera = self.kivy_camera_factory(index) if self.kivy_camera_factory is not None else None
            self.rig_camera = KivyCameraSource(index, camera=camera)
        except StoryBeamError as exc:
            self._rig_camera_failed = True
            log.warning("%s; the projector uses the synthetic rig", exc)
            self.show_message(self.t("error", why=str(exc)))
        return self.rig_camera

    def open_projector_window(self):
        """When a second display exists (:func:`app.ui.projector_window.second_display`),
        start the projector window there (a second process; this window stays where it
        is). Returns it, or None (one display: *Full screen* is the projector mode; Android,
        where an app has one window and one process)."""
        if self.projector_window is not None or platform == "android":
            return self.projector_window
        try:
            display = second_display()
            if display is not None:
                self.projector_window = ProjectorWindow(
                    display, headless=os.environ.get("SDL_VIDEODRIVER") == "offscreen")
        except StoryBeamError as exc:
            log.warning("no projector window: %s", exc)
            self.show_message(self.t("error", why=str(exc)))
        return self.projector_window

    def feed_projector_window(self, light) -> None:
        """Show the light image (RGB) in the projector window, if one is open (never waits)."""
        window = self.projector_window
        if window is None:
            return
        if not window.alive:  # closed by hand, or crashed: the show goes on here
            log.warning("the projector window has gone")
            self.close_projector_window()
            return
        try:
            window.show(light)
        except StoryBeamError as exc:
            log.warning("projector window: %s", exc)

    def close_projector_window(self) -> None:
        window, self.projector_window = self.projector_window, None
        if window is not None:
            window.close()

    def release_rig_camera(self) -> None:
        """On Kivy's main thread (leaving the projector screen, closing the app): stop the
        Kivy camera; the stage's live rig sees it closed and is reopened on the next one."""
        camera, self.rig_camera = self.rig_camera, None
        self._rig_camera_failed = False
        if camera is not None:
            camera.close()


__all__ = ["StoryBeamApp", "register_fonts"]
