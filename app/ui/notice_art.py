"""The pictures of the app's notices (:mod:`app.ui.notices`): what went wrong, drawn so a
child who cannot read sees it -- a thing (a speaker, a microphone, a sheet of paper, a
camera, a box of stories, a character, a face) with a mark on it (a red cross: it does not
work; scissors: cut it shorter; a plus: add one first; a clock: wait; a padlock: for
grown-ups). Drawn with Kivy's canvas like :mod:`app.ui.art`, so they stay sharp at every
density and cost no package space.
"""
from __future__ import annotations

from kivy.graphics import Color, Ellipse, Line, Rectangle, RoundedRectangle, Triangle

from app.ui.art import draw_character_badge, draw_icon

INK = (0.15, 0.15, 0.2)
RED = (0.85, 0.2, 0.2)

#: notice picture -> (thing, mark)
PICTURES: dict[str, tuple[str, str]] = {
    "add_someone": ("character", "plus"),
    "sound_broken": ("speaker", "cross"),
    "sound_long": ("speaker", "scissors"),
    "sound_silent": ("microphone", "zzz"),
    "no_microphone": ("microphone", "cross"),
    "recording_off": ("microphone", "padlock"),
    "file_broken": ("sheet", "cross"),
    "file_big": ("sheet", "scissors"),
    "story_full": ("speaker", "full"),
    "no_camera": ("camera", "cross"),
    "storage": ("box", "cross"),
    "grown_up": ("box", "padlock"),
    "wait": ("face", "clock"),
    "oops": ("face", "cross"),
}


def _thing(name: str, x: float, y: float, s: float) -> None:
    lw = max(1.5, s * 0.05)

    def P(u: float, v: float) -> tuple[float, float]:
        return x + u * s, y + v * s
    Color(*INK)
    if name == "speaker":
        Rectangle(pos=P(0.12, 0.38), size=(0.16 * s, 0.24 * s))
        Triangle(points=[*P(0.26, 0.5), *P(0.5, 0.82), *P(0.5, 0.18)])
        Triangle(points=[*P(0.26, 0.62), *P(0.26, 0.38), *P(0.5, 0.5)])
        for r in (0.16, 0.28):
            Line(circle=(*P(0.5, 0.5), r * s, 50, 130), width=lw)
    elif name == "microphone":
        RoundedRectangle(pos=P(0.38, 0.42), size=(0.24 * s, 0.44 * s), radius=[0.12 * s])
        Line(circle=(*P(0.5, 0.52), 0.2 * s, 90, 270), width=lw)
        Line(points=[*P(0.5, 0.32), *P(0.5, 0.14)], width=lw)
        Line(points=[*P(0.36, 0.14), *P(0.64, 0.14)], width=lw, cap="round")
    elif name == "sheet":
        Line(points=[*P(0.22, 0.08), *P(0.22, 0.92), *P(0.58, 0.92), *P(0.78, 0.72), *P(0.78, 0.08),
                     *P(0.22, 0.08)], width=lw, joint="round")
        Line(points=[*P(0.58, 0.92), *P(0.58, 0.72), *P(0.78, 0.72)], width=lw * 0.7)
        for v in (0.55, 0.42, 0.29):
            Line(points=[*P(0.32, v), *P(0.68, v)], width=lw * 0.6)
    elif name == "camera":
        RoundedRectangle(pos=P(0.1, 0.25), size=(0.8 * s, 0.5 * s), radius=[0.08 * s])
        Rectangle(pos=P(0.3, 0.75), size=(0.2 * s, 0.08 * s))
        Color(1, 1, 1)
        Ellipse(pos=P(0.34, 0.31), size=(0.32 * s, 0.32 * s))
        Color(*INK)
        Ellipse(pos=P(0.41, 0.38), size=(0.18 * s, 0.18 * s))
    elif name == "box":
        Rectangle(pos=P(0.14, 0.12), size=(0.72 * s, 0.5 * s))
        Color(0.95, 0.8, 0.45)
        for i, colour in enumerate(((0.45, 0.55, 0.75), (0.95, 0.6, 0.25), (0.95, 0.5, 0.65))):
            Color(*colour)
            Rectangle(pos=P(0.2 + 0.2 * i, 0.55), size=(0.16 * s, 0.3 * s))
    elif name == "character":
        draw_character_badge("child", x + 0.42 * s, y + 0.45 * s, 0.32 * s)
    elif name == "face":
        Color(1.0, 0.85, 0.35)
        Ellipse(pos=P(0.12, 0.12), size=(0.76 * s, 0.76 * s))
        Color(*INK)
        for u in (0.36, 0.64):
            Ellipse(pos=P(u - 0.05, 0.52), size=(0.1 * s, 0.1 * s))
        Line(ellipse=(*P(0.32, 0.22), 0.36 * s, 0.3 * s, -60, 60), width=lw)  # a small frown


