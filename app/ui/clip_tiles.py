"""Big "more like this" tiles that show the motion itself: an animated stick figure
(:mod:`app.services.thumbnails`) drawn with a few Kivy lines, cycling through its poses, so a
child who cannot read the clip's name picks by looking. Until the figure is ready (or
when the clip cannot be read) the tile shows the motion's icon. A tile may start its
figure part-way through the clip (``start``, a fraction of it): a pose search's tiles
start at the moment the clip passes through the pose."""
from __future__ import annotations

from typing import Callable

from kivy.clock import Clock
from kivy.graphics import Color, Ellipse, Line
from kivy.metrics import dp
from kivy.uix.widget import Widget

from app.services import BONES, HEAD, StickFrames, ThumbnailCache
from app.ui.art import MOTION_COLOURS
from app.ui.widgets import IconButton

POSES_PER_SECOND = 6.0


def clip_tile_name(t: Callable[..., str], label: str, trial: str, number_of: Callable[[str], int | None]) -> str:
    """What a clip's tile says: its class and its number among that class's clips
    ("Run 3"), never a capture id ("Run 02_03") -- the tile's moving figure is the real
    name; the number only tells two tiles apart. ``number_of`` is
    :meth:`app.services.catalog.MotionCatalog.number_of`."""
    name = t(f"motion_{label}") if label in MOTION_COLOURS else label
    number = number_of(trial)
    return f"{name} {number}" if number is not None else name


def numbered_names(names: list[str]) -> list[str]:
    """Names made distinct where they repeat: two groups both named "Kick" become
    "Kick 1" and "Kick 2"; a name used once stays as it is."""
    counts: dict[str, int] = {}
    for n in names:
        counts[n] = counts.get(n, 0) + 1
    seen: dict[str, int] = {}
    out = []
    for n in names:
        if counts[n] == 1:
            out.append(n)
        else:
            seen[n] = seen.get(n, 0) + 1
            out.append(f"{n} {seen[n]}")
    return out


class StickFigureView(Widget):
    """One pose of a :class:`StickFrames` at a time; :meth:`step` shows the next."""

    def __init__(self, frames: StickFrames, colour=(0.15, 0.15, 0.2), **kwargs):
        super().__init__(**kwargs)
        self.frames, self.colour, self.pose = frames, tuple(colour), 0
        self.bind(pos=self.redraw, size=self.redraw)

    def step(self) -> None:
        self.pose = (self.pose + 1) % self.frames.n_frames
        self.redraw()

    def redraw(self, *_: object) -> None:
        self.canvas.clear()
        s = min(self.width, self.height) * 0.92
        x0, y0 = self.center_x - s / 2, self.center_y - s / 2
        p = self.frames.points[self.pose]
        with self.canvas:
            Color(*self.colour, 1)
            for a, b in BONES:
                Line(points=[x0 + p[a, 0] * s, y0 + p[a, 1] * s, x0 + p[b, 0] * s, y0 + p[b, 1] * s],
                     width=max(1.2, s * 0.018), cap="round")
            r = s * 0.055
            Ellipse(pos=(x0 + p[HEAD, 0] * s - r, y0 + p[HEAD, 1] * s - r), size=(2 * r, 2 * r))


class ClipTile(IconButton):
    """A clip choice: the motion's icon, replaced by its animated stick figure when ready."""

    def __init__(self, trial: str, label: str, icon: str, colour, thumbs: ThumbnailCache | None,
                 on_press: Callable[[], object], selected: bool = False, start: float = 0.0):
        super().__init__(icon, label, on_press=on_press, font_size=dp(13), icon_colour=list(colour),
                         selected=selected)
        self.trial = trial
        self.figure: StickFigureView | None = None
        self._colour = tuple(colour)
        self._start = min(max(float(start), 0.0), 1.0)
        self._event = None
        if thumbs is not None:
            ready = thumbs.get(trial)
            if ready is not None:
                self.show_figure(ready)
            else:
                thumbs.request([trial], lambda t, frames: Clock.schedule_once(lambda dt: self.show_figure(frames), 0))

    def show_figure(self, frames: StickFrames) -> None:
        if self.figure is not None:
            return
        self.figure = StickFigureView(frames, colour=tuple(c * 0.6 for c in self._colour))
        self.figure.pose = int(round(self._start * (frames.n_frames - 1)))
        index = self.children.index(self.icon_view) if self.icon_view in self.children else None
        if index is not None:
            self.remove_widget(self.icon_view)
            self.add_widget(self.figure, index=index)
        self._event = Clock.schedule_interval(lambda dt: self._animate(), 1.0 / POSES_PER_SECOND)

    def _animate(self) -> None:
        if self.get_root_window() is None:  # the list was closed
            if self._event is not None:
                self._event.cancel()
                self._event = None
            return
        self.figure.step()
