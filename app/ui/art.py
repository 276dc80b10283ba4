"""Procedural pictures: backgrounds, icons and character badges drawn with Kivy's canvas.

Drawn rather than shipped as images so they stay sharp at any screen density, cost no
package space, and look the same on the tablet, the projector view and in screenshots.
Every function draws into the *current* canvas context (call inside ``with canvas:``).
"""
from __future__ import annotations

import math

from kivy.graphics import Color, Ellipse, Line, Rectangle, RoundedRectangle, Triangle

# name -> (base colour, accent colour), RGB 0..1
BACKGROUND_COLOURS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "sky": ((0.62, 0.84, 0.98), (1.0, 1.0, 1.0)),
    "grass": ((0.55, 0.80, 0.42), (1.0, 0.85, 0.3)),
    "night": ((0.10, 0.13, 0.32), (1.0, 0.95, 0.6)),
    "sea": ((0.20, 0.50, 0.80), (0.75, 0.90, 1.0)),
    "castle": ((0.93, 0.86, 0.72), (0.60, 0.55, 0.65)),
    "forest": ((0.30, 0.55, 0.30), (0.15, 0.38, 0.18)),
    "space": ((0.06, 0.04, 0.14), (0.95, 0.55, 0.35)),
    "sand": ((0.96, 0.84, 0.55), (0.88, 0.70, 0.40)),
}
CHARACTER_COLOURS = {"robot": (0.45, 0.55, 0.75), "animal": (0.95, 0.60, 0.25), "child": (0.95, 0.50, 0.65)}
MOTION_COLOURS = {"walk": (0.30, 0.65, 0.35), "run": (0.90, 0.45, 0.20), "jump": (0.25, 0.55, 0.90),
                  "dance": (0.75, 0.35, 0.80), "kick": (0.85, 0.30, 0.30), "more": (0.5, 0.5, 0.5)}

# Stick-figure poses on a unit square: head centre, then line strips (body, arms, legs).
_POSES: dict[str, tuple[tuple[float, float], list[list[tuple[float, float]]]]] = {
    "walk": ((0.5, 0.82), [[(0.5, 0.72), (0.5, 0.42)], [(0.32, 0.50), (0.5, 0.65), (0.66, 0.52)],
                          [(0.36, 0.1), (0.5, 0.42), (0.62, 0.1)]]),
    "run": ((0.6, 0.82), [[(0.58, 0.72), (0.48, 0.42)], [(0.30, 0.60), (0.55, 0.66), (0.72, 0.52)],
                         [(0.22, 0.2), (0.48, 0.42), (0.70, 0.25), (0.62, 0.06)]]),
    "jump": ((0.5, 0.86), [[(0.5, 0.76), (0.5, 0.48)], [(0.25, 0.92), (0.5, 0.68), (0.75, 0.92)],
                          [(0.32, 0.22), (0.5, 0.48), (0.68, 0.22)]]),
    "dance": ((0.45, 0.82), [[(0.46, 0.72), (0.52, 0.42)], [(0.2, 0.78), (0.48, 0.64), (0.78, 0.50)],
                            [(0.35, 0.08), (0.52, 0.42), (0.82, 0.30)]]),
    "kick": ((0.35, 0.82), [[(0.36, 0.72), (0.40, 0.42)], [(0.15, 0.55), (0.38, 0.64), (0.60, 0.70)],
                           [(0.35, 0.06), (0.40, 0.42), (0.88, 0.48)]]),
}


