"""A story character as a 3-D motion: its chosen clip, retargeted onto its design and laid
along its sketched path.

Shared by the Play preview (:mod:`app.player.preview`), the projector stage
(:mod:`app.player.stage`) and the MP4 export, so all three show the same animation. Per
character: the chosen clip (or the first clip of its motion class) from the motion
library, :func:`retrieval.animation.retarget` onto the ``ar.scene`` design (robot / cat
/ kid), then :func:`retrieval.animation.follow_path` along the path mapped into the scene
by a :class:`app.player.placement.TablePlacement`: walk and run loop along the path;
jump, dance and kick, and the hop / spin marks, are one-shots along a walk. With a
``ground`` (the scanned table, :func:`ar.scene.scene_ground`; the projector stage only)
the laid motion then follows the surface (:func:`retrieval.animation.follow_surface`):
its feet on the boxes it crosses, a jump at an edge higher than a step.

Needs :mod:`ar.scene` only (the character designs are numpy): it runs on the tablet.
"""
from __future__ import annotations

import csv
import logging
from pathlib import Path

import numpy as np

from app.paths import MOTIONS_DIR
from app.player.placement import PREVIEW_PLACEMENT, TablePlacement, table_to_scene
from app.story import Character
from ar.scene import Character as CharacterDesign
from ar.scene import build_character
from retrieval.animation import Ground, OneShot, TablePath, find_loop, follow_path, follow_surface, retarget
from retrieval.errors import StoryBeamError
from retrieval.motion import Motion, load_motion

log = logging.getLogger(__name__)

#: story character kinds -> ar.scene character designs
CHARACTER_DESIGNS = {"robot": "robot", "animal": "cat", "child": "kid"}
#: motion classes that travel by themselves (looped along the path); the others are
#: played once part-way along a walk
CYCLIC_CLASSES = ("walk", "run")
MARK_CLASSES = {"hop": "jump", "spin": "dance"}
CHARACTER_HEIGHT_M = 0.16


class SceneAnimator:
    """Turns a story character into a retargeted motion laid on its sketched path.

    ``placement`` lays the table in the scene (the stage uses a miniature of the table,
    hence ``character_height_m`` and ``placement`` are parameters); ``ground``: the
    surface in the scene frame (``ground(X, Z) -> Y``), None for the bare table. Retargeted clips are
    cached (the same clip is reused across scenes)."""

    def __init__(self, clip_files: dict[str, Path], first_of_class: dict[str, str], fps: float = 30.0,
                 character_height_m: float = CHARACTER_HEIGHT_M, placement: TablePlacement = PREVIEW_PLACEMENT,
                 ground: Ground | None = None):
        self.clip_files = clip_files
        self.ground = ground
        self.first_of_class = first_of_class
        self.fps = fps
        self.character_height_m = character_height_m
        self.placement = placement
        self._motions: dict[tuple, Motion] = {}

    @classmethod
    def from_library(cls, motions_dir: str | Path = MOTIONS_DIR, **kwargs) -> "SceneAnimator":
        """Read ``labels.csv`` of a motion library (raises StoryBeamError naming it)."""
        labels = Path(motions_dir) / "labels.csv"
        try:
            with open(labels, newline="", encoding="utf-8") as fh:
                rows = list(csv.DictReader(fh))
            clip_files = {r["trial"]: Path(motions_dir) / r["file"] for r in rows}
        except (OSError, KeyError, UnicodeDecodeError, csv.Error) as exc:
            raise StoryBeamError(f"{labels}: cannot read the motion library ({exc})") from None
        first: dict[str, str] = {}
        for r in rows:
            first.setdefault(r["label"], r["trial"])
        return cls(clip_files, first, **kwargs)

    def _clip(self, trial: str, design: CharacterDesign) -> Motion:
        """A library clip retargeted onto ``design`` (cached: the same clip is reused)."""
        key = (trial, design.name, round(float(design.height_m), 4))
        if key not in self._motions:
            path = self.clip_files.get(trial)
            if path is None:
                raise StoryBeamError(f"clip {trial!r} is not in the motion library's labels.csv")
            self._motions[key] = retarget(load_motion(path), design.skeleton)
        return self._motions[key]

    def animate(self, character: Character) -> tuple[CharacterDesign, Motion]:
        """``(design, motion)``: the character's chosen clip laid along its path (scene frame)."""
        design = build_character(CHARACTER_DESIGNS[character.kind], self.character_height_m)
        motion_class = character.motion.motion_class
        chosen = character.motion.clip_id or self.first_of_class.get(motion_class)
        if chosen is None:
            raise StoryBeamError(f"no clip of class {motion_class!r} in the library")
        pts = np.array(character.path)
        times = pts[:, 2] if np.all(np.diff(pts[:, 2]) > 0) else None
        path = TablePath(table_to_scene(pts, self.placement), times)
        locomotion_trial = chosen if motion_class in CYCLIC_CLASSES else self.first_of_class.get("walk")
        locomotion = self._clip(locomotion_trial, design)
        loop = find_loop(locomotion, blend_frames=max(1, int(0.3 * locomotion.fps)))
        one_shots = []
        if motion_class not in CYCLIC_CLASSES:
            one_shots.append(OneShot(self._clip(chosen, design), 0.4 * path.length))
        for mark in character.marks:
            trial = self.first_of_class.get(MARK_CLASSES[mark.kind])
            if trial is not None and character.duration > 0:
                one_shots.append(OneShot(self._clip(trial, design), path.length * mark.at / character.duration))
        try:
            result = follow_path(locomotion, path, fps=self.fps, loop=loop, one_shots=one_shots or None)
        except StoryBeamError:
            if not one_shots:
                raise
            result = follow_path(locomotion, path, fps=self.fps, loop=loop)  # the actions did not fit
        if self.ground is not None:
            return design, follow_surface(result.motion, self.ground).motion
        return design, result.motion

    def animate_scene(self, characters: list[Character], where: str = "scene"
                      ) -> tuple[list[tuple[Character, CharacterDesign, Motion]], list[str]]:
        """``(cast, problems)``: every character with a path (two points or more) as
        ``(character, design, motion)`` (:meth:`animate`). One that cannot be animated (no
        clip of its class, a clip that cannot be read, a path its motion cannot follow)
        is left out; ``problems`` says why (``"<kind> <id>: <reason>"``), and so does the
        log, naming ``where`` (the preview, the stage, the film)."""
        cast, problems = [], []
        for character in characters:
            if len(character.path) < 2:
                continue
            try:
                design, motion = self.animate(character)
            except (StoryBeamError, ValueError, OSError) as exc:
                problems.append(f"{character.kind} {character.id}: {exc}")
                log.warning("%s leaves out %s: %s", where, character.id, exc)
                continue
            cast.append((character, design, motion))
        return cast, problems


__all__ = ["SceneAnimator", "CHARACTER_DESIGNS", "CYCLIC_CLASSES", "MARK_CLASSES", "CHARACTER_HEIGHT_M"]
