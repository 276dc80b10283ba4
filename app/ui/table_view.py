"""The top-down view of the table: where children sketch paths, and the 2-D preview.

Touch handling follows Kivy's *touchtracer* example: on touch-down the widget grabs the
touch and starts a line, on move it appends points, on up it ungrabs and reports the
stroke. Points are converted to table metres at once (x right, y away from the child),
so the model never sees pixels.
"""
from __future__ import annotations

import math
import time

from kivy.graphics import Color, Ellipse, InstructionGroup, Line, Rectangle
from kivy.metrics import dp
from kivy.properties import ListProperty, NumericProperty, ObjectProperty, OptionProperty, StringProperty
from kivy.uix.widget import Widget

from app.story import TABLE_DEPTH_M, TABLE_WIDTH_M, Scene, thin
from app.ui.art import CHARACTER_COLOURS, draw_background, draw_character_badge, draw_icon

#: A sketch drawn faster than this (table metres per second) is slowed down to it, so a
#: quick flick still gives a character time to walk.
MAX_SKETCH_SPEED_MS = 0.4
MIN_SKETCH_SECONDS = 1.0


def normalise_times(points: list[tuple[float, float, float]]) -> list[tuple[float, float, float]]:
    """Start the path at t = 0 and stretch it to a walkable speed (see MAX_SKETCH_SPEED_MS)."""
    if not points:
        return []
    t0 = points[0][2]
    pts = [(x, y, t - t0) for x, y, t in points]
    length = sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(pts, pts[1:]))
    duration = pts[-1][2]
    wanted = max(MIN_SKETCH_SECONDS, length / MAX_SKETCH_SPEED_MS)
    if len(pts) > 1 and duration < wanted:
        if duration <= 1e-6:  # no usable timing: spread by distance
            cum, out = 0.0, [pts[0]]
            for a, b in zip(pts, pts[1:]):
                cum += math.hypot(b[0] - a[0], b[1] - a[1])
                out.append((b[0], b[1], cum))
            scale = wanted / cum if cum > 0 else 0.0
            pts = [(x, y, t * scale if cum > 0 else i * wanted / (len(out) - 1))
                   for i, (x, y, t) in enumerate(out)]
        else:
            k = wanted / duration
            pts = [(x, y, t * k) for x, y, t in pts]
    return [(round(x, 4), round(y, 4), round(t, 3)) for x, y, t in pts]