def _mark(name: str, x: float, y: float, s: float) -> None:
    """The mark in the picture's lower-right quarter (x, y, s: that quarter's square)."""
    lw = max(2.0, s * 0.12)

    def P(u: float, v: float) -> tuple[float, float]:
        return x + u * s, y + v * s
    Color(1, 1, 1)
    Ellipse(pos=P(-0.05, -0.05), size=(1.1 * s, 1.1 * s))
    if name == "cross":
        Color(*RED)
        Line(points=[*P(0.22, 0.22), *P(0.78, 0.78)], width=lw, cap="round")
        Line(points=[*P(0.22, 0.78), *P(0.78, 0.22)], width=lw, cap="round")
    elif name == "plus":
        Color(0.2, 0.65, 0.3)
        draw_icon("add", x + 0.1 * s, y + 0.1 * s, 0.8 * s, (0.2, 0.65, 0.3))
    elif name == "scissors":
        Color(*INK)
        for v in (0.3, 0.7):
            Line(circle=(*P(0.22, v), 0.14 * s), width=lw * 0.5)
        Line(points=[*P(0.33, 0.36), *P(0.9, 0.7)], width=lw * 0.5, cap="round")
        Line(points=[*P(0.33, 0.64), *P(0.9, 0.3)], width=lw * 0.5, cap="round")
    elif name == "zzz":
        Color(0.3, 0.4, 0.8)
        for i, (u, v, k) in enumerate(((0.15, 0.15, 0.35), (0.45, 0.45, 0.28), (0.7, 0.7, 0.22))):
            Line(points=[*P(u, v + k), *P(u + k, v + k), *P(u, v), *P(u + k, v)], width=lw * 0.35)
    elif name == "full":
        Color(0.95, 0.6, 0.2)
        for i in range(4):
            Rectangle(pos=P(0.15, 0.12 + 0.2 * i), size=(0.7 * s, 0.14 * s))
    elif name == "clock":
        Color(*INK)
        Line(circle=(*P(0.5, 0.5), 0.4 * s), width=lw * 0.5)
        Line(points=[*P(0.5, 0.5), *P(0.5, 0.8)], width=lw * 0.5, cap="round")
        Line(points=[*P(0.5, 0.5), *P(0.72, 0.5)], width=lw * 0.5, cap="round")
    elif name == "padlock":
        Color(0.85, 0.65, 0.15)
        RoundedRectangle(pos=P(0.18, 0.1), size=(0.64 * s, 0.5 * s), radius=[0.08 * s])
        Line(ellipse=(*P(0.3, 0.42), 0.4 * s, 0.5 * s, -90, 90), width=lw * 0.5)


def draw_notice(picture: str, x: float, y: float, size: float) -> None:
    """The notice picture ``picture`` (a key of :data:`PICTURES`; unknown: *oops*) in
    the square (x, y, size)."""
    thing, mark = PICTURES.get(picture, PICTURES["oops"])
    _thing(thing, x, y, size)
    _mark(mark, x + 0.55 * size, y, 0.45 * size)
