"""The story film's drawn pictures: each place's sky, the title card and the ending card.

No words anywhere (the children may not read yet): the title card is the story's cover
picture (or its first place) with its cast, revealed by a stage curtain opening; the
ending card is the whole cast bouncing under confetti (:func:`app.player.celebration.confetti`,
as Play's celebration) while the curtain closes on a heart.

Palette: :data:`PLACES` gives every place its ground (the table top's colour in the 3-D
Play preview, :func:`app.player.preview.table_colour`) and its sky (a vertical gradient
and what is in it: sun and clouds, moon and stars, a ringed planet, gulls). Character
badges use the tablet's colours (``app.ui.art.CHARACTER_COLOURS``).

Pillow draws (imported on first use: the module is light, and Android never exports).
Frames are (H, W, 3) uint8 RGB.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from app.player.celebration import CELEBRATION_SECONDS, confetti
from app.story import COVER_COLOURS, Story

#: the story film's size and rate: what a class projector shows well
FILM_SIZE = (1280, 720)
FILM_FPS = 30.0
#: the title card's and the ending card's lengths (seconds)
TITLE_SECONDS = 2.0
ENDING_SECONDS = CELEBRATION_SECONDS


def card_frames(fps: float) -> tuple[int, int]:
    """(title card frames, ending card frames) at ``fps``."""
    return max(1, round(TITLE_SECONDS * fps)), max(1, round(ENDING_SECONDS * fps))


@dataclass(frozen=True)
class Place:
    """A place's colours (RGB 0..255): ground, sky at the top and at the horizon, and what
    is drawn in the sky (``sun``, ``clouds``, ``moon``, ``stars``, ``planet``, ``gulls``)."""

    ground: tuple[int, int, int]
    sky_top: tuple[int, int, int]
    sky_horizon: tuple[int, int, int]
    things: tuple[str, ...]


PLACES: dict[str, Place] = {
    "sky": Place((158, 214, 250), (70, 150, 235), (200, 232, 255), ("sun", "clouds")),
    "grass": Place((140, 204, 107), (90, 170, 240), (205, 235, 255), ("sun", "clouds")),
    "night": Place((40, 50, 110), (8, 10, 40), (40, 50, 110), ("moon", "stars")),
    "sea": Place((70, 140, 210), (110, 185, 245), (215, 240, 255), ("sun", "gulls")),
    "castle": Place((237, 219, 184), (120, 170, 230), (240, 220, 235), ("clouds",)),
    "forest": Place((77, 140, 77), (120, 190, 230), (215, 240, 220), ("sun", "clouds")),
    "space": Place((40, 30, 70), (2, 2, 12), (30, 20, 60), ("stars", "planet")),
    "sand": Place((245, 214, 140), (250, 170, 80), (255, 230, 170), ("sun",)),
}
DEFAULT_PLACE = Place((150, 150, 160), (120, 170, 230), (220, 235, 250), ())
CHARACTER_COLOURS = {"robot": (115, 140, 191), "animal": (242, 153, 64), "child": (242, 128, 166)}
CURTAIN = (190, 30, 45)
HEART = (255, 89, 120)


def place(name: str) -> Place:
    return PLACES.get(name, DEFAULT_PLACE)


def _mix(a, b, u: float) -> tuple[int, int, int]:
    return tuple(int(round(x + (y - x) * u)) for x, y in zip(a, b))


def sky_picture(name: str, size: tuple[int, int]) -> np.ndarray:
    """The sky of place ``name`` at ``size`` (W, H): a gradient from ``sky_top`` to
    ``sky_horizon`` (at the bottom) and its things, placed the same on every call."""
    from PIL import Image, ImageDraw  # optional: Pillow (desktop export only)

    w, h = size
    p = place(name)
    u = np.linspace(0.0, 1.0, h)[:, None]
    grad = (np.asarray(p.sky_top, float) * (1 - u) + np.asarray(p.sky_horizon, float) * u)
    img = Image.fromarray(np.repeat(grad[:, None, :], w, axis=1).round().astype(np.uint8).reshape(h, w, 3))
    d = ImageDraw.Draw(img)
    s = min(w, h)
    rng = np.random.default_rng(sum(map(ord, name)))
    if "stars" in p.things:
        for x, y, r in zip(rng.uniform(0, w, 120), rng.uniform(0, 0.6 * h, 120), rng.uniform(0.8, 2.6, 120)):
            d.ellipse([x - r, y - r, x + r, y + r], fill=(255, 250, 215))
    if "sun" in p.things:
        cx, cy, r = 0.84 * w, 0.14 * h, 0.07 * s
        for k in range(12):
            a = k * math.pi / 6
            d.line([cx + 1.2 * r * math.cos(a), cy + 1.2 * r * math.sin(a),
                    cx + 1.6 * r * math.cos(a), cy + 1.6 * r * math.sin(a)], fill=(255, 210, 60), width=max(2, s // 160))
        d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=(255, 220, 70))
    if "moon" in p.things:
        cx, cy, r = 0.82 * w, 0.15 * h, 0.06 * s
        d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=(255, 245, 190))
        d.ellipse([cx - 0.45 * r, cy - 1.05 * r, cx + 1.5 * r, cy + 0.9 * r], fill=p.sky_top)
    if "planet" in p.things:
        cx, cy, r = 0.8 * w, 0.17 * h, 0.07 * s
        d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=(242, 140, 90))
        d.ellipse([cx - 2 * r, cy - 0.35 * r, cx + 2 * r, cy + 0.35 * r], outline=(130, 180, 255), width=max(2, s // 180))
    if "clouds" in p.things:
        for cx, cy in ((0.18, 0.12), (0.5, 0.07), (0.62, 0.2)):
            for dx, dy, rr in ((-0.05, 0.0, 0.035), (0.0, -0.02, 0.045), (0.05, 0.0, 0.035)):
                x, y, r = (cx + dx) * w, (cy + dy) * h, rr * s
                d.ellipse([x - 1.4 * r, y - r, x + 1.4 * r, y + r], fill=(255, 255, 255))
    if "gulls" in p.things:
        for cx, cy in ((0.3, 0.12), (0.38, 0.18), (0.55, 0.1)):
            x, y, r = cx * w, cy * h, 0.02 * s
            d.arc([x - 2 * r, y - r, x, y + r], 200, 340, fill=(60, 60, 80), width=max(2, s // 240))
            d.arc([x, y - r, x + 2 * r, y + r], 200, 340, fill=(60, 60, 80), width=max(2, s // 240))
    return np.asarray(img)


def draw_badge(d, kind: str, cx: float, cy: float, r: float) -> None:
    """A character's round badge with a face (``d``: a Pillow ImageDraw), as on the tablet."""
    colour = CHARACTER_COLOURS.get(kind, (160, 160, 160))
    if kind == "animal":  # ears
        for ex in (-0.55, 0.55):
            d.ellipse([cx + ex * r - 0.3 * r, cy - 0.95 * r, cx + ex * r + 0.3 * r, cy - 0.35 * r], fill=colour)
    if kind == "robot":
        d.rounded_rectangle([cx - 0.8 * r, cy - 0.8 * r, cx + 0.8 * r, cy + 0.8 * r], radius=0.25 * r, fill=colour)
        d.line([cx, cy - 0.8 * r, cx, cy - 1.05 * r], fill=colour, width=max(1, int(0.08 * r)))
        d.ellipse([cx - 0.1 * r, cy - 1.18 * r, cx + 0.1 * r, cy - 0.98 * r], fill=colour)
    else:
        d.ellipse([cx - 0.8 * r, cy - 0.8 * r, cx + 0.8 * r, cy + 0.8 * r], fill=colour)
    for ex in (-0.3, 0.3):
        d.ellipse([cx + ex * r - 0.15 * r, cy - 0.35 * r, cx + ex * r + 0.15 * r, cy - 0.05 * r], fill=(255, 255, 255))
        d.ellipse([cx + ex * r - 0.07 * r, cy - 0.26 * r, cx + ex * r + 0.07 * r, cy - 0.12 * r], fill=(25, 25, 25))
    d.arc([cx - 0.35 * r, cy + 0.1 * r, cx + 0.35 * r, cy + 0.5 * r], 20, 160, fill=(25, 25, 25),
          width=max(1, int(0.06 * r)))


