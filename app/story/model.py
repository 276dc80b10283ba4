"""The story model: stories, scenes, characters and their sketched paths.

Plain dataclasses with a versioned dictionary form, so the same structure is stored in
SQLite, written into story packages and handed to the renderer. Everything that comes
from outside (a database row, a package, a test) goes through :meth:`Story.from_dict`,
which validates the whole tree and raises :class:`StoryError` naming the field and the
problem; nothing half-checked reaches the UI.

Units: paths are in *table metres* (x to the right, y away from the child, origin at the
table's front-left corner) with ``t`` in seconds from the start of the scene, because
that is what the projector-camera calibration and the path follower work in.
"""
from __future__ import annotations

import math
import uuid
from dataclasses import dataclass, field
from typing import Any

from retrieval.errors import StoryBeamError

#: Version of the dictionary form written by :meth:`Story.to_dict`.
STORY_FORMAT_VERSION = 1
STORY_FORMAT_NAME = "storybeam.story"

#: Story arcs offered on "new story": name -> the parts a scene can belong to.
ARCS: dict[str, tuple[str, ...]] = {
    "short": ("beginning", "middle", "end"),
    "classic": ("setup", "conflict", "challenge", "climax", "resolution"),
    "free": (),
}
CHARACTER_KINDS = ("robot", "animal", "child")
#: Motion classes with a big icon in the editor; "more" opens the clip list.
MOTION_CLASSES = ("walk", "run", "jump", "dance", "kick")
MARK_KINDS = ("hop", "spin")
BACKGROUNDS = ("sky", "grass", "night", "sea", "castle", "forest", "space", "sand")

#: The projection area on the table (metres). Paths must stay inside, with a small
#: tolerance because a finger may slide just past the edge of the drawing area.
TABLE_WIDTH_M = 1.2
TABLE_DEPTH_M = 0.8
_EDGE_TOLERANCE_M = 0.05
MAX_PATH_POINTS = 5000
MAX_SCENES = 60
MAX_CHARACTERS_PER_SCENE = 6
MAX_TITLE_CHARS = 80
MAX_SCENE_SECONDS = 600.0


class StoryError(StoryBeamError):
    """A story (or part of one) is malformed; the message names the field."""


def new_id() -> str:
    """A short random identifier (hex), unique enough for one device's stories."""
    return uuid.uuid4().hex[:12]


def _require(condition: bool, where: str, problem: str) -> None:
    if not condition:
        raise StoryError(f"{where}: {problem}")


def _get(data: Any, key: str, where: str, kind: type | tuple[type, ...]) -> Any:
    _require(isinstance(data, dict), where, "expected an object")
    _require(key in data, where, f"missing field '{key}'")
    value = data[key]
    ok = isinstance(value, kind) and not (isinstance(value, bool) and kind in (int, float, (int, float)))
    _require(ok, f"{where}.{key}", f"expected {getattr(kind, '__name__', kind)}, found {type(value).__name__}")
    return value


def _finite(value: int | float, where: str) -> float:
    """``float(value)``, refusing what cannot be one: JSON allows integers of any length,
    and ``float(10**400)`` raises OverflowError (found by package fuzzing)."""
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    _require(math.isfinite(number), where, "not a finite number")
    return number


def _check_text(value: str, where: str, max_chars: int = MAX_TITLE_CHARS) -> str:
    _require(isinstance(value, str), where, "expected text")
    _require(len(value) <= max_chars, where, f"longer than {max_chars} characters")
    _require(all(ch.isprintable() for ch in value), where, "contains control characters")
    return value


@dataclass
class Mark:
    """A one-shot action along the path (a hop drawn as an arc, a spin drawn as a loop).

    ``at`` is the time (seconds into the scene) where the action starts.
    """

    kind: str
    at: float

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "at": self.at}

    @classmethod
    def from_dict(cls, data: Any, where: str = "mark") -> "Mark":
        kind = _get(data, "kind", where, str)
        _require(kind in MARK_KINDS, f"{where}.kind", f"unknown mark '{kind}' (expected one of {', '.join(MARK_KINDS)})")
        at = _finite(_get(data, "at", where, (int, float)), f"{where}.at")
        _require(math.isfinite(at) and 0.0 <= at <= MAX_SCENE_SECONDS, f"{where}.at", "time out of range")
        return cls(kind, at)


