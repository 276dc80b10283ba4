"""Teacher mode behind a PIN (a grown-up question before the first one, slowed-down
wrong tries, a recovery code): class sessions and group rosters, calibration wizard,
presenting every story, exports (videos, story packages, activity-log CSV).

Teacher screens may use text entry (session and group names); the children's flow never
does."""
from __future__ import annotations

import logging
import math
import threading
import time
from pathlib import Path

import numpy as np
from kivy.app import App
from kivy.clock import Clock
from kivy.core.window import Window
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.gridlayout import GridLayout
from kivy.uix.label import Label
from kivy.uix.screenmanager import Screen
from kivy.uix.scrollview import ScrollView
from kivy.uix.textinput import TextInput
from kivy.uix.widget import Widget

from app.player.app_renderer import CAMERA_SETTING, DEFAULT_CAMERA, check_camera_choice
from app.services import (CalibrationWizard, GrayCodeWizard, act_it_out_allowed, set_act_it_out_allowed,
                          set_video_saving_allowed, video_saving_allowed)
from app.story import RECOVERY_CODE_DIGITS, GrownUpQuestion, StorageError, valid_pin
from app.ui.import_picker import ImportPicker
from app.ui.narration import RECORDING_SETTING, recording_allowed
from app.ui.number_words import in_words
from app.ui.story_bin import BinView
from app.ui.widgets import BUTTON_DP, IconButton, big_label, compact_screen, filled
from retrieval.errors import StoryBeamError

log = logging.getLogger(__name__)

_STEP_TEXT = {
    "board": {"en": "1. Put the printed board on the table", "ja": "1. いんさつした ボードを つくえに おく"},
    "capture": {"en": "2. Capture views of the board", "ja": "2. ボードを いろいろな むきで うつす"},
    "solve": {"en": "3. Compute the camera calibration", "ja": "3. カメラの けいさん"},
    "save": {"en": "4. Save", "ja": "4. ほぞん"},
    "scan": {"en": "5. Scan the table: put the boxes on it, hold the rig still",
             "ja": "5. つくえを スキャン: はこを おいて、リグを うごかさない"},
    # the Gray-code wizard (a real rig: the projector shows the patterns, the camera films them)
    "graycode_pose": {"en": "2.{n} Put the board in a new place in the light, hold the rig still, tap Next",
                      "ja": "2.{n} ボードを ひかりの べつの ばしょに おき、リグを うごかさずに つぎへ"},
}


def step_text(key: str, lang: str) -> str:
    """The wizard step's explanation (a Gray-code pose: its number)."""
    if key.startswith("graycode_pose_"):
        return _STEP_TEXT["graycode_pose"][lang].format(n=key.rsplit("_", 1)[1])
    return _STEP_TEXT[key][lang]


#: Digits the pad takes in each mode.
_MAX_DIGITS = {"gate": 6, "new1": 8, "new2": 8, "enter": 8, "recover": RECOVERY_CODE_DIGITS}
#: A PIN being chosen (after the grown-up check or a recovery code), or a recovery code
#: shown and not yet confirmed, is abandoned after this many seconds without a key: a
#: grown-up who walks away mid-way leaves nothing a child can finish (the check, the
#: recovery code or the PIN is asked again; an unconfirmed code is replaced).
SETUP_IDLE_S = 120.0


def question_text(question: GrownUpQuestion, lang: str) -> str:
    """The grown-up check as shown: the number in words (:mod:`app.ui.number_words`)."""
    return in_words(question.number, lang)


def _wait_text(seconds: float) -> str:
    s = math.ceil(seconds)
    return f"{s // 60}:{s % 60:02d}"