def cast(story: Story) -> list[str]:
    """The kinds of character in the story, in order of first appearance (at most 4)."""
    kinds: list[str] = []
    for scene in story.scenes:
        for c in scene.characters:
            if c.kind not in kinds:
                kinds.append(c.kind)
    return kinds[:4]


def _backdrop(background: str, size: tuple[int, int]):
    """A place as a flat picture: its sky above, its ground below (the lower 30%)."""
    from PIL import Image, ImageDraw  # optional: Pillow (desktop export only)

    w, h = size
    img = Image.fromarray(sky_picture(background, size))
    ImageDraw.Draw(img).rectangle([0, int(0.7 * h), w, h], fill=place(background).ground)
    return img


def _curtains(d, size: tuple[int, int], closed: float) -> None:
    """Two stage curtains, each covering ``closed`` (0..1) of its half, with folds."""
    w, h = size
    cw = closed * w / 2
    if cw < 1:
        return
    dark = _mix(CURTAIN, (0, 0, 0), 0.35)
    for left in (True, False):
        x0, x1 = (0, cw) if left else (w - cw, w)
        d.rectangle([x0, 0, x1, h], fill=CURTAIN)
        for k in range(1, 6):
            x = x0 + (x1 - x0) * k / 6
            d.line([x, 0, x, h], fill=dark, width=max(2, w // 200))
    d.rectangle([0, 0, w, 0.06 * h], fill=dark)  # the valance


def _heart(d, cx: float, cy: float, r: float) -> None:
    d.ellipse([cx - r, cy - 0.8 * r, cx, cy + 0.2 * r], fill=HEART)
    d.ellipse([cx, cy - 0.8 * r, cx + r, cy + 0.2 * r], fill=HEART)
    d.polygon([(cx - 0.97 * r, cy - 0.15 * r), (cx + 0.97 * r, cy - 0.15 * r), (cx, cy + r)], fill=HEART)


def _cover_picture(img, story: Story, cx: float, cy: float, r: float) -> None:
    """The story's name by picture: its cover colour in a ring around a character badge or
    a little picture of a place (a star when the story has no cover)."""
    from PIL import Image, ImageDraw  # optional: Pillow (desktop export only)

    d = ImageDraw.Draw(img)
    ring = COVER_COLOURS[story.cover.colour] if story.cover is not None else (255, 202, 58)
    d.ellipse([cx - 1.15 * r, cy - 1.15 * r, cx + 1.15 * r, cy + 1.15 * r], fill=ring)
    d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=(255, 255, 255))
    picture = story.cover.picture if story.cover is not None else None
    if picture in CHARACTER_COLOURS:
        draw_badge(d, picture, cx, cy + 0.1 * r, 0.7 * r)
        return
    if picture is not None:
        side = int(1.3 * r)
        tile = _backdrop(picture, (side, side))
        mask = Image.new("L", (side, side), 0)
        ImageDraw.Draw(mask).ellipse([0, 0, side - 1, side - 1], fill=255)
        img.paste(tile, (int(cx - side / 2), int(cy - side / 2)), mask)
        return
    pts = [(cx + (0.8 if k % 2 == 0 else 0.35) * r * math.sin(k * math.pi / 5),
            cy - (0.8 if k % 2 == 0 else 0.35) * r * math.cos(k * math.pi / 5)) for k in range(10)]
    d.polygon(pts, fill=ring)


def title_card(story: Story, i: int, n: int, size: tuple[int, int]) -> np.ndarray:
    """Frame ``i`` of ``n`` of the title card: the first place, the cover picture and the
    cast popping in one after another, while the curtain opens (first 60% of the card)."""
    from PIL import ImageDraw  # optional: Pillow (desktop export only)

    w, h = size
    u = i / max(n - 1, 1)
    background = story.scenes[0].background if story.scenes else "sky"
    img = _backdrop(background, size)
    d = ImageDraw.Draw(img)
    _cover_picture(img, story, w / 2, 0.4 * h, 0.2 * h)
    kinds = cast(story)
    for k, kind in enumerate(kinds):
        pop = np.clip((u - 0.35 - 0.12 * k) / 0.15, 0.0, 1.0)
        if pop <= 0:
            continue
        r = 0.09 * h * (pop + 0.15 * math.sin(math.pi * pop))
        x = w / 2 + (k - (len(kinds) - 1) / 2) * 0.22 * h
        draw_badge(d, kind, x, 0.8 * h, r)
    _curtains(d, size, 1.0 - float(np.clip(u / 0.6, 0.0, 1.0)) ** 0.7)
    return np.asarray(img)


def ending_card(story: Story, i: int, n: int, size: tuple[int, int]) -> np.ndarray:
    """Frame ``i`` of ``n`` of the ending card: the last place, the cast bouncing, the
    confetti of :func:`app.player.celebration.confetti`, then the curtain closing on a
    heart (last 35% of the card)."""
    from PIL import ImageDraw  # optional: Pillow (desktop export only)

    w, h = size
    u = i / max(n - 1, 1)
    seconds = n / 30.0
    background = story.scenes[-1].background if story.scenes else "sky"
    img = _backdrop(background, size)
    d = ImageDraw.Draw(img)
    kinds = cast(story) or ["child"]
    for k, kind in enumerate(kinds):
        hop = abs(math.sin(2 * math.pi * (1.6 * u * seconds / 2.5 + 0.25 * k)))
        x = w / 2 + (k - (len(kinds) - 1) / 2) * 0.28 * h
        draw_badge(d, kind, x, 0.62 * h - 0.12 * h * hop, 0.11 * h)
    bits = confetti(u * seconds)
    for (x, y), colour, angle, s in zip(bits["xy"], bits["colour"], bits["angle"], bits["size"]):
        px, py, a, b = x * w, (1 - y) * h, s * h, 0.45 * s * h
        ca, sa = math.cos(angle), math.sin(angle)
        corners = [(px + ca * dx - sa * dy, py + sa * dx + ca * dy) for dx, dy in ((-a, -b), (a, -b), (a, b), (-a, b))]
        d.polygon(corners, fill=tuple(int(c) for c in colour))
    close = float(np.clip((u - 0.65) / 0.3, 0.0, 1.0))
    _curtains(d, size, close)
    if close >= 1.0:
        _heart(d, w / 2, 0.48 * h, 0.16 * h)
    return np.asarray(img)


def with_cards(story: Story, fps: float, size: tuple[int, int], scenes) -> Iterator[np.ndarray]:
    """The title card's frames, then ``scenes`` (an iterator of frames), then the ending card's."""
    lead, tail = card_frames(fps)
    for i in range(lead):
        yield title_card(story, i, lead, size)
    yield from scenes
    for i in range(tail):
        yield ending_card(story, i, tail, size)


__all__ = ["FILM_SIZE", "FILM_FPS", "TITLE_SECONDS", "ENDING_SECONDS", "card_frames", "with_cards", "Place", "PLACES",
           "DEFAULT_PLACE", "CHARACTER_COLOURS", "CURTAIN", "HEART", "place", "sky_picture", "draw_badge", "cast",
           "title_card", "ending_card"]
