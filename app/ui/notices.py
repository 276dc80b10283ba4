"""Notices: what the app tells a child when something cannot be done -- a picture first
(:mod:`app.ui.notice_art`), the same sentence spoken where the device can speak
(:mod:`app.services.speech`), and one short sentence for the grown-ups. Never an
exception's text, a module name or a file path: those go to the log.

:func:`notice_for` turns an error into a notice (its picture's name); :class:`NoticeView`
draws one; :meth:`app.ui.app.StoryBeamApp.show_notice` shows it in a pop-up.
"""
from __future__ import annotations

import logging

from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.widget import Widget

from app.services import ActItOutError, RecordingError
from app.story import NarrationError, StorageError, StoryError
from app.ui.notice_art import PICTURES, draw_notice
from app.ui.widgets import big_label
from ar.camera_sources import CameraSourceError
from ar.errors import RigError

log = logging.getLogger(__name__)

#: NarrationError.kind -> notice
NARRATION_NOTICES = {"unreadable": "sound_broken", "missing": "sound_broken", "too_long": "sound_long",
                     "too_big": "file_big", "silent": "sound_silent", "too_short": "sound_silent",
                     "story_full": "story_full"}


def notice_for(exc: BaseException) -> str:
    """The notice (a key of :data:`app.ui.notice_art.PICTURES`) for an error a child met."""
    if isinstance(exc, NarrationError):
        return NARRATION_NOTICES.get(getattr(exc, "kind", ""), "sound_broken")
    if isinstance(exc, RecordingError) or isinstance(exc, ImportError):
        return "no_microphone"
    if isinstance(exc, StorageError):
        return "storage"
    if isinstance(exc, (RigError, ActItOutError, CameraSourceError)):
        return "no_camera"
    if isinstance(exc, StoryError):
        return "file_broken"
    return "oops"


def notice_sentence(t, notice: str) -> str:
    """The notice's one sentence for grown-ups (in the app's language)."""
    return t(f"notice_{notice if notice in PICTURES else 'oops'}")


class NoticePicture(Widget):
    """One notice picture, centred in its box."""

    def __init__(self, notice: str, **kwargs):
        super().__init__(**kwargs)
        self.notice = notice
        self.bind(pos=self._redraw, size=self._redraw)

    def _redraw(self, *_: object) -> None:
        self.canvas.clear()
        s = min(self.width, self.height)
        with self.canvas:
            draw_notice(self.notice, self.center_x - s / 2, self.center_y - s / 2, s)


class NoticeView(BoxLayout):
    """A notice: its picture, large, above its sentence."""

    def __init__(self, notice: str, sentence: str, **kwargs):
        kwargs.setdefault("orientation", "vertical")
        kwargs.setdefault("spacing", dp(6))
        super().__init__(**kwargs)
        self.notice, self.sentence = notice, sentence
        self.picture = NoticePicture(notice)
        self.add_widget(self.picture)
        self.label = big_label(sentence, 18, size_hint_y=None, height=dp(48))
        self.label.bind(size=lambda lbl, s: setattr(lbl, "text_size", (s[0], None)))
        self.label.halign = "center"
        self.add_widget(self.label)


class NoticeToast(BoxLayout):
    """A notice floating over the screen for a few seconds: it never takes a touch, so the
    child's next tap (adding the character the notice asks for) works at once, and it
    cannot trap anyone -- it goes by itself."""

    def __init__(self, notice: str, sentence: str, **kwargs):
        kwargs.setdefault("padding", dp(12))
        super().__init__(**kwargs)
        self.view = NoticeView(notice, sentence)
        self.add_widget(self.view)
        self.bind(pos=self._redraw, size=self._redraw)

    def _redraw(self, *_: object) -> None:
        from kivy.graphics import Color, RoundedRectangle  # deferred: drawing only
        self.canvas.before.clear()
        with self.canvas.before:
            Color(0, 0, 0, 0.18)
            RoundedRectangle(pos=(self.x + dp(3), self.y - dp(3)), size=self.size, radius=[dp(18)])
            Color(1, 0.95, 0.85, 0.97)
            RoundedRectangle(pos=self.pos, size=self.size, radius=[dp(18)])

    def on_touch_down(self, touch):  # touches pass through to the screen below
        return False

    def on_touch_move(self, touch):
        return False

    def on_touch_up(self, touch):
        return False


def log_notice(notice: str, detail: object) -> None:
    """What the notice stands for, in full, for the teacher's log and the developer."""
    if detail:
        log.warning("notice %s: %s", notice, detail)