def draw_background(name: str, x: float, y: float, w: float, h: float, dim: float = 1.0) -> None:
    """A simple scene picture filling (x, y, w, h); ``dim`` < 1 darkens it (projector preview)."""
    base, accent = BACKGROUND_COLOURS.get(name, BACKGROUND_COLOURS["sky"])
    Color(*(c * dim for c in base))
    Rectangle(pos=(x, y), size=(w, h))
    Color(*(c * dim for c in accent))
    s = min(w, h)
    if name == "sky":
        Color(1.0 * dim, 0.85 * dim, 0.2 * dim)
        Ellipse(pos=(x + w - 0.22 * s, y + h - 0.22 * s), size=(0.16 * s, 0.16 * s))
        Color(dim, dim, dim)
        for cx, cy in ((0.2, 0.75), (0.55, 0.6), (0.3, 0.3)):
            for dx in (0, 0.05, 0.1):
                Ellipse(pos=(x + (cx + dx) * w, y + cy * h), size=(0.1 * s, 0.06 * s))
    elif name == "grass":
        for i in range(14):
            fx, fy = (i * 0.37) % 1.0, (i * 0.61) % 1.0
            Ellipse(pos=(x + fx * w, y + fy * h), size=(0.03 * s, 0.03 * s))
    elif name in ("night", "space"):
        for i in range(40):
            fx, fy = (i * 0.137) % 1.0, (i * 0.311 + 0.05) % 1.0
            r = 0.006 * s if i % 3 else 0.01 * s
            Color(dim, dim, 0.85 * dim)
            Ellipse(pos=(x + fx * w, y + fy * h), size=(r, r))
        Color(*(c * dim for c in accent))
        Ellipse(pos=(x + 0.78 * w, y + 0.70 * h), size=(0.14 * s, 0.14 * s))
        if name == "space":
            Color(0.5 * dim, 0.7 * dim, 1.0 * dim)
            Line(ellipse=(x + 0.75 * w, y + 0.70 * h + 0.04 * s, 0.2 * s, 0.06 * s), width=1.5)
    elif name == "sea":
        for row in range(6):
            pts = []
            for i in range(41):
                px = x + w * i / 40
                pts += [px, y + h * (row + 0.5) / 6 + 0.012 * s * math.sin(i * 0.9 + row)]
            Line(points=pts, width=1.4)
    elif name == "castle":
        bx, by, bw, bh = x + 0.3 * w, y + 0.55 * h, 0.4 * w, 0.3 * h
        Rectangle(pos=(bx, by), size=(bw, bh))
        for i in range(5):
            Rectangle(pos=(bx + i * bw / 4.5, by + bh), size=(bw / 9, 0.05 * h))
        Color(0.35 * dim, 0.25 * dim, 0.2 * dim)
        Rectangle(pos=(bx + 0.42 * bw, by), size=(0.16 * bw, 0.45 * bh))
    elif name == "forest":
        for i in range(9):
            tx, ty = x + ((i * 0.29) % 0.9) * w, y + ((i * 0.47) % 0.85) * h
            Triangle(points=[tx, ty, tx + 0.09 * s, ty, tx + 0.045 * s, ty + 0.13 * s])
    elif name == "sand":
        for i in range(4):  # dunes, inside the picture (a cover tile draws it in a square)
            Ellipse(pos=(x + i * 0.22 * w, y + i * 0.04 * h), size=(0.34 * w, 0.2 * h))