class PinScreen(Screen):
    """The teacher's way in, on a big number pad.

    Modes: ``gate`` (a fresh install: the grown-up check first -- a six-digit number in
    words to type in digits; a wrong answer locks it for a growing time,
    :meth:`ProfileStore.try_grownup`, and brings a new number), ``new1``/``new2`` (the new
    PIN, typed twice), ``code`` (the recovery code, shown once), ``enter`` (the PIN; wrong
    ones slowed down by :meth:`ProfileStore.try_pin`), ``recover`` (the recovery code
    instead of a forgotten PIN, then ``new1``/``new2``; stories are kept). Leaving the
    screen, or :data:`SETUP_IDLE_S` without a key while a PIN is being chosen, starts
    over, so no step can be skipped or finished by someone else."""

    #: OK presses so far (what the UI tests wait on after a tap of OK).
    submits = 0

    def on_pre_enter(self, *args):
        self._start_over()
        self.refresh()
        Clock.unschedule(self._tick)
        Clock.schedule_interval(self._tick, 1.0)

    def _start_over(self) -> None:
        app = App.get_running_app()
        self.question = GrownUpQuestion.draw()
        self.last_key_at = time.monotonic()
        self.recovery_used: str | None = None  # the code that unlocked a reset
        self.first_pin = ""
        self.shown_code = ""
        self.mode = "enter" if app.store.has_pin() else "gate"
        self.entered = ""
        self.note = ""

    def on_leave(self, *args):
        Clock.unschedule(self._tick)

    def _tick(self, _dt) -> None:
        """Count a running lock down on screen; start over when a PIN being chosen was left."""
        mode = getattr(self, "mode", None)
        if mode in ("new1", "new2", "code") and time.monotonic() - self.last_key_at > SETUP_IDLE_S:
            if mode == "code":  # never confirmed as written down: the next right PIN shows a new one
                App.get_running_app().store.forget_recovery_code()
                self.shown_code = ""
            self._start_over()
            self.refresh()
            return
        if mode not in ("enter", "recover", "gate"):
            return
        store = App.get_running_app().store
        if store is None:
            return
        wait = {"enter": store.pin_wait, "recover": store.recovery_wait, "gate": store.grownup_wait}[mode]()
        if wait > 0:
            self.message.text = App.get_running_app().t(self._wait_key(), time=_wait_text(wait))
            self._counting = True
        elif getattr(self, "_counting", False):
            self.message.text = self.note = ""
            self._counting = False

    def _title(self) -> str:
        app = App.get_running_app()
        t = app.t
        return {"gate": t("gate_title"), "new1": t("new_pin"),
                "new2": t("repeat_pin"), "code": t("recovery_title"), "enter": t("enter_pin"),
                "recover": t("enter_recovery")}[self.mode]

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        if not hasattr(self, "mode"):  # the app's first screen is refreshed without on_pre_enter
            self._start_over()
        self.clear_widgets()
        compact = compact_screen()  # a small tablet: smaller type, so the pad keeps 48-dp keys
        root = filled(BoxLayout(orientation="vertical", padding=dp(12 if compact else 24), spacing=dp(10)),
                      (0.9, 0.93, 0.98, 1))
        bar = BoxLayout(size_hint_y=None, height=dp(60 if compact else BUTTON_DP), spacing=dp(10))
        if self.mode != "code":  # the code is shown once: the only way on is "I wrote it down"
            bar.add_widget(IconButton("home", t("back"), on_press=app.go_home, size_hint_x=None, width=dp(100)))
        self.title_label = big_label(self._title(), 24, size_hint_y=1)
        bar.add_widget(self.title_label)
        self.forgot_button = None
        if self.mode == "enter":
            self.forgot_button = IconButton("teacher", t("forgot_pin"), on_press=self.forgot, size_hint_x=None,
                                            width=dp(150), font_size=dp(14))
            bar.add_widget(self.forgot_button)
        root.add_widget(bar)
        self.question_label = None
        if self.mode == "gate":
            self.question_label = big_label(question_text(self.question, app.lang), 22 if compact else 28,
                                            colour=(0.1, 0.2, 0.6, 1), halign="center", valign="middle", height=dp(80))
            self.question_label.bind(width=lambda lbl, w: setattr(lbl, "text_size", (w, None)),
                                     texture_size=lambda lbl, ts: setattr(lbl, "height", max(dp(56), ts[1] + dp(8))))
            root.add_widget(self.question_label)
        self.display = big_label(self._shown(), 28 if compact else 36)
        self.message = big_label(self.note, 16 if compact else 18, colour=(0.8, 0.1, 0.1, 1), halign="center",
                                 valign="middle", height=dp(44 if compact else 70))
        self.message.bind(width=lambda lbl, w: setattr(lbl, "text_size", (w, None)))
        root.add_widget(self.display)
        root.add_widget(self.message)
        self.keys = {}
        self.done_button = None
        if self.mode == "code":
            self.message.color = (0.1, 0.1, 0.2, 1)
            self.message.text = t("recovery_note")
            self.done_button = IconButton("play", t("recovery_done"), on_press=self.code_noted, size_hint=(None, None),
                                          width=dp(320), height=dp(96), font_size=dp(20),
                                          background=[0.75, 0.95, 0.75, 1])
            centre = BoxLayout()
            centre.add_widget(Widget())
            centre.add_widget(self.done_button)
            centre.add_widget(Widget())
            root.add_widget(centre)
            self.add_widget(root)
            return
        pad = GridLayout(cols=3, spacing=dp(10), size_hint=(None, 1), width=dp(3 * 110))
        for key in ("1", "2", "3", "4", "5", "6", "7", "8", "9", "clear", "0", "ok"):
            label = t(key) if key in ("clear", "ok") else key
            icon = {"clear": "delete", "ok": "play"}.get(key, "")
            b = IconButton(icon, label, on_press=lambda k=key: self.press(k), font_size=dp(26))
            self.keys[key] = b
            pad.add_widget(b)
        centre = BoxLayout()
        centre.add_widget(Widget())
        centre.add_widget(pad)
        centre.add_widget(Widget())
        root.add_widget(centre)
        self.add_widget(root)

    def _shown(self) -> str:
        if self.mode == "code":
            c = self.shown_code
            return " ".join(c[i:i + 4] for i in range(0, len(c), 4))
        if self.mode in ("gate", "recover"):  # the grown-up sees what they typed
            return self.entered
        return "●" * len(self.entered)

    def _switch(self, mode: str, note: str = "") -> None:
        self.last_key_at = time.monotonic()
        self.mode, self.entered, self.note = mode, "", note
        self.refresh()

    def press(self, key: str) -> None:
        self.last_key_at = time.monotonic()
        if key == "clear":
            self.entered = ""
        elif key == "ok":
            self.submit()
            return
        elif len(self.entered) < _MAX_DIGITS.get(self.mode, 8):
            self.entered += key
        self.display.text = self._shown()

    def submit(self) -> None:
        app = App.get_running_app()
        self.submits += 1
        t, store, entered = app.t, app.store, self.entered
        try:
            if self.mode == "gate":
                check = store.try_grownup(self.question, entered)
                if check.ok:
                    return self._switch("new1")
                if not check.refused:  # a new number after every checked answer: none repeats
                    self.question = GrownUpQuestion.draw(previous=self.question)
                return self._switch("gate", self._refusal(check, "gate_wrong"))
            if self.mode == "new1":
                if not valid_pin(entered):
                    return self._switch("new1", t("pin_digits"))
                self.first_pin = entered
                return self._switch("new2")
            if self.mode == "new2":
                if entered != self.first_pin:
                    self.first_pin = ""
                    return self._switch("new1", t("pin_mismatch"))
                if self.recovery_used is not None:
                    self.shown_code = store.reset_pin(self.recovery_used, entered)
                    store.log_activity("teacher PIN reset")
                else:
                    self.shown_code = store.set_pin(entered)
                self.first_pin = ""
                return self._switch("code")
            if self.mode == "recover":
                check = store.try_recovery_code(entered)
                if check.ok:
                    self.recovery_used = entered
                    return self._switch("new1")
                return self._switch("recover", self._refusal(check, "wrong_code"))
            check = store.try_pin(entered)
            if check.ok and not store.has_recovery_code():  # a PIN from before recovery codes: make one now
                self.shown_code = store.new_recovery_code()
                return self._switch("code")
            if check.ok:
                return self.unlock()
            self._switch("enter", self._refusal(check, "wrong_pin"))
        except StorageError as exc:  # a damaged PIN record, a full disk: say so; "forgot PIN" stays offered
            self._switch(self.mode, str(exc))

    def _wait_key(self) -> str:
        return "gate_wait" if self.mode == "gate" else "pin_wait"

    def _refusal(self, check, wrong_key: str) -> str:
        app = App.get_running_app()
        if check.refused:
            return app.t(self._wait_key(), time=_wait_text(check.wait_s))
        text = app.t(wrong_key)
        if check.wait_s > 0:
            text += "\n" + app.t(self._wait_key(), time=_wait_text(check.wait_s))
        return text

    def forgot(self) -> None:
        self._switch("recover")

    def code_noted(self) -> None:
        self.shown_code = ""  # shown once: gone from the screen and never stored in clear
        self.unlock()

    def unlock(self) -> None:
        app = App.get_running_app()
        app.teacher_unlocked = True
        app.store.log_activity("teacher mode")
        app.go("teacher")


