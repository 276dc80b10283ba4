"""Big, friendly touch widgets: every button has an icon *and* a label, and is at least
``MIN_TOUCH_DP`` on each side (children's fingers; Android's guideline is 48 dp)."""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterable

from kivy.graphics import Color, Line, Rectangle, RoundedRectangle
from kivy.metrics import dp
from kivy.properties import BooleanProperty, ListProperty, StringProperty
from kivy.uix.behaviors import ButtonBehavior
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.gridlayout import GridLayout
from kivy.uix.label import Label
from kivy.uix.scrollview import ScrollView
from kivy.uix.widget import Widget

from app.ui.art import draw_icon

MIN_TOUCH_DP = 48
BUTTON_DP = 76


class IconView(Widget):
    """Draws one procedural icon centred in its box."""

    icon = StringProperty("")
    colour = ListProperty([0.15, 0.15, 0.2])

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.bind(pos=self._redraw, size=self._redraw, icon=self._redraw, colour=self._redraw)

    def _redraw(self, *_: object) -> None:
        self.canvas.clear()
        s = min(self.width, self.height)
        with self.canvas:
            draw_icon(self.icon, self.center_x - s / 2, self.center_y - s / 2, s, tuple(self.colour))


class IconButton(ButtonBehavior, BoxLayout):
    """A rounded button: icon on top, label below. ``selected`` draws a thick outline."""

    icon = StringProperty("")
    text = StringProperty("")
    selected = BooleanProperty(False)
    background = ListProperty([1, 1, 1, 0.92])
    icon_colour = ListProperty([0.15, 0.15, 0.2])

    def __init__(self, icon: str = "", text: str = "", on_press: Callable[..., object] | None = None,
                 font_size: float | None = None, **kwargs):
        kwargs.setdefault("orientation", "vertical")
        kwargs.setdefault("padding", dp(4))
        kwargs.setdefault("spacing", dp(2))
        super().__init__(**kwargs)
        self.icon, self.text = icon, text
        self.icon_view = IconView(icon=icon, colour=self.icon_colour)
        self.label = Label(text=text, color=(0.1, 0.1, 0.15, 1), font_size=font_size or dp(15),
                           size_hint_y=None, height=dp(22), halign="center", shorten=True,
                           shorten_from="right")
        self.label.bind(size=lambda lbl, size: setattr(lbl, "text_size", (size[0], None)))
        if icon:
            self.add_widget(self.icon_view)
        else:  # text-only key: the label fills the button
            self.label.size_hint_y, self.label.font_size = 1, (font_size or dp(15)) * 1.4
        self.add_widget(self.label)
        if icon and not text:  # a picture-only button: the picture takes the label's room too
            self.label.height, self.label.opacity = 0, 0
        self.bind(text=lambda *_: setattr(self.label, "text", self.text),
                  icon=lambda *_: setattr(self.icon_view, "icon", self.icon),
                  icon_colour=lambda *_: setattr(self.icon_view, "colour", self.icon_colour),
                  pos=self._redraw, size=self._redraw, selected=self._redraw, state=self._redraw,
                  background=self._redraw)
        if on_press is not None:
            self.bind(on_release=lambda *_: on_press())

    def _redraw(self, *_: object) -> None:
        self.canvas.before.clear()
        pressed = self.state == "down"
        with self.canvas.before:
            r, g, b, a = self.background
            k = 0.85 if pressed else 1.0
            Color(r * k, g * k, b * k, a)
            RoundedRectangle(pos=self.pos, size=self.size, radius=[dp(14)])
            if self.selected:
                Color(1.0, 0.55, 0.1, 1)
                Line(rounded_rectangle=(self.x + 2, self.y + 2, self.width - 4, self.height - 4, dp(14)),
                     width=dp(3))


def window_dp() -> tuple[float, float]:
    """The window's size in dp (density-independent pixels): what a layout has to fill.
    A 1280x800 tablet at density 1.33 is 962 x 601 dp; 2560x1600 at density 2 is 1280 x 800."""
    from kivy.core.window import Window  # deferred: the window opens when first imported
    return Window.width / dp(1), Window.height / dp(1)


def compact_screen() -> bool:
    """True on a small tablet screen (under 1100 x 700 dp: 1024 x 600, 1280 x 800 at
    density 1.33): layouts use their narrower columns and shorter rows."""
    w, h = window_dp()
    return w < 1100 or h < 700


def big_label(text: str, size: float = 22, colour: tuple[float, ...] = (0.1, 0.1, 0.15, 1), **kwargs) -> Label:
    """A label with room for Japanese descenders and a readable size."""
    kwargs.setdefault("size_hint_y", None)
    kwargs.setdefault("height", dp(size * 1.9))
    return Label(text=text, font_size=dp(size), color=colour, **kwargs)


def filled(widget: Widget, rgba: tuple[float, float, float, float]) -> Widget:
    """Give a layout a solid background colour that follows its size."""
    with widget.canvas.before:
        Color(*rgba)
        rect = Rectangle(pos=widget.pos, size=widget.size)
    widget.bind(pos=lambda w, p: setattr(rect, "pos", p), size=lambda w, s: setattr(rect, "size", s))
    return widget


def newest_files(folders: Iterable[Path], suffixes: tuple[str, ...], limit: int = 60) -> list[Path]:
    """Files in ``folders`` (not recursive) whose suffix is one of ``suffixes`` (lower
    case), newest first, at most ``limit`` (a downloads folder can be big). A folder that
    cannot be read is skipped; a file that vanishes while listed sorts last."""
    found: list[Path] = []
    for folder in folders:
        try:
            found += [p for p in Path(folder).iterdir() if p.is_file() and p.suffix.lower() in suffixes]
        except OSError:
            continue

    def mtime(p: Path) -> float:
        try:
            return p.stat().st_mtime
        except OSError:
            return 0.0
    return sorted(found, key=mtime, reverse=True)[:limit]


def tile_grid(cols: int, row_dp: float, spacing_dp: float = 8) -> tuple[ScrollView, GridLayout]:
    """A vertically scrolling grid of ``cols`` columns of rows ``row_dp`` high that grows
    with its tiles: returns the scroll view (to place) and the grid (to fill)."""
    grid = GridLayout(cols=cols, spacing=dp(spacing_dp), size_hint_y=None, row_default_height=dp(row_dp),
                      row_force_default=True)
    grid.bind(minimum_height=grid.setter("height"))
    scroll = ScrollView(do_scroll_x=False)
    scroll.add_widget(grid)
    return scroll, grid


def file_tiles(paths, name: Callable, on_pick: Callable, empty_text: str, row_dp: float = 110,
               font_dp: float = 14, empty_dp: float = 14) -> tuple[ScrollView, dict]:
    """A scrolling grid of big tiles, one per file in ``paths`` (labelled ``name(path)``;
    a tap calls ``on_pick(path)``), or ``empty_text`` when there is none. Returns the
    scroll view and the tiles by ``str(path)`` (what the touch tests tap)."""
    scroll, grid = tile_grid(3, row_dp, spacing_dp=10)
    tiles = {}
    for path in paths:
        tile = IconButton("add", name(path), on_press=lambda p=path: on_pick(p), font_size=dp(font_dp))
        tiles[str(path)] = tile
        grid.add_widget(tile)
    if not paths:
        grid.add_widget(big_label(empty_text, empty_dp))
    return scroll, tiles
