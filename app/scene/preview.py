"""3-D preview of a whole scene for Play: every character retargeted, laid on its sketched
path and rendered from above the table with pyrender.

Made to run inside :class:`app.scene.render_thread.RenderThread` (pyrender's GL context must
live on that one thread). Preparing a scene (load the clip, retarget, follow the path)
costs about a second per character, so prepared scenes are cached by content; changing
a path prepares the scene again. A character whose motion cannot be laid on its path is
reported in ``problems`` and left out; the tablet keeps its 2-D preview meanwhile.
"""
from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.story.model import TABLE_DEPTH_M, TABLE_WIDTH_M, Character, Scene
from retrieval.errors import StoryBeamError

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

log = logging.getLogger(__name__)

REPO_ROOT = Path(__file__).resolve().parents[2]
MOTIONS_DIR = REPO_ROOT / "assets" / "motions"
#: story character kinds -> ar.characters designs
CHARACTER_DESIGNS = {"robot": "robot", "animal": "cat", "child": "kid"}
#: motion classes that travel by themselves (looped along the path); the others are
#: played once part-way along a walk
CYCLIC_CLASSES = ("walk", "run")
MARK_CLASSES = {"hop": "jump", "spin": "dance"}
CHARACTER_HEIGHT_M = 0.16


@dataclass
class _Prepared:
    renderer: object
    rigs: list = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


def table_to_scene(points: np.ndarray) -> np.ndarray:
    """Table metres (origin at the front-left corner) -> scene (X, Z) centred on the table.

    X is negated so that, seen from the child's side (scene -Z, Y up), table +x is to the
    right and table +y away from the viewer, exactly as on the tablet's top-down view.
    """
    p = np.asarray(points, np.float64)[:, :2] - np.array([TABLE_WIDTH_M / 2, TABLE_DEPTH_M / 2])
    return p * np.array([-1.0, 1.0])