def draw_icon(name: str, x: float, y: float, size: float, colour: tuple[float, float, float] = (0.15, 0.15, 0.2)) -> None:
    """An icon in the square (x, y, size); names match motions, characters and actions."""
    s = size
    lw = max(1.5, s * 0.06)
    if not name:  # a text-only key (e.g. a digit on the PIN pad)
        return

    def P(u: float, v: float) -> tuple[float, float]:
        return x + u * s, y + v * s

    if name in _POSES:
        head, strips = _POSES[name]
        Color(*colour)
        hx, hy = P(*head)
        Ellipse(pos=(hx - 0.09 * s, hy - 0.09 * s), size=(0.18 * s, 0.18 * s))
        for strip in strips:
            Line(points=[c for p in strip for c in P(*p)], width=lw, cap="round", joint="round")
        return
    if name in ("robot", "animal", "child"):
        draw_character_badge(name, x + s / 2, y + s / 2, s / 2)
        return
    Color(*colour)
    if name == "more":
        for u in (0.25, 0.5, 0.75):
            cx, cy = P(u, 0.5)
            Ellipse(pos=(cx - 0.07 * s, cy - 0.07 * s), size=(0.14 * s, 0.14 * s))
    elif name in ("undo", "redo"):
        # a U-turn arrow: head on the top line, pointing back (undo: left, redo: right)
        m = 1 if name == "undo" else -1

        def Q(u: float, v: float) -> tuple[float, float]:
            return P(0.5 + m * (u - 0.5), v)
        top, bottom, turn = 0.68, 0.28, 0.62
        Line(points=[*Q(0.32, top), *Q(turn, top)], width=lw, cap="none")
        cx, cy = Q(turn, (top + bottom) / 2)
        r = (top - bottom) / 2 * s
        Line(circle=(cx, cy, r, 0, 180) if m == 1 else (cx, cy, r, 180, 360), width=lw)
        Line(points=[*Q(turn, bottom), *Q(0.25, bottom)], width=lw, cap="round")
        Triangle(points=[*Q(0.1, top), *Q(0.34, top + 0.16), *Q(0.34, top - 0.16)])
    elif name == "play":
        Triangle(points=[*P(0.25, 0.15), *P(0.25, 0.85), *P(0.85, 0.5)])
    elif name == "pause":
        Rectangle(pos=P(0.22, 0.15), size=(0.2 * s, 0.7 * s))
        Rectangle(pos=P(0.58, 0.15), size=(0.2 * s, 0.7 * s))
    elif name == "home":
        Triangle(points=[*P(0.1, 0.5), *P(0.9, 0.5), *P(0.5, 0.9)])
        Rectangle(pos=P(0.2, 0.1), size=(0.6 * s, 0.42 * s))
    elif name == "add":
        Rectangle(pos=P(0.42, 0.12), size=(0.16 * s, 0.76 * s))
        Rectangle(pos=P(0.12, 0.42), size=(0.76 * s, 0.16 * s))
    elif name == "duplicate":
        Line(rectangle=(*P(0.1, 0.3), 0.5 * s, 0.55 * s), width=lw)
        Line(rectangle=(*P(0.38, 0.12), 0.5 * s, 0.55 * s), width=lw)
    elif name == "delete":
        Line(points=[*P(0.2, 0.2), *P(0.8, 0.8)], width=lw * 1.4, cap="round")
        Line(points=[*P(0.2, 0.8), *P(0.8, 0.2)], width=lw * 1.4, cap="round")
    elif name == "teacher":
        Line(ellipse=(*P(0.3, 0.45), 0.4 * s, 0.45 * s, -90, 90), width=lw)
        RoundedRectangle(pos=P(0.18, 0.1), size=(0.64 * s, 0.45 * s), radius=[0.06 * s])
    elif name == "projector":
        Rectangle(pos=P(0.08, 0.35), size=(0.4 * s, 0.3 * s))
        Color(*colour, 0.5)
        Triangle(points=[*P(0.48, 0.5), *P(0.95, 0.9), *P(0.95, 0.1)])
    elif name == "hop":
        Line(points=[*P(0.05, 0.2), *P(0.25, 0.7), *P(0.5, 0.85), *P(0.75, 0.7), *P(0.95, 0.2)], width=lw)
    elif name == "spin":
        Line(circle=(*P(0.5, 0.55), 0.28 * s, 0, 300), width=lw)
        Line(points=[*P(0.05, 0.15), *P(0.45, 0.27)], width=lw)
    elif name == "language":
        Line(circle=(*P(0.5, 0.5), 0.4 * s), width=lw)
        Line(ellipse=(*P(0.3, 0.1), 0.4 * s, 0.8 * s), width=lw * 0.7)
        Line(points=[*P(0.1, 0.5), *P(0.9, 0.5)], width=lw * 0.7)
    elif name == "calibration":
        for u in (0.1, 0.36, 0.62):
            for v in (0.1, 0.36, 0.62):
                if int(u * 10 + v * 10) % 2 == 0:
                    Rectangle(pos=P(u, v), size=(0.26 * s, 0.26 * s))
        Line(rectangle=(*P(0.1, 0.1), 0.78 * s, 0.78 * s), width=lw * 0.5)
    elif name == "export":
        Rectangle(pos=P(0.42, 0.35), size=(0.16 * s, 0.55 * s))
        Triangle(points=[*P(0.25, 0.4), *P(0.75, 0.4), *P(0.5, 0.12)])
        Rectangle(pos=P(0.1, 0.05), size=(0.8 * s, 0.08 * s))
    elif name == "act":  # "Act it out": a camera watching a child with arms up
        RoundedRectangle(pos=P(0.04, 0.52), size=(0.36 * s, 0.26 * s), radius=[0.04 * s])
        Rectangle(pos=P(0.12, 0.76), size=(0.12 * s, 0.05 * s))
        Color(1, 1, 1)
        cx, cy = P(0.22, 0.65)
        Ellipse(pos=(cx - 0.08 * s, cy - 0.08 * s), size=(0.16 * s, 0.16 * s))
        Color(*colour)
        Ellipse(pos=(cx - 0.045 * s, cy - 0.045 * s), size=(0.09 * s, 0.09 * s))
        hx, hy = P(0.72, 0.8)
        Ellipse(pos=(hx - 0.08 * s, hy - 0.08 * s), size=(0.16 * s, 0.16 * s))
        for strip in ([(0.72, 0.7), (0.72, 0.38)], [(0.52, 0.82), (0.72, 0.62), (0.92, 0.82)],
                      [(0.6, 0.06), (0.72, 0.38), (0.84, 0.06)]):
            Line(points=[c for p in strip for c in P(*p)], width=lw, cap="round", joint="round")
    elif name == "record":  # a red dot, as on every recorder
        Color(0.85, 0.15, 0.15)
        Ellipse(pos=P(0.2, 0.2), size=(0.6 * s, 0.6 * s))
    elif name == "stop":
        Rectangle(pos=P(0.24, 0.24), size=(0.52 * s, 0.52 * s))
    elif name == "similar":  # "more like this": a figure and a fainter one like it beside it
        head, strips = _POSES["walk"]
        for du, alpha in ((0.42, 0.45), (0.0, 1.0)):
            Color(*colour, alpha)
            hx, hy = P(head[0] * 0.6 + du + 0.0, head[1] * 0.9 + 0.05)
            Ellipse(pos=(hx - 0.07 * s, hy - 0.07 * s), size=(0.14 * s, 0.14 * s))
            for strip in strips:
                Line(points=[c for p in strip for c in P(p[0] * 0.6 + du, p[1] * 0.9 + 0.05)], width=lw * 0.8,
                     cap="round", joint="round")
    elif name == "pose":  # a figure with arms out inside the corners of a frame
        for (u, v, du, dv) in ((0.05, 0.05, 1, 1), (0.95, 0.05, -1, 1), (0.05, 0.95, 1, -1), (0.95, 0.95, -1, -1)):
            Line(points=[*P(u + 0.18 * du, v), *P(u, v), *P(u, v + 0.18 * dv)], width=lw * 0.7)
        hx, hy = P(0.5, 0.76)
        Ellipse(pos=(hx - 0.08 * s, hy - 0.08 * s), size=(0.16 * s, 0.16 * s))
        for strip in ([(0.5, 0.67), (0.5, 0.4)], [(0.22, 0.62), (0.5, 0.6), (0.78, 0.62)],
                      [(0.36, 0.14), (0.5, 0.4), (0.64, 0.14)]):
            Line(points=[c for p in strip for c in P(*p)], width=lw, cap="round", joint="round")
    elif name == "groups":  # dots gathered into three rings
        for cu, cv in ((0.28, 0.68), (0.72, 0.68), (0.5, 0.28)):
            Line(circle=(*P(cu, cv), 0.2 * s), width=lw * 0.6)
            for du, dv in ((-0.07, -0.05), (0.07, -0.05), (0.0, 0.07)):
                cx, cy = P(cu + du, cv + dv)
                Ellipse(pos=(cx - 0.04 * s, cy - 0.04 * s), size=(0.08 * s, 0.08 * s))
    elif name in ("tick", "keep"):  # done, saved, keep this
        Line(points=[*P(0.12, 0.5), *P(0.4, 0.2), *P(0.9, 0.82)], width=lw * 1.6, cap="round", joint="round")
    elif name == "bin":  # the story bin: a can with a lid
        Rectangle(pos=P(0.12, 0.74), size=(0.76 * s, 0.08 * s))
        Rectangle(pos=P(0.4, 0.82), size=(0.2 * s, 0.06 * s))
        Line(points=[*P(0.2, 0.7), *P(0.27, 0.08), *P(0.73, 0.08), *P(0.8, 0.7)], width=lw, joint="round")
        for u in (0.38, 0.5, 0.62):
            Line(points=[*P(u, 0.6), *P(u, 0.18)], width=lw * 0.6)
    elif name in ("mic", "voice"):  # a microphone: a voice to record
        RoundedRectangle(pos=P(0.36, 0.4), size=(0.28 * s, 0.5 * s), radius=[0.14 * s])
        Line(ellipse=(*P(0.24, 0.22), 0.52 * s, 0.52 * s, 90, 270), width=lw)
        Line(points=[*P(0.5, 0.22), *P(0.5, 0.08)], width=lw)
        Line(points=[*P(0.32, 0.08), *P(0.68, 0.08)], width=lw, cap="round")
    elif name == "rename":  # a pencil
        Line(points=[*P(0.2, 0.2), *P(0.78, 0.78)], width=lw * 2.2, cap="none")
        Triangle(points=[*P(0.1, 0.1), *P(0.3, 0.16), *P(0.16, 0.3)])
    elif name in ("sky", "grass", "night", "sea", "castle", "forest", "space", "sand"):
        draw_background(name, x, y, s, s)
    else:  # unknown: a plain dot, never an empty button
        Ellipse(pos=P(0.3, 0.3), size=(0.4 * s, 0.4 * s))


