"""Which widgets a screen shows cut off or covered: the check behind
``storybeam app --screenshot``'s ``clipped_widgets`` and the layout tests at every tablet
size (issue 29).

Method. The window's widget tree is walked in drawing order (a Kivy parent draws its
``children`` from the last to the first, so ``children[0]`` is on top). The widgets a
person reads or touches are checked -- buttons (anything with ``ButtonBehavior``), sliders,
text inputs and labels with text -- each by its rectangle in window pixels:

* **cut** -- it reaches past the window's edge by more than :data:`TOLERANCE_PX`, or past
  its own parent's box when the parent is a layout (a row of buttons wider than its row);
  inside a :class:`~kivy.uix.scrollview.ScrollView` only the scroll view itself is checked
  (its content may be scrolled to);
* **text cut** -- a label whose drawn text is larger than its box (``texture_size``), unless
  it shortens its text with an ellipsis on purpose (``shorten``);
* **covered** -- another checked widget drawn after it (not its ancestor or descendant)
  overlaps more than :data:`COVER_FRACTION` of its area.

Invisible widgets (zero opacity or size, or under such a parent) are skipped. The result is
a list of plain dicts (JSON), empty when the screen is laid out well.
"""
from __future__ import annotations

from typing import Iterator

from kivy.uix.behaviors import ButtonBehavior
from kivy.uix.label import Label
from kivy.uix.layout import Layout
from kivy.uix.scrollview import ScrollView
from kivy.uix.slider import Slider
from kivy.uix.textinput import TextInput
from kivy.uix.widget import Widget

TOLERANCE_PX = 2.0
COVER_FRACTION = 0.1


def _visible(w: Widget) -> bool:
    return w.opacity > 0.01 and w.width > 0.5 and w.height > 0.5


def _walk(w: Widget, view: tuple | None = None) -> Iterator[tuple[Widget, tuple | None]]:
    """Every visible widget under ``w`` in drawing order, with the box of the ScrollView
    that holds it (None: not in one)."""
    if not _visible(w):
        return
    yield w, view
    inner = _box(w) if isinstance(w, ScrollView) and view is None else view
    for child in reversed(w.children):
        yield from _walk(child, inner)


def _checked(w: Widget) -> bool:
    if isinstance(w, (ButtonBehavior, Slider, TextInput)):
        return True
    return isinstance(w, Label) and bool(w.text.strip()) and not isinstance(w.parent, ButtonBehavior)


def _box(w: Widget) -> tuple[float, float, float, float]:
    x0, y0 = w.to_window(w.x, w.y)
    x1, y1 = w.to_window(w.right, w.top)
    return min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1)


def _name(w: Widget) -> str:
    text = getattr(w, "text", "") or getattr(w, "icon", "")
    kind = type(w).__name__
    return f"{kind} {text!r}" if text else kind


def _ancestors(w: Widget) -> set[int]:
    out = set()
    p = w.parent
    while p is not None and p is not p.parent:
        out.add(id(p))
        p = p.parent
    return out


def _label_text_cut(w: Widget) -> bool:
    if not isinstance(w, Label) or getattr(w, "shorten", False) or not w.text.strip():
        return False
    tw, th = w.texture_size
    return tw > w.width + TOLERANCE_PX or th > w.height + TOLERANCE_PX


def clipped_widgets(roots: list[Widget], size: tuple[float, float]) -> list[dict]:
    """The widgets under ``roots`` (the window's children, bottom first) that are cut off
    by the window or their row, show cut text, or are covered by another; see the module
    docstring. Each: ``{"widget", "problem", "box"}`` (box: x0, y0, x1, y1 in pixels)."""
    W, H = size
    drawn: list[tuple[Widget, tuple, bool]] = []
    for root in roots:
        for w, view in _walk(root):
            if not (_checked(w) or isinstance(w, ScrollView)):
                continue
            box = _box(w)
            if view is not None:  # only the part the scroll view shows can be covered
                box = (max(box[0], view[0]), max(box[1], view[1]), min(box[2], view[2]), min(box[3], view[3]))
                if box[2] - box[0] < 1 or box[3] - box[1] < 1:
                    continue  # scrolled out of view
            drawn.append((w, box, view is not None))
    problems: list[dict] = []

    def report(w: Widget, problem: str, box: tuple) -> None:
        problems.append({"widget": _name(w), "problem": problem, "box": [round(v, 1) for v in box]})

    ancestors = [_ancestors(w) for w, _, _ in drawn]
    for i, (w, box, in_scroll) in enumerate(drawn):
        x0, y0, x1, y1 = box
        if not in_scroll:
            if x0 < -TOLERANCE_PX or y0 < -TOLERANCE_PX or x1 > W + TOLERANCE_PX or y1 > H + TOLERANCE_PX:
                report(w, "cut by the window", box)
                continue
            parent = w.parent
            if isinstance(parent, Layout) and not isinstance(parent, ScrollView) and _visible(parent):
                px0, py0, px1, py1 = _box(parent)
                if x0 < px0 - TOLERANCE_PX or x1 > px1 + TOLERANCE_PX or y0 < py0 - TOLERANCE_PX \
                        or y1 > py1 + TOLERANCE_PX:
                    report(w, "outside its row", box)
                    continue
        if isinstance(w, ScrollView):
            continue
        if _label_text_cut(w):
            report(w, "text cut", box)
            continue
        area = max((x1 - x0) * (y1 - y0), 1.0)
        for (v, (ox0, oy0, ox1, oy1), _), theirs in zip(drawn[i + 1:], ancestors[i + 1:]):
            if isinstance(v, ScrollView) or id(v) in ancestors[i] or id(w) in theirs:
                continue
            ix = min(x1, ox1) - max(x0, ox0)
            iy = min(y1, oy1) - max(y0, oy0)
            if ix > 0 and iy > 0 and ix * iy > COVER_FRACTION * area:
                report(w, f"covered by {_name(v)}", box)
                break
    return problems
