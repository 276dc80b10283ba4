"""The screen shown when the profile cannot be opened: never a fresh install in disguise.

A picture says it first (a torn page; when a good copy exists, an arrow to a whole page
with a check mark), then one sentence for the teacher: the file is damaged and kept, and
what the good copy holds (when it was saved, how many stories, the teacher PIN).
*Put back the copy* restores it (:func:`app.story.restore_backup`: the damaged file is
moved aside, never deleted; the stories and the PIN come back; stories made meanwhile are
carried over). *Continue* lets the children go on in a rescue profile beside it, which
keeps the teacher's PIN from the good copy; the screen comes back at the next start for
as long as the damaged file is in place.
"""
from __future__ import annotations

from kivy.app import App
from kivy.graphics import Color, Ellipse, Line, Rectangle
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.screenmanager import Screen
from kivy.uix.widget import Widget

from app.ui.widgets import BUTTON_DP, IconButton, big_label, filled


class DamagedPicture(Widget):
    """A torn page (red tear), and with ``has_copy`` an arrow to a whole page with a green
    check mark: "this is broken, that copy is good"."""

    def __init__(self, has_copy: bool, **kwargs):
        super().__init__(**kwargs)
        self.has_copy = has_copy
        self.bind(pos=self._draw, size=self._draw)

    def _page(self, x: float, y: float, w: float, h: float) -> None:
        Color(1, 1, 1, 1)
        Rectangle(pos=(x, y), size=(w, h))
        Color(0.25, 0.3, 0.4, 1)
        Line(rectangle=(x, y, w, h), width=dp(2))
        for k in range(1, 5):  # lines of writing
            Line(points=[x + w * 0.15, y + h * k / 5.5, x + w * 0.85, y + h * k / 5.5], width=dp(1.5))

    def _draw(self, *_: object) -> None:
        self.canvas.clear()
        h = min(self.height * 0.9, dp(160))
        w = h * 0.75
        pages = 2 if self.has_copy else 1
        gap = w * 0.9
        x0 = self.center_x - (pages * w + (pages - 1) * gap) / 2
        y = self.center_y - h / 2
        with self.canvas:
            self._page(x0, y, w, h)
            Color(0.85, 0.1, 0.1, 1)  # the tear
            zig = [x0 + w * 0.55, y + h]
            for k in range(1, 7):
                zig += [x0 + w * (0.35 if k % 2 else 0.6), y + h * (1 - k / 6)]
            Line(points=zig, width=dp(4))
            if not self.has_copy:
                return
            ax, ay = x0 + w + gap * 0.15, self.center_y  # the arrow
            Color(0.2, 0.3, 0.6, 1)
            Line(points=[ax, ay, ax + gap * 0.7, ay], width=dp(4))
            Line(points=[ax + gap * 0.5, ay + gap * 0.2, ax + gap * 0.7, ay, ax + gap * 0.5, ay - gap * 0.2],
                 width=dp(4))
            x1 = x0 + w + gap
            self._page(x1, y, w, h)
            r = w * 0.3  # the check mark, in a green disc
            Color(0.2, 0.65, 0.3, 1)
            Ellipse(pos=(x1 + w - r * 1.4, y - r * 0.4), size=(2 * r, 2 * r))
            Color(1, 1, 1, 1)
            cx, cy = x1 + w - r * 0.4, y + r * 0.6
            Line(points=[cx - r * 0.5, cy, cx - r * 0.1, cy - r * 0.4, cx + r * 0.55, cy + r * 0.4], width=dp(4))


class ProfileProblemScreen(Screen):
    """The damaged-profile screen (the app's first screen when its profile was refused)."""

    def on_pre_enter(self, *args):
        self.refresh()

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        info = app.profile_backup
        self.clear_widgets()
        root = filled(BoxLayout(orientation="vertical", padding=dp(24), spacing=dp(12)), (0.98, 0.95, 0.9, 1))
        self.picture = DamagedPicture(info is not None)
        root.add_widget(self.picture)
        if info is None:
            sentence = t("damaged_none", name=app.damaged_profile.name)
        else:
            key = "damaged_backup_pin" if info.has_pin else "damaged_backup"
            sentence = t(key, date=info.saved_text(), n=info.stories)
        self.sentence = big_label(sentence, 20, halign="center", valign="middle", height=dp(110))
        self.sentence.bind(width=lambda lbl, w: setattr(lbl, "text_size", (w, None)))
        root.add_widget(self.sentence)
        bar = BoxLayout(size_hint_y=None, height=dp(BUTTON_DP + 24), spacing=dp(24))
        bar.add_widget(Widget())
        self.restore_button = None
        if info is not None:
            self.restore_button = IconButton("play", t("restore_copy"), on_press=app.restore_profile,
                                             size_hint_x=None, width=dp(260), background=[0.75, 0.95, 0.75, 1])
            bar.add_widget(self.restore_button)
        self.continue_button = IconButton("home", t("continue_new"), on_press=app.go_home, size_hint_x=None,
                                          width=dp(220))
        bar.add_widget(self.continue_button)
        bar.add_widget(Widget())
        root.add_widget(bar)
        self.add_widget(root)


__all__ = ["ProfileProblemScreen", "DamagedPicture"]