@dataclass
class MotionChoice:
    """What the character does while following its path: a class, optionally one clip.

    ``clip_id`` is set when the child picked a specific clip (e.g. from "more like this");
    otherwise the renderer picks the best clip of ``motion_class``.
    """

    motion_class: str = "walk"
    clip_id: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"class": self.motion_class, "clip": self.clip_id}

    @classmethod
    def from_dict(cls, data: Any, where: str = "motion") -> "MotionChoice":
        motion_class = _check_text(_get(data, "class", where, str), f"{where}.class", 40)
        _require(bool(motion_class), f"{where}.class", "empty")
        clip = data.get("clip")
        _require(clip is None or isinstance(clip, str), f"{where}.clip", "expected text or null")
        if clip is not None:
            _check_text(clip, f"{where}.clip", 200)
        return cls(motion_class, clip)


@dataclass
class Character:
    """One character in a scene: its look, its sketched path and its motion."""

    kind: str = "robot"
    path: list[tuple[float, float, float]] = field(default_factory=list)
    motion: MotionChoice = field(default_factory=MotionChoice)
    marks: list[Mark] = field(default_factory=list)
    id: str = field(default_factory=new_id)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last path point (0 without a path)."""
        return self.path[-1][2] - self.path[0][2] if len(self.path) >= 2 else 0.0

    def position_at(self, t: float) -> tuple[float, float] | None:
        """Where the character is at scene time ``t`` (linear along the sketch)."""
        if not self.path:
            return None
        t0 = self.path[0][2]
        t = t0 + min(max(t, 0.0), self.duration)
        for (xa, ya, ta), (xb, yb, tb) in zip(self.path, self.path[1:]):
            if tb >= t:
                w = 0.0 if tb <= ta else (t - ta) / (tb - ta)
                return (xa + w * (xb - xa), ya + w * (yb - ya))
        return self.path[-1][0], self.path[-1][1]

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "kind": self.kind,
            "path": [[x, y, t] for x, y, t in self.path],
            "motion": self.motion.to_dict(),
            "marks": [m.to_dict() for m in self.marks],
        }

    @classmethod
    def from_dict(cls, data: Any, where: str = "character") -> "Character":
        cid = _check_text(_get(data, "id", where, str), f"{where}.id", 64)
        kind = _get(data, "kind", where, str)
        _require(kind in CHARACTER_KINDS, f"{where}.kind", f"unknown character '{kind}'")
        raw_path = _get(data, "path", where, list)
        _require(len(raw_path) <= MAX_PATH_POINTS, f"{where}.path", f"more than {MAX_PATH_POINTS} points")
        path = [path_point(p, f"{where}.path[{i}]") for i, p in enumerate(raw_path)]
        for i in range(1, len(path)):
            _require(path[i][2] >= path[i - 1][2], f"{where}.path[{i}]", "time goes backwards")
        motion = MotionChoice.from_dict(_get(data, "motion", where, dict), f"{where}.motion")
        marks = [Mark.from_dict(m, f"{where}.marks[{i}]") for i, m in enumerate(_get(data, "marks", where, list))]
        return cls(kind=kind, path=path, motion=motion, marks=marks, id=cid)


def path_point(p: Any, where: str) -> tuple[float, float, float]:
    _require(isinstance(p, (list, tuple)) and len(p) == 3, where, "expected [x, y, t]")
    _require(all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in p), where, "expected numbers")
    x, y, t = (_finite(v, where) for v in p)
    _require(all(math.isfinite(v) for v in (x, y, t)), where, "not a finite number")
    tol = _EDGE_TOLERANCE_M
    _require(-tol <= x <= TABLE_WIDTH_M + tol and -tol <= y <= TABLE_DEPTH_M + tol, where,
             f"point ({x:.3f}, {y:.3f}) m is off the {TABLE_WIDTH_M} x {TABLE_DEPTH_M} m table")
    _require(0.0 <= t <= MAX_SCENE_SECONDS, where, f"time {t:.2f} s out of range")
    return (x, y, t)


#: Longest narration one scene may carry (seconds); :mod:`app.story.narration` enforces
#: it on import and recording, the model again on load (a package may lie).
MAX_NARRATION_SECONDS = 120.0


@dataclass
class Narration:
    """A scene's recorded or imported voice: a story asset (a validated mono 16-bit PCM
    WAV, see :mod:`app.story.narration`) that starts with the scene.

    ``asset`` names the file among the story's assets (content-addressed, so saving a
    new recording never overwrites the one the saved story still points to);
    ``seconds`` is its length. A scene lasts at least as long as its narration.
    """

    asset: str
    seconds: float

    def to_dict(self) -> dict[str, Any]:
        return {"asset": self.asset, "seconds": self.seconds}

    @classmethod
    def from_dict(cls, data: Any, where: str = "narration") -> "Narration":
        asset = _check_text(_get(data, "asset", where, str), f"{where}.asset", 64)
        _require(bool(asset) and asset[0].isalnum() and ".." not in asset
                 and all(ch.isascii() and (ch.isalnum() or ch in "_.-") for ch in asset),
                 f"{where}.asset", f"unsafe asset name {asset!r}")
        seconds = _finite(_get(data, "seconds", where, (int, float)), f"{where}.seconds")
        _require(0.0 < seconds <= MAX_NARRATION_SECONDS, f"{where}.seconds",
                 f"length {seconds:.2f} s out of range (0 to {MAX_NARRATION_SECONDS:.0f} s)")
        return cls(asset, seconds)


@dataclass
class Scene:
    """One scene: a background, up to a handful of characters and an optional narration."""

    background: str = "sky"
    characters: list[Character] = field(default_factory=list)
    part: str | None = None  # which part of the story arc this scene tells
    id: str = field(default_factory=new_id)
    narration: Narration | None = None

    @property
    def duration(self) -> float:
        """Length of the scene: the longest character path or the narration, at least two
        seconds (a child's voice is never cut off by a short path)."""
        voice = self.narration.seconds if self.narration is not None else 0.0
        return max([2.0, voice] + [c.duration for c in self.characters])

    def character(self, character_id: str) -> Character:
        for c in self.characters:
            if c.id == character_id:
                return c
        raise StoryError(f"scene {self.id}: no character '{character_id}'")

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = {"id": self.id, "background": self.background, "part": self.part,
                                "characters": [c.to_dict() for c in self.characters]}
        if self.narration is not None:  # absent, not null: stories without a voice stay as they were
            data["narration"] = self.narration.to_dict()
        return data

    @classmethod
    def from_dict(cls, data: Any, where: str = "scene") -> "Scene":
        sid = _check_text(_get(data, "id", where, str), f"{where}.id", 64)
        background = _get(data, "background", where, str)
        _require(background in BACKGROUNDS, f"{where}.background", f"unknown background '{background}'")
        part = data.get("part")
        _require(part is None or isinstance(part, str), f"{where}.part", "expected text or null")
        chars = _get(data, "characters", where, list)
        _require(len(chars) <= MAX_CHARACTERS_PER_SCENE, f"{where}.characters",
                 f"more than {MAX_CHARACTERS_PER_SCENE} characters")
        characters = [Character.from_dict(c, f"{where}.characters[{i}]") for i, c in enumerate(chars)]
        _require(len({c.id for c in characters}) == len(characters), f"{where}.characters", "duplicate character id")
        raw_narration = data.get("narration")  # optional: stories saved before narration have none
        narration = None if raw_narration is None else Narration.from_dict(raw_narration, f"{where}.narration")
        return cls(background=background, characters=characters, part=part, id=sid, narration=narration)


#: What a story's name can be for a child who cannot type: a picture (drawn by
#: ``app.ui.art.draw_icon`` and ``app.player.cards``) on one of these colours (RGB 0..255).
COVER_PICTURES = CHARACTER_KINDS + BACKGROUNDS
COVER_COLOURS: tuple[tuple[int, int, int], ...] = (
    (255, 89, 94), (255, 146, 76), (255, 202, 58), (138, 201, 38),
    (25, 170, 160), (25, 130, 196), (106, 76, 147), (255, 112, 166))


@dataclass
class Cover:
    """A story's name by picture: ``picture`` (one of :data:`COVER_PICTURES`) on colour
    ``colour`` (an index into :data:`COVER_COLOURS`), and optionally ``voice``, the name
    said aloud (a recorded asset, like a narration)."""

    picture: str
    colour: int = 0
    voice: Narration | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"picture": self.picture, "colour": self.colour,
                "voice": self.voice.to_dict() if self.voice is not None else None}

    @classmethod
    def from_dict(cls, data: Any, where: str = "cover") -> "Cover":
        picture = _get(data, "picture", where, str)
        _require(picture in COVER_PICTURES, f"{where}.picture", f"unknown picture '{picture}'")
        colour = _get(data, "colour", where, int)
        _require(0 <= colour < len(COVER_COLOURS), f"{where}.colour", "out of range")
        voice = data.get("voice")
        return cls(picture, colour, None if voice is None else Narration.from_dict(voice, f"{where}.voice"))