class TableView(Widget):
    """Top-down table: background, paths, marks and character badges at ``time``.

    ``mode``: "edit" (sketching allowed), "preview" (animated, no touch), "projector"
    (black background as the projector shows it, characters only).
    Dispatches ``on_sketch(points)`` with table-metre points when a stroke ends.
    """

    scene = ObjectProperty(None, allownone=True)
    selected_id = StringProperty("")
    time = NumericProperty(0.0)
    mode = OptionProperty("edit", options=["edit", "preview", "projector"])
    frame_texture = ObjectProperty(None, allownone=True)  # a rendered 3-D frame, when available
    #: a stroke drawn before there was a character to give it to (table metres): drawn
    #: dashed until a character is added, who then takes it as its path
    pending = ListProperty([])

    __events__ = ("on_sketch",)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._live = InstructionGroup()
        self.bind(pos=self.redraw, size=self.redraw, scene=self.redraw, selected_id=self.redraw,
                  time=self.redraw, mode=self.redraw, frame_texture=self.redraw, pending=self.redraw)

    # -- geometry -------------------------------------------------------------------
    @property
    def table_rect(self) -> tuple[float, float, float, float]:
        """(x, y, w, h) in pixels of the table area, letter-boxed to the table's aspect."""
        aspect = TABLE_WIDTH_M / TABLE_DEPTH_M
        w, h = self.width, self.height
        if w / max(h, 1) > aspect:
            tw, th = h * aspect, h
        else:
            tw, th = w, w / aspect
        return self.x + (w - tw) / 2, self.y + (h - th) / 2, tw, th

    def to_table(self, px: float, py: float) -> tuple[float, float]:
        x, y, w, h = self.table_rect
        mx = (px - x) / w * TABLE_WIDTH_M
        my = (py - y) / h * TABLE_DEPTH_M
        return min(max(mx, 0.0), TABLE_WIDTH_M), min(max(my, 0.0), TABLE_DEPTH_M)

    def to_px(self, mx: float, my: float) -> tuple[float, float]:
        x, y, w, h = self.table_rect
        return x + mx / TABLE_WIDTH_M * w, y + my / TABLE_DEPTH_M * h

    # -- touch (touchtracer style) --------------------------------------------------
    def on_touch_down(self, touch):
        if self.mode != "edit" or not self.collide_point(*touch.pos):
            return super().on_touch_down(touch)
        touch.grab(self)
        mx, my = self.to_table(*touch.pos)
        touch.ud["storybeam_points"] = [(mx, my, self._touch_time(touch))]
        self._live.clear()
        self._live.add(Color(1.0, 0.45, 0.1, 0.9))
        line = Line(points=list(touch.pos), width=dp(4), cap="round", joint="round")
        touch.ud["storybeam_line"] = line
        self._live.add(line)
        if self._live not in self.canvas.after.children:
            self.canvas.after.add(self._live)
        return True

    def on_touch_move(self, touch):
        if touch.grab_current is not self:
            return super().on_touch_move(touch)
        mx, my = self.to_table(*touch.pos)
        touch.ud["storybeam_points"].append((mx, my, self._touch_time(touch)))
        touch.ud["storybeam_line"].points += list(touch.pos)
        return True

    def on_touch_up(self, touch):
        if touch.grab_current is not self:
            return super().on_touch_up(touch)
        touch.ungrab(self)
        mx, my = self.to_table(*touch.pos)
        points = touch.ud.pop("storybeam_points", [])
        points.append((mx, my, self._touch_time(touch)))
        self._live.clear()
        thinned = thin(points)
        if len(thinned) >= 2:
            self.dispatch("on_sketch", thinned)
        return True

    @staticmethod
    def _touch_time(touch) -> float:
        return float(getattr(touch, "time_update", 0.0) or getattr(touch, "time_start", 0.0) or time.time())

    def on_sketch(self, points):  # default handler (Kivy event)
        pass

    # -- drawing --------------------------------------------------------------------
    def redraw(self, *_: object) -> None:
        self.canvas.clear()
        scene: Scene | None = self.scene
        x, y, w, h = self.table_rect
        with self.canvas:
            if self.mode == "projector":
                Color(0, 0, 0, 1)
                Rectangle(pos=self.pos, size=self.size)
            else:
                Color(0.2, 0.2, 0.25, 1)
                Rectangle(pos=self.pos, size=self.size)
            if scene is None:
                return
            if self.frame_texture is not None:
                Color(1, 1, 1, 1)
                Rectangle(texture=self.frame_texture, pos=(x, y), size=(w, h))
                return
            if self.mode != "projector":
                draw_background(scene.background, x, y, w, h)
            badge_r = max(dp(16), w * 0.028)
            if len(self.pending) >= 2 and self.mode == "edit":
                line = [c for p in self.pending for c in self.to_px(p[0], p[1])]
                Color(1, 1, 1, 0.35)  # Kivy dashes only 1-px lines: a faint wide line under a dashed one
                Line(points=line, width=dp(4), cap="round", joint="round")
                Color(1, 1, 1, 1)
                Line(points=line, width=1, dash_length=dp(10), dash_offset=dp(6))
            for character in scene.characters:
                self._draw_path(character, badge_r)
            for character in scene.characters:
                if self.mode == "edit":
                    where = character.path[0][:2] if character.path else None
                else:
                    where = character.position_at(self.time)
                if where is None:
                    continue
                cx, cy = self.to_px(*where)
                if character.id == self.selected_id and self.mode == "edit":
                    Color(1.0, 0.55, 0.1, 1)
                    Ellipse(pos=(cx - badge_r * 1.25, cy - badge_r * 1.25), size=(badge_r * 2.5, badge_r * 2.5))
                draw_character_badge(character.kind, cx, cy, badge_r)

    def _draw_path(self, character, badge_r: float) -> None:
        if len(character.path) < 2:
            return
        selected = character.id == self.selected_id
        r, g, b = CHARACTER_COLOURS.get(character.kind, (1, 1, 1))
        alpha = 1.0 if (selected or self.mode != "edit") else 0.6
        if self.mode == "projector":
            Color(r, g, b, 0.35)
        else:
            Color(1, 1, 1, 0.55 * alpha)
            Line(points=[c for p in character.path for c in self.to_px(p[0], p[1])], width=dp(7 if selected else 5),
                 cap="round", joint="round")
            Color(r, g, b, alpha)
        Line(points=[c for p in character.path for c in self.to_px(p[0], p[1])], width=dp(4 if selected else 2.5),
             cap="round", joint="round")
        ex, ey = self.to_px(*character.path[-1][:2])
        Ellipse(pos=(ex - dp(6), ey - dp(6)), size=(dp(12), dp(12)))
        for mark in character.marks:
            pos = character.position_at(mark.at)
            if pos is None:
                continue
            mx, my = self.to_px(*pos)
            s = badge_r * 1.6
            Color(1, 1, 1, 0.9)
            Ellipse(pos=(mx - s / 2, my + badge_r * 0.2), size=(s, s))
            draw_icon(mark.kind, mx - s * 0.4, my + badge_r * 0.2 + s * 0.1, s * 0.8, (0.9, 0.3, 0.1))