class ScenePreviewRenderer:
    """``render(scene, t) -> (H, W, 3) uint8``: the scene at time ``t`` seen from above the
    child's side of the table."""

    def __init__(self, width: int = 640, height: int = 426, fps: float = 30.0,
                 motions_dir: str | Path = MOTIONS_DIR):
        import csv
        self.width, self.height, self.fps = width, height, fps
        self.motions_dir = Path(motions_dir)
        with open(self.motions_dir / "labels.csv", newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
        self.clip_files = {r["trial"]: self.motions_dir / r["file"] for r in rows}
        self.first_of_class: dict[str, str] = {}
        for r in rows:
            self.first_of_class.setdefault(r["label"], r["trial"])
        self._key: str | None = None
        self._prepared: _Prepared | None = None
        self.animator = SceneAnimator(self.clip_files, self.first_of_class, fps=fps)

    def __call__(self, scene: Scene, t: float) -> np.ndarray:
        return self.render(scene, t)

    def render(self, scene: Scene, t: float) -> np.ndarray:
        key = json.dumps(scene.to_dict(), sort_keys=True)
        if key != self._key:
            self.close()
            self._prepared = self._prepare(scene)
            self._key = key
        frame = int(round(max(t, 0.0) * self.fps))
        for rig in self._prepared.rigs:
            rig.show_frame(frame)
        return np.ascontiguousarray(self._prepared.renderer.render()[..., :3])

    @property
    def problems(self) -> list[str]:
        return list(self._prepared.problems) if self._prepared else []

    def close(self) -> None:
        if self._prepared is not None:
            self._prepared.renderer.close()
            self._prepared = None
            self._key = None

    # -- preparation --------------------------------------------------------------------
    def _prepare(self, scene: Scene) -> _Prepared:
        import pyrender
        import trimesh

        from ar.render.character_render import CharacterRig, _material, path_ribbon
        from ar.geometry import look_at
        from ar.render.projector_view import ProjectorRenderer

        w, h = self.width, self.height
        f = 0.95 * w
        K = np.array([[f, 0, w / 2 - 0.5], [0, f, h / 2 - 0.5], [0, 0, 1.0]])
        renderer = ProjectorRenderer(w, h, K, ambient=0.45, light_intensity=3.5)
        table = trimesh.creation.box(extents=(TABLE_WIDTH_M, 0.01, TABLE_DEPTH_M))
        table.apply_translation([0, -0.0051, 0])
        renderer.add("table", pyrender.Mesh.from_trimesh(table, material=_material(_table_colour(scene.background))))
        # above the child's edge of the table (scene -Z), looking across it
        renderer.set_view(look_at(np.array([0.0, 0.95, -0.75]), np.array([0.0, 0.0, 0.02]), np.array([0.0, 1.0, 0.0])))
        prepared = _Prepared(renderer)
        for i, character in enumerate(scene.characters):
            if len(character.path) < 2:
                continue
            xz = table_to_scene(np.array(character.path))
            renderer.add(f"path{i}", pyrender.Mesh.from_trimesh(path_ribbon(xz, width=0.01),
                                                               material=_material((255, 255, 255))))
            try:
                design, motion = self.animator.animate(character)
            except (StoryBeamError, ValueError, OSError) as exc:
                prepared.problems.append(f"{character.kind} {character.id}: {exc}")
                log.warning("3-D preview leaves out %s: %s", character.id, exc)
                continue
            rig = CharacterRig(renderer, design, prefix=f"char{i}")
            rig.bind(motion)
            prepared.rigs.append(rig)
        return prepared


class SceneAnimator:
    """Turns a story character into a retargeted motion laid on its sketched path.

    Shared by the Play preview, the projector stage and the MP4 export so all three show
    the same animation. ``place`` maps table metres ``(N, >=2)`` to scene ``(N, 2)`` (X, Z);
    the stage uses a miniature of the table, hence ``character_height_m`` and ``place``
    are parameters. Retargeted clips are cached (the same clip is reused across scenes).
    """

    def __init__(self, clip_files: dict[str, Path], first_of_class: dict[str, str], fps: float = 30.0,
                 character_height_m: float = CHARACTER_HEIGHT_M, place=table_to_scene):
        self.clip_files = clip_files
        self.first_of_class = first_of_class
        self.fps = fps
        self.character_height_m = character_height_m
        self.place = place
        self._motions: dict[tuple, object] = {}

    @classmethod
    def from_library(cls, motions_dir: str | Path = MOTIONS_DIR, **kwargs) -> "SceneAnimator":
        """Read ``labels.csv`` of a motion library (raises StoryBeamError naming it)."""
        import csv
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

    def _clip(self, trial: str, design) -> object:
        """A library clip retargeted onto ``design`` (cached: the same clip is reused)."""
        from retrieval.motion.formats import load_motion
        from retrieval.animation import retarget

        key = (trial, design.name, round(float(design.height_m), 4))
        if key not in self._motions:
            path = self.clip_files.get(trial)
            if path is None:
                raise StoryBeamError(f"clip {trial!r} is not in the motion library's labels.csv")
            self._motions[key] = retarget(load_motion(path), design.skeleton)
        return self._motions[key]

    def animate(self, character: Character):
        """``(design, motion)``: the character's chosen clip laid along its path (scene frame)."""
        from ar.render.characters import build_character
        from retrieval.animation import OneShot, TablePath, follow_path
        from retrieval.animation import find_loop

        design = build_character(CHARACTER_DESIGNS[character.kind], self.character_height_m)
        motion_class = character.motion.motion_class
        chosen = character.motion.clip_id or self.first_of_class.get(motion_class)
        if chosen is None:
            raise StoryBeamError(f"no clip of class {motion_class!r} in the library")
        pts = np.array(character.path)
        times = pts[:, 2] if np.all(np.diff(pts[:, 2]) > 0) else None
        path = TablePath(self.place(pts), times)
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
        return design, result.motion


def _table_colour(background: str) -> tuple[int, int, int]:
    return {"sky": (158, 214, 250), "grass": (140, 204, 107), "night": (40, 50, 110), "sea": (70, 140, 210),
            "castle": (237, 219, 184), "forest": (77, 140, 77), "space": (40, 30, 70),
            "sand": (245, 214, 140)}.get(background, (150, 150, 160))