@dataclass
class Story:
    """A story: a title, an arc, an ordered list of scenes and, optionally, a cover (its
    name by picture and voice)."""

    title: str = ""
    arc: str = "short"
    scenes: list[Scene] = field(default_factory=list)
    id: str = field(default_factory=new_id)
    cover: Cover | None = None

    @classmethod
    def new(cls, arc: str = "short", title: str = "") -> "Story":
        """A fresh story with one empty scene per part of ``arc`` (one scene for "free")."""
        _require(arc in ARCS, "arc", f"unknown arc '{arc}' (expected one of {', '.join(ARCS)})")
        parts = ARCS[arc] or (None,)
        backgrounds = BACKGROUNDS
        scenes = [Scene(background=backgrounds[i % len(backgrounds)], part=p) for i, p in enumerate(parts)]
        return cls(title=title, arc=arc, scenes=scenes)

    @property
    def duration(self) -> float:
        return sum(s.duration for s in self.scenes)

    def scene(self, scene_id: str) -> Scene:
        for s in self.scenes:
            if s.id == scene_id:
                return s
        raise StoryError(f"story {self.id}: no scene '{scene_id}'")

    def scene_index(self, scene_id: str) -> int:
        return self.scenes.index(self.scene(scene_id))

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": STORY_FORMAT_NAME,
            "version": STORY_FORMAT_VERSION,
            "id": self.id,
            "title": self.title,
            "arc": self.arc,
            "scenes": [s.to_dict() for s in self.scenes],
            **({"cover": self.cover.to_dict()} if self.cover is not None else {}),
        }

    @classmethod
    def from_dict(cls, data: Any, where: str = "story") -> "Story":
        _require(isinstance(data, dict), where, "expected an object")
        _require(data.get("format") == STORY_FORMAT_NAME, where, "not a StoryBeam story")
        version = data.get("version")
        _require(isinstance(version, int) and not isinstance(version, bool), where, "missing format version")
        _require(version <= STORY_FORMAT_VERSION, where,
                 f"made by a newer StoryBeam (story format {version}, this app reads up to {STORY_FORMAT_VERSION})")
        _require(version >= 1, where, f"unknown story format {version}")
        sid = _check_text(_get(data, "id", where, str), f"{where}.id", 64)
        _require(bool(sid) and all(ch.isalnum() or ch in "-_" for ch in sid), f"{where}.id", "must be letters, digits, - or _")
        title = _check_text(_get(data, "title", where, str), f"{where}.title")
        arc = _get(data, "arc", where, str)
        _require(arc in ARCS, f"{where}.arc", f"unknown arc '{arc}'")
        raw_scenes = _get(data, "scenes", where, list)
        _require(len(raw_scenes) <= MAX_SCENES, f"{where}.scenes", f"more than {MAX_SCENES} scenes")
        scenes = [Scene.from_dict(s, f"{where}.scenes[{i}]") for i, s in enumerate(raw_scenes)]
        _require(len({s.id for s in scenes}) == len(scenes), f"{where}.scenes", "duplicate scene id")
        cover = None if data.get("cover") is None else Cover.from_dict(data["cover"], f"{where}.cover")
        return cls(title=title, arc=arc, scenes=scenes, id=sid, cover=cover)