class TeacherScreen(Screen):
    """Sessions and groups on the left; actions on the right."""

    def on_pre_enter(self, *args):
        app = App.get_running_app()
        if not app.teacher_unlocked:
            Clock.schedule_once(lambda dt: app.go("pin"), 0)
            return
        self.refresh()

    def on_leave(self, *args):
        self.clear_widgets()  # nothing of teacher mode stays behind, drawn or not

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        store = app.store
        self.clear_widgets()
        if not app.teacher_unlocked:  # never drawn without the PIN, whoever asks for it
            return
        root = filled(BoxLayout(padding=dp(12), spacing=dp(12)), (0.93, 0.95, 0.98, 1))
        left = BoxLayout(orientation="vertical", spacing=dp(8))
        bar = BoxLayout(size_hint_y=None, height=dp(BUTTON_DP), spacing=dp(8))
        bar.add_widget(IconButton("home", t("home"), on_press=self.leave, size_hint_x=None, width=dp(100)))
        title = big_label(t("sessions"), 18 if compact_screen() else 24, size_hint_y=1, halign="center",
                          valign="middle")
        title.bind(width=lambda lbl, w: setattr(lbl, "text_size", (w, None)))  # two lines where it is narrow
        bar.add_widget(title)
        saving_on = video_saving_allowed(store)  # children may save their story's video (app.ui.story_end)
        self.video_saving_button = IconButton(
            "export", f"{t('video_saving_setting')}: {t('on') if saving_on else t('off')}",
            on_press=self.toggle_video_saving, selected=saving_on, font_size=dp(12), size_hint_x=None, width=dp(170))
        bar.add_widget(self.video_saving_button)
        self.bin_button = IconButton("bin", t("story_bin"), on_press=self.open_bin, size_hint_x=None, width=dp(100))
        bar.add_widget(self.bin_button)
        left.add_widget(bar)
        row = BoxLayout(size_hint_y=None, height=dp(56), spacing=dp(8))
        self.session_name = TextInput(hint_text=t("new_session"), multiline=False, font_size=dp(20))
        row.add_widget(self.session_name)
        row.add_widget(IconButton("add", t("new_session"), on_press=self.add_session, size_hint_x=None,
                                  width=dp(140), font_size=dp(12)))
        left.add_widget(row)
        sessions = store.list_sessions()
        if sessions and app.teacher_session_id not in [s[0] for s in sessions]:
            app.teacher_session_id = sessions[-1][0]
        lst = GridLayout(cols=1, spacing=dp(4), size_hint_y=None)
        lst.bind(minimum_height=lst.setter("height"))
        for sid, name in sessions:
            b = IconButton("teacher", name, on_press=lambda s=sid: self.pick_session(s), size_hint_y=None,
                           height=dp(64), selected=sid == app.teacher_session_id)
            lst.add_widget(b)
        if app.teacher_session_id is not None:
            lst.add_widget(big_label(t("roster"), 20))
            for group in store.list_groups(app.teacher_session_id):
                lst.add_widget(Label(text=f"{group.name}: {', '.join(group.members)}", color=(0.1, 0.1, 0.2, 1),
                                     font_size=dp(17), size_hint_y=None, height=dp(34)))
            grow = BoxLayout(size_hint_y=None, height=dp(56), spacing=dp(6))
            self.group_name = TextInput(hint_text=t("group_name"), multiline=False, font_size=dp(18))
            self.members = TextInput(hint_text=t("members"), multiline=False, font_size=dp(18))
            grow.add_widget(self.group_name)
            grow.add_widget(self.members)
            grow.add_widget(IconButton("add", t("add_group"), on_press=self.add_group, size_hint_x=None,
                                       width=dp(130), font_size=dp(12)))
            lst.add_widget(grow)
        scroll = ScrollView(do_scroll_x=False)
        scroll.add_widget(lst)
        left.add_widget(scroll)
        root.add_widget(left)

        right = GridLayout(cols=2, spacing=dp(10), size_hint_x=None, width=dp(420), row_default_height=dp(96),
                           row_force_default=True)
        self.calibration_button = IconButton("calibration", t("calibration"), on_press=lambda: app.go("calibration"))
        right.add_widget(self.calibration_button)
        self.action_buttons = {
            "present_all": IconButton("projector", t("present_all"), on_press=app.present_all),
            "export_video": IconButton("export", t("export_video"), on_press=self.export_videos),
            "export_packages": IconButton("export", t("export_packages"), on_press=self.export_packages),
            "import_package": IconButton("add", t("import_package"), on_press=self.import_packages),
            "export_log": IconButton("export", t("export_log"), on_press=self.export_log),
        }
        log_on = store.activity_logging
        self.action_buttons["activity_log"] = IconButton(
            "teacher", f"{t('activity_log')}: {t('on') if log_on else t('off')}", on_press=self.toggle_log,
            selected=log_on, font_size=dp(13))
        voice_on = recording_allowed(store)  # the class's voice recording switch (app.ui.narration)
        self.action_buttons["recording"] = IconButton(
            "teacher", f"{t('recording_setting')}: {t('on') if voice_on else t('off')}",
            on_press=self.toggle_recording, selected=voice_on, font_size=dp(13))
        for button in self.action_buttons.values():
            right.add_widget(button)
        # the rig's camera: a device number, or a recording (video file, folder of images)
        self.camera_input = TextInput(text=store.get_setting(CAMERA_SETTING) or DEFAULT_CAMERA,
                                      hint_text=t("rig_camera_hint"), multiline=False, font_size=dp(16))
        right.add_widget(self.camera_input)
        self.action_buttons["rig_camera"] = IconButton("projector", t("rig_camera"), on_press=self.save_camera,
                                                       font_size=dp(13))
        right.add_widget(self.action_buttons["rig_camera"])
        act_on = act_it_out_allowed(store)  # the class's camera switch for "Act it out" (app.ui.act_view)
        self.action_buttons["act_it_out"] = IconButton(
            "act", f"{t('act_setting')}: {t('on') if act_on else t('off')}", on_press=self.toggle_act_it_out,
            selected=act_on, font_size=dp(13))
        right.add_widget(self.action_buttons["act_it_out"])
        self.status = Label(text="", color=(0.1, 0.3, 0.1, 1), font_size=dp(14), halign="left", valign="top")
        self.status.bind(size=lambda lbl, s: setattr(lbl, "text_size", s))
        right.add_widget(self.status)
        rows = -(-len(right.children) // 2)  # every row fits the window's height (a 600-px tablet too)
        right.row_default_height = min(dp(96), (Window.height - dp(24) - (rows - 1) * dp(10)) / rows)
        root.add_widget(right)
        self.add_widget(root)

    # -- actions --------------------------------------------------------------------
    def leave(self) -> None:
        app = App.get_running_app()
        app.teacher_unlocked = False
        app.go_home()

    def _report(self, text: str) -> None:
        self.status.text = text

    def add_session(self) -> None:
        app = App.get_running_app()
        try:
            app.teacher_session_id = app.store.create_session(self.session_name.text)
        except StorageError as exc:
            return self._report(str(exc))
        self.refresh()

    def pick_session(self, session_id: int) -> None:
        App.get_running_app().teacher_session_id = session_id
        self.refresh()

    def add_group(self) -> None:
        app = App.get_running_app()
        members = [m.strip() for m in self.members.text.replace("、", ",").split(",") if m.strip()]
        try:
            app.store.add_group(app.teacher_session_id, self.group_name.text, members)
        except StorageError as exc:
            return self._report(str(exc))
        self.refresh()

    def toggle_log(self) -> None:
        store = App.get_running_app().store
        store.set_activity_logging(not store.activity_logging)
        self.refresh()

    def save_camera(self) -> None:
        """Save the rig camera choice (checked first: a recording must open); the projector
        screen uses it the next time the app starts its stage."""
        app = App.get_running_app()
        try:
            choice = check_camera_choice(self.camera_input.text)
            app.store.set_setting(CAMERA_SETTING, choice)
        except (StoryBeamError, StorageError) as exc:
            return self._report(str(exc))
        self._report(app.t("rig_camera_saved", source=choice))

    def toggle_recording(self) -> None:
        store = App.get_running_app().store
        store.set_setting(RECORDING_SETTING, "off" if recording_allowed(store) else "on")
        self.refresh()

    def toggle_video_saving(self) -> None:
        store = App.get_running_app().store
        set_video_saving_allowed(store, not video_saving_allowed(store))
        self.refresh()

    def open_bin(self) -> None:
        """The bin: bring a story back, or delete the binned ones for good (app.ui.story_bin)."""
        self.bin_view = BinView()
        self.bin_view.open()

    def toggle_act_it_out(self) -> None:
        """Switch the camera feature (*Act it out*) on or off for the class."""
        app = App.get_running_app()
        try:
            set_act_it_out_allowed(app.store, not act_it_out_allowed(app.store))
        except StorageError as exc:
            return self._report(str(exc))
        self.refresh()

    def export_log(self) -> None:
        app = App.get_running_app()
        path = app.export_dir / "activity.csv"
        n = app.store.export_activity_csv(path)
        self._report(app.t("exported_to", path=f"{path} ({n})"))

    def export_packages(self) -> None:
        app = App.get_running_app()
        paths = []
        for summary in app.store.list_stories():
            try:
                paths.append(app.store.export_package(summary.id, app.export_dir / f"story_{summary.id}.zip"))
            except StorageError as exc:
                self._report(str(exc))
        app.store.log_activity("export packages", detail=str(len(paths)))
        self._report(app.t("exported_to", path=f"{app.export_dir} ({len(paths)})"))

    def import_packages(self) -> None:
        """Open the package picker (big tiles of the .zip files found in the inbox, the
        profile's import folder and downloads); a tap imports one."""
        app = App.get_running_app()
        app.inbox_dir.mkdir(parents=True, exist_ok=True)
        self.import_picker = ImportPicker(on_done=self._report)
        self.import_picker.open()

    def export_videos(self) -> None:
        """Write one MP4 per story (:func:`app.player.video_export.app_exporter`: the 3-D
        characters as the audience sees them, in a child process; 2-D when 3-D rendering
        is unavailable, which the status line and the log say) on a worker thread, with
        per-story frame progress."""
        app = App.get_running_app()
        exporter = app.video_exporter
        if exporter is None:
            return self._report(app.t("not_available", why="ffmpeg"))
        running = getattr(self, "export_thread", None)
        if running is not None and running.is_alive():
            return  # a second tap while videos are being written: the status line shows progress
        # read the stories here: the SQLite connection belongs to the UI thread
        stories, lines = [], []
        for summary in app.store.list_stories():
            try:
                stories.append(app.store.load_story(summary.id))
            except StorageError as exc:
                lines.append(str(exc))
        app.store.log_activity("export videos", detail=str(len(stories)))
        export_dir = app.export_dir
        self.export_results = []

        def work():
            for k, story in enumerate(stories, start=1):
                def progress(done, total, k=k):
                    text = app.t("export_progress", i=k, n=len(stories), done=done, total=total)
                    Clock.schedule_once(lambda dt: self._report(text), 0)
                try:
                    result = exporter(story, export_dir / f"story_{story.id}.mp4", progress)
                    self.export_results.append(result)
                    lines.append(str(result.path) + (f" ({result.mode})"))
                    if result.note:
                        lines.append(app.t("video_2d_note", why=result.note))
                        log.warning("video export: %s", result.note)
                except StoryBeamError as exc:
                    lines.append(str(exc))
            Clock.schedule_once(lambda dt: self._report("\n".join(lines)), 0)
        self.export_thread = threading.Thread(target=work, name="storybeam-video-export", daemon=True)
        self.export_thread.start()
        self._report("...")


def rig_scan_capture(app):
    """The *Scan the table* step's capture on a real rig, or None (the synthetic rig's
    table): when the profile holds a Gray-code ``projector.json``, the rig's camera is a
    device and the projector window opens, show each Gray-code pattern there and keep a
    camera frame (:func:`app.services.table_scan.capture_sequence`)."""
    choice = str(getattr(app.renderer_factory, "camera", "") or "")
    calibration = Path(app.profile_dir) / "projector.json"
    if not (choice.isdigit() and calibration.is_file()):
        return None
    window = app.open_projector_window()
    if window is None:
        return None

    def capture() -> list:
        from ar import open_camera_source  # deferred: OpenCV, when the teacher scans
        from ar.structured_light.calibrate import GrayCodeCalibration  # deferred: as above
        from ar.structured_light.patterns import graycode_sequence  # deferred: as above
        from app.services.table_scan import capture_sequence  # deferred: as above

        size = tuple(GrayCodeCalibration.load(calibration).projector.image_size)
        source = open_camera_source(choice, paced=False)
        try:
            return capture_sequence(graycode_sequence(size), window.show,
                                    lambda: (frame := source.read()) and frame.image)
        finally:
            source.close()
            window.show(np.zeros((8, 8, 3), np.uint8))  # the projector goes dark again
    return capture


def calibration_wizard(app, open_source=None) -> CalibrationWizard:
    """The wizard this rig can run. A real rig -- the rig's camera is a device and the
    projector window opens on a second display -- gets the Gray-code wizard
    (:class:`app.services.GrayCodeWizard`): each pose, the projector shows the Gray-code
    sequence, the camera films it, and the camera, the projector and their pose are
    calibrated from it, then the table is scanned. Otherwise (no second display, a
    recording, the tablet's Kivy camera) the camera-only wizard on the synthetic views.
    ``open_source(choice)``: opens the camera (default :func:`ar.open_camera_source`)."""
    choice = str(getattr(app.renderer_factory, "camera", "") or "")
    window = app.open_projector_window() if choice.isdigit() else None
    if window is None:
        return CalibrationWizard(Path(app.profile_dir), scan_capture=rig_scan_capture(app))
    if open_source is None:
        from ar import open_camera_source  # deferred: OpenCV, when the teacher calibrates

        def open_source(choice):
            return open_camera_source(choice, paced=False)
    _, _, width, height = window.display
    return GrayCodeWizard(Path(app.profile_dir), show=window.show, camera=open_source(choice),
                          projector_size=(int(width), int(height)))


class CalibrationScreen(Screen):
    """Step-by-step calibration; each step runs on a worker thread."""

    def on_pre_enter(self, *args):
        app = App.get_running_app()
        if not app.teacher_unlocked:
            Clock.schedule_once(lambda dt: app.go("pin"), 0)
            return
        self.wizard = calibration_wizard(app)
        self.refresh()

    def on_leave(self, *args):
        camera = getattr(getattr(self, "wizard", None), "camera", None)
        if camera is not None:  # the Gray-code wizard's camera: free it for the rig
            camera.close()
            self.wizard.camera = None

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        if not app.teacher_unlocked or not hasattr(self, "wizard"):
            return
        root = filled(BoxLayout(orientation="vertical", padding=dp(16), spacing=dp(10)), (0.93, 0.95, 0.98, 1))
        bar = BoxLayout(size_hint_y=None, height=dp(BUTTON_DP), spacing=dp(8))
        bar.add_widget(IconButton("home", t("back"), on_press=lambda: app.go("teacher"), size_hint_x=None,
                                  width=dp(100)))
        bar.add_widget(big_label(t("calib_intro"), 24, size_hint_y=1))
        root.add_widget(bar)
        for i, step in enumerate(self.wizard.steps):
            text = step_text(step.key, app.lang)
            if step.result:
                text += f"  ✓ {step.result}"
            if step.error:
                text += f"  ✗ {step.error}"
            colour = (0.1, 0.45, 0.1, 1) if step.result else (0.7, 0.1, 0.1, 1) if step.error else (0.1, 0.1, 0.2, 1)
            if i == self.wizard.current:
                colour = (0.1, 0.2, 0.7, 1) if not step.error else colour
            root.add_widget(big_label(text, 19, colour=colour, halign="left", text_size=(dp(900), None)))
        root.add_widget(Widget())
        label = t("calib_done") if self.wizard.done else t("calib_next")
        self.next_button = IconButton("play", label, on_press=self.next_step, size_hint_y=None, height=dp(90),
                                      background=[0.75, 0.95, 0.75, 1])
        root.add_widget(self.next_button)
        self.add_widget(root)

    def next_step(self) -> None:
        if self.wizard.done or getattr(self, "_busy", False):
            return
        self._busy = True
        self.next_button.text = "..."

        def work():
            self.wizard.run_next()
            Clock.schedule_once(lambda dt: self._finished(), 0)
        threading.Thread(target=work, daemon=True).start()

    def _finished(self) -> None:
        self._busy = False
        self.refresh()
