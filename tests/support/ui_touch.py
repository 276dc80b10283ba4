"""Simulated touches for the UI drivers (tests/support/ui_driver.py and the scenario files
it runs): a touch waits until its target can really be touched.

A finger lands only where a widget is on the window, on top, in the current screen, inside
every ScrollView and laid out in two drawn frames (:func:`why_untouchable`); until then a
touch raises :class:`NotReady` and the driver runs the step again a frame later. A
:func:`touching` step also waits for its effect, and touches again only when it provably
had none. The drawn frames are counted by the running driver app (``_flips``).

Imported after :func:`app.ui.env.prepare_kivy_env` (it imports Kivy).
"""
from __future__ import annotations

import time
import weakref
from typing import Callable

from kivy.app import App
from kivy.core.window import Window
from kivy.tests.common import UnitTestTouch


class NotReady(Exception):
    """The step's touch target cannot be touched yet: the step runs again a frame later."""


def centre(widget) -> tuple[float, float]:
    return widget.to_window(*widget.center)


_seen_at: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # widget -> (window rect, flip count)


def why_untouchable(widget) -> str | None:
    """Why a finger on ``widget``'s centre would not reach it now (None: it would).

    The widget must be on the window, under the topmost window child (a ModalView on top
    takes every touch, also while it fades out), in the current screen, inside the window
    and every enclosing ScrollView, and laid out: the same non-empty window rectangle in
    two different drawn frames (a rebuilt screen's widgets move when the layout runs).
    """
    from kivy.uix.modalview import ModalView
    from kivy.uix.screenmanager import Screen
    from kivy.uix.scrollview import ScrollView

    if widget.get_root_window() is not Window:
        return f"{type(widget).__name__} is not on the window"
    top, node = widget, widget
    while node.parent is not None and node.parent is not Window:
        node = node.parent
        if isinstance(node, Screen) and node.manager is not None and node.manager.current != node.name:
            return f"screen {node.name!r} is not the current one ({node.manager.current!r})"
        if isinstance(node, ScrollView) and not node.collide_point(*node.to_parent(*node.to_widget(*centre(widget)))):
            return "its centre is scrolled out of view"
        top = node
    if Window.children and Window.children[0] is not top:
        return f"a {type(Window.children[0]).__name__} is on top of it"
    if isinstance(top, ModalView) and (top._anim_alpha < 1 or not top._is_open):
        return "its ModalView is still opening or closing"
    x, y = widget.to_window(*widget.pos)
    rect = (round(x, 1), round(y, 1), round(widget.width, 1), round(widget.height, 1))
    cx, cy = centre(widget)
    if widget.width < 1 or widget.height < 1 or not (0 <= cx < Window.width and 0 <= cy < Window.height):
        return f"not laid out inside the window yet ({rect})"
    flips = App.get_running_app()._flips  # the driver app counts the drawn frames
    seen = _seen_at.get(widget)
    if seen is None or seen[0] != rect:
        _seen_at[widget] = (rect, flips)
        return "its layout may still change"
    if seen[1] == flips:
        return "no frame drawn since it was first seen there"
    return None


def ensure_touchable(widget) -> None:
    why = why_untouchable(widget)
    if why is not None:
        raise NotReady(why)


def tap(widget) -> None:
    ensure_touchable(widget)
    x, y = centre(widget)
    touch = UnitTestTouch(x, y)
    touch.touch_down()
    touch.touch_up()


class TimedTouch(UnitTestTouch):
    """A test touch whose move times are set by the test (a real finger takes time;
    the simulated one would draw the whole stroke within a millisecond)."""

    fake_time = 0.0

    def move(self, args):
        super().move(args)
        self.time_update = self.fake_time


def stroke(points_px: list[tuple[float, float]], on, dt: float = 0.05) -> None:
    """A finger stroke through window pixels on the widget ``on``, time stamps ``dt`` apart.
    Compute ``points_px`` in the same step (they depend on the widget's layout)."""
    ensure_touchable(on)
    t0 = time.time()
    touch = TimedTouch(*points_px[0])
    touch.time_start = touch.time_update = touch.fake_time = t0
    touch.touch_down()
    for i, (x, y) in enumerate(points_px[1:], start=1):
        touch.fake_time = t0 + i * dt
        touch.touch_move(x, y)
    touch.touch_up()


def drag(widget, dy: float, steps: int = 8) -> None:
    ensure_touchable(widget)
    x, y = centre(widget)
    stroke([(x, y + dy * i / steps) for i in range(steps + 1)], on=widget)


class TouchStep:
    """A step that touches the app and then waits for the effect on the model.

    ``effect`` is called just before the first touch and returns the test of success
    (so it can remember the state before). Touch handling in Kivy is synchronous, so a
    touch whose effect is still missing once a few frames are drawn had none: only then is
    it repeated, at most ``retries`` times.
    """

    def __init__(self, act: Callable[[], object], effect: Callable[[], Callable[[], bool]], retries: int = 2):
        self.act, self.effect, self.retries = act, effect, retries


def touching(act: Callable[[], object], until: Callable[[], bool] | None = None,
             changes: Callable[[], object] | None = None, retries: int = 2) -> TouchStep:
    """A :class:`TouchStep` whose effect is ``until()`` becoming true, or the value of
    ``changes()`` differing from its value before the touch."""
    if (until is None) == (changes is None):
        raise ValueError("give exactly one of until= and changes=")
    if until is not None:
        return TouchStep(act, lambda: until, retries)

    def arm():
        before = changes()
        return lambda: changes() != before
    return TouchStep(act, arm, retries)


def table_px(table, mx: float, my: float) -> tuple[float, float]:
    return table.to_window(*table.to_px(mx, my))