def draw_character_badge(kind: str, cx: float, cy: float, r: float, dim: float = 1.0) -> None:
    """A round badge with a face, used as the character's marker on the table view."""
    colour = CHARACTER_COLOURS.get(kind, (0.6, 0.6, 0.6))
    Color(*(c * dim for c in colour))
    if kind == "animal":  # ears
        Ellipse(pos=(cx - 0.85 * r, cy + 0.35 * r), size=(0.6 * r, 0.6 * r))
        Ellipse(pos=(cx + 0.25 * r, cy + 0.35 * r), size=(0.6 * r, 0.6 * r))
    if kind == "robot":
        RoundedRectangle(pos=(cx - 0.8 * r, cy - 0.8 * r), size=(1.6 * r, 1.6 * r), radius=[0.25 * r])
        Line(points=[cx, cy + 0.8 * r, cx, cy + 1.05 * r], width=max(1.0, 0.08 * r))
        Ellipse(pos=(cx - 0.1 * r, cy + 0.98 * r), size=(0.2 * r, 0.2 * r))
    else:
        Ellipse(pos=(cx - 0.8 * r, cy - 0.8 * r), size=(1.6 * r, 1.6 * r))
    Color(dim, dim, dim)
    for ex in (-0.3, 0.3):
        Ellipse(pos=(cx + ex * r - 0.15 * r, cy + 0.05 * r), size=(0.3 * r, 0.3 * r))
    Color(0.1 * dim, 0.1 * dim, 0.1 * dim)
    for ex in (-0.3, 0.3):
        Ellipse(pos=(cx + ex * r - 0.07 * r, cy + 0.1 * r), size=(0.14 * r, 0.14 * r))
    Line(ellipse=(cx - 0.35 * r, cy - 0.5 * r, 0.7 * r, 0.5 * r, 110, 250), width=max(1.0, 0.06 * r))
