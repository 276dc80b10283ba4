"""The StoryBeam Kivy application: screens, the open story and its autosave.

Import this module only after the Kivy environment is set (see
:func:`app.ui.env.prepare_kivy_env`): Kivy reads its settings at import time.
It imports the story, the services and the light part of :mod:`app.player` only: the
3-D renderers are loaded by the render thread (``renderer_factory``), when there is one.
"""
from __future__ import annotations

import logging
import os
import time
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
from app.services import MotionCatalog, ThumbnailCache, find_speaker
from app.story import (
    BackupInfo,
    ProfileStore,
    Scene,
    StorageError,
    Story,
    StoryEditor,
    backup_settings,
    demo_story,
    prune_narrations,
    read_backup,
    restore_backup,
)
from app.ui.editor import EditorScreen
from app.ui.home import HomeScreen
from app.ui.play import PlayScreen, ProjectorScreen
from app.ui.profile_rescue import ProfileProblemScreen
from app.ui.projector_window import ProjectorWindow, second_display
from app.ui.notices import NoticeToast, log_notice, notice_for, notice_sentence
from app.ui.strings import LANGUAGES, device_language, tr
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


#: The screens of teacher mode: shown only while the teacher is unlocked (the PIN typed).
TEACHER_SCREENS = ("teacher", "calibration")
#: Teacher mode left untouched this long (seconds) locks and goes home (a teacher called away).
TEACHER_IDLE_S = 600.0
#: The settings that make the teacher's PIN (carried into a rescue profile from the good copy).
PIN_SETTINGS = ("teacher_pin", "teacher_recovery")


class GatedScreenManager(ScreenManager):
    """The app's screens, with the teacher gate at the one place every way of changing
    screen passes: ``current`` itself. A teacher screen asked for while locked (a Back
    button, *Present all*'s return, a screen name set directly, a start screen given on
    the command line) shows the PIN screen instead; showing any other screen locks
    teacher mode again, so the PIN is asked every time teacher mode is entered."""

    def __init__(self, unlocked: Callable[[], bool], lock: Callable[[], None], **kwargs):
        self._unlocked, self._lock = unlocked, lock
        #: when the screen was last touched (time.monotonic): teacher mode left alone locks
        self.last_touch = time.monotonic()
        super().__init__(**kwargs)

    def on_touch_down(self, touch):
        self.last_touch = time.monotonic()
        return super().on_touch_down(touch)

    def on_current(self, instance, value):
        if value in TEACHER_SCREENS and not self._unlocked():
            self.current = "pin"  # dispatches on_current("pin") in turn
            return
        if value is not None and value not in TEACHER_SCREENS:
            self._lock()
        super().on_current(instance, value)


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
        #: the profile refused at start (kept where it was) and its last good copy, if any
        self.damaged_profile: Path | None = None
        self.profile_backup: BackupInfo | None = None
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
        #: says notices aloud (:mod:`app.services.speech`); tests give a recording stand-in
        self.speaker = find_speaker(platform)
        self.last_notice: str | None = None

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
        """Open the profile. If it is refused (damaged, foreign, unreadable), it is not
        treated as a fresh install: the damaged file is left untouched, the first screen
        says so and offers its last good copy (:mod:`app.ui.profile_rescue`), and until
        then the children work in a rescue profile beside it, which carries the teacher's
        PIN from that copy."""
        try:
            self.store = ProfileStore(self.db_path)
        except StorageError as exc:
            self.storage_problem = str(exc)
            log.error("%s", exc)
            self.damaged_profile = self.db_path
            self.profile_backup = read_backup(self.db_path)
            rescue = self.db_path.with_name(self.db_path.stem + ".recovered.db")
            self.store = ProfileStore(rescue)
            if not self.store.has_pin():
                for key, value in backup_settings(self.db_path, PIN_SETTINGS).items():
                    self.store.set_setting(key, value)
            self.db_path = rescue

    def restore_profile(self) -> bool:
        """Put the damaged profile's last good copy back (:func:`app.story.restore_backup`;
        the damaged file is moved aside, kept), open it, carry over the stories made in the
        rescue profile meanwhile, and go home locked. False (and a message) when it fails."""
        damaged = self.damaged_profile
        try:
            kept = restore_backup(damaged)
            restored = ProfileStore(damaged)
        except StorageError as exc:
            log.error("%s", exc)
            self.show_message(self.t("restore_failed"))
            return False
        rescue, self.store, self.db_path = self.store, restored, damaged
        for summary in rescue.list_stories():
            if restored.has_story(summary.id):
                continue
            try:
                restored.save_story(rescue.load_story(summary.id))
                for name in rescue.asset_names(summary.id):
                    restored.put_asset(summary.id, name, rescue.read_asset(summary.id, name))
            except StorageError as exc:  # kept in the rescue file, which stays beside it
                log.error("not carried over: %s", exc)
        rescue.close()
        restored.log_activity("profile restored", detail=kept.name)
        self.storage_problem = self.damaged_profile = self.profile_backup = None
        self.editor = None
        self.lock_teacher()
        self.go_home()
        self.show_message(self.t("restored", name=kept.name))
        return True

    def build(self):
        register_fonts()
        self._open_store()
        saved_lang = self.store.get_setting("language")
        self.lang = self.requested_lang or (saved_lang if saved_lang in LANGUAGES else device_language(platform))
        if self.renderer_factory is not None:
            self.renderer = RenderThread(self.renderer_factory,
                                         lambda cb, frame: Clock.schedule_once(lambda dt: cb(frame), 0))
        if available() is None:
            self.video_exporter = app_exporter(self.video_view,  # narrated scenes: their voice from the assets
                                               narration_dirs=lambda story: self.store.story_assets_dir(story.id))
        self.sm = GatedScreenManager(lambda: self.teacher_unlocked, self.lock_teacher, transition=NoTransition())
        for screen in (HomeScreen(name="home"), EditorScreen(name="editor"), PlayScreen(name="play"),
                       ProjectorScreen(name="projector"), PinScreen(name="pin"), TeacherScreen(name="teacher"),
                       CalibrationScreen(name="calibration"), ProfileProblemScreen(name="damaged")):
            self.sm.add_widget(screen)
        if self.demo:
            story = demo_story()
            if not self.store.has_story(story.id):
                self.store.save_story(story)
            self.requested_story = story.id
        if self.requested_story:
            self.open_story(self.requested_story, switch=False)
            self.sm.current = self.start_screen or "editor"
        elif self.start_screen in ("pin", "home", *TEACHER_SCREENS):  # teacher: the PIN first (GatedScreenManager)
            self.sm.current = self.start_screen
        else:
            self.sm.current = "home"
        if hasattr(self.sm.current_screen, "refresh"):  # the first screen gets no on_pre_enter
            self.sm.current_screen.refresh()
        Clock.schedule_interval(self._check_idle, 5.0)
        if self.damaged_profile is not None:  # say what happened before anything else
            self.sm.current = "damaged"
            self.sm.current_screen.refresh()
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

    def _check_idle(self, _dt=None) -> None:
        """Teacher mode untouched for :data:`TEACHER_IDLE_S`: lock it and go home."""
        if self.sm.current in TEACHER_SCREENS and time.monotonic() - self.sm.last_touch > TEACHER_IDLE_S:
            self.lock_teacher()
            self.go_home()

    def lock_teacher(self) -> None:
        """Leave teacher mode: the PIN is asked again before the next teacher screen."""
        self.teacher_unlocked = False

    def on_pause(self) -> bool:
        """Android: the app goes to the background (home button, another app). Teacher
        mode is locked; on return a teacher screen shows the PIN pad instead."""
        self.lock_teacher()
        return True

    def on_resume(self) -> None:
        if self.sm.current in TEACHER_SCREENS:
            self.sm.current = "pin"

    def open_story(self, story_id: str, switch: bool = True) -> bool:
        try:
            story = self.store.load_story(story_id)
        except StorageError as exc:
            self.show_error(exc)
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
            self.show_error(exc)

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
    def show_notice(self, notice: str, detail: object = None, seconds: float = 5.0) -> None:
        """Tell the child what cannot be done: the notice's picture, its sentence for the
        grown-ups, the sentence spoken where the device can speak (:mod:`app.ui.notices`).
        ``detail`` (an exception, a reason) goes to the log, never to the screen."""
        log_notice(notice, detail)
        sentence = notice_sentence(self.t, notice)
        from kivy.core.window import Window  # deferred: the window exists once the app runs
        old = getattr(self, "_toast", None)
        if old is not None and old.parent is not None:
            old.parent.remove_widget(old)
        w, h = Window.size
        side = min(0.3 * w, 0.4 * h)
        toast = NoticeToast(notice, sentence, size_hint=(None, None), size=(max(side * 1.3, dp(260)), side),
                            pos=(0, 0))
        toast.pos = ((w - toast.width) / 2, h - toast.height - dp(24))
        Window.add_widget(toast)
        self._toast = toast
        self.last_notice, self.last_message = notice, sentence
        self.speaker.say(sentence, self.lang)

        def remove(_dt) -> None:
            if toast.parent is not None:
                toast.parent.remove_widget(toast)
        Clock.schedule_once(remove, seconds)

    def show_error(self, exc: BaseException) -> None:
        """:meth:`show_notice` for an error a child met (:func:`app.ui.notices.notice_for`)."""
        self.show_notice(notice_for(exc), exc)

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
            self.show_error(exc)
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
            self.show_error(exc)
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
