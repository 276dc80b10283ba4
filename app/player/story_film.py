"""The story film: the story as the child made it, for the video they take home.

Frames, in order: the title card (:func:`app.player.cards.title_card`), every scene, the
ending card (:func:`app.player.cards.ending_card`). A scene is drawn in 3-D by pyrender
(the reference renderer, :class:`ar.render.PyrenderSceneRenderer`) from the same
:class:`ar.scene.SceneDescription` s the app's 3-D Play draws:

* the table laid full size (:data:`app.player.placement.PREVIEW_PLACEMENT`), its top
  reaching to the horizon in the place's ground colour (:data:`app.player.cards.PLACES`),
  the child's paths as pale ribbons on it;
* every character retargeted and laid on its path with its motion
  (:class:`app.player.animator.SceneAnimator`, as Play), :data:`FILM_CHARACTER_HEIGHT_M`
  tall (larger than Play's table figures, so they fill the film), with a soft shadow;
* where no surface is hit (depth 0), the place's drawn sky (:func:`app.player.cards.sky_picture`).

The virtual camera (:func:`frame_camera`) stands on the child's side of the table,
:data:`CAMERA_ELEVATION_DEG` above the horizontal, looking across it, and frames the cast:
per frame the smallest distance at which every character (head to feet, shoulder to
shoulder) lies inside the central :data:`FRAME_MARGIN` of the picture, but no nearer than
one at which a character is :data:`MAX_CHARACTER_FRACTION` of the picture's height;
the distance is spread to the worst of the next and previous second (a sliding maximum)
and the aim smoothed over about half a second (Gaussian), so the camera glides and never
cuts anyone off. All of this is computed before the first frame (the whole scene is known).

Size and rate: 1280x720 at 30 fps by default (what a class projector shows well).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from app.paths import MOTIONS_DIR
from app.player.animator import SceneAnimator
from app.player.cards import ENDING_SECONDS, FILM_FPS, FILM_SIZE, TITLE_SECONDS, card_frames, place, sky_picture, with_cards
from app.player.placement import PREVIEW_PLACEMENT, table_to_scene
from app.story import Scene, Story
from ar import look_at
from ar.scene import Lighting, SceneDescription, View, add_character, add_mesh, ribbon, table_mesh
from ar.scene.mesh import ellipsoid
from retrieval.errors import StoryBeamError

FILM_CHARACTER_HEIGHT_M = 0.30
CAMERA_ELEVATION_DEG = 14.0
#: the share of the half-width / half-height inside which the cast is kept
FRAME_MARGIN = (0.82, 0.80)
MAX_CHARACTER_FRACTION = 0.62
FOCAL_PER_WIDTH = 0.8
FILM_LIGHTING = Lighting(ambient=0.55, key_intensity=2.4)
GROUND_M = 60.0


@dataclass
class Shot:
    """A scene's camera, frame by frame: ``targets`` (F, 3) scene points looked at and
    ``distances`` (F,) metres from them, along the fixed elevation."""

    targets: np.ndarray
    distances: np.ndarray

    def view(self, i: int, width: int, height: int) -> View:
        f = FOCAL_PER_WIDTH * width
        K = np.array([[f, 0, width / 2 - 0.5], [0, f, height / 2 - 0.5], [0, 0, 1.0]])
        i = int(np.clip(i, 0, len(self.distances) - 1))
        eye = self.targets[i] + self.distances[i] * _back()
        return View(width, height, K, look_at(eye, self.targets[i], np.array([0.0, 1.0, 0.0])), 0.02, GROUND_M)


def _back() -> np.ndarray:
    """Unit vector from the target to the camera: the child's side (-Z), raised."""
    e = np.radians(CAMERA_ELEVATION_DEG)
    return np.array([0.0, np.sin(e), -np.cos(e)])


def frame_camera(hips: np.ndarray, height_m: float, fps: float, size: tuple[int, int]) -> Shot:
    """The camera for a scene whose characters' hips are at ``hips`` (F, C, 3) scene
    metres (NaN where a character is absent) -- see the module docstring."""
    from scipy.ndimage import gaussian_filter1d, maximum_filter1d  # deferred: scipy only when a film is made

    w, h = size
    f = FOCAL_PER_WIDTH * w
    R = look_at(_back(), np.zeros(3), np.array([0.0, 1.0, 0.0]))[:3, :3]  # camera axes (distance-free)
    n_frames = hips.shape[0]
    offsets = np.array([[dx, dy, dz] for dx in (-0.35, 0.35) for dy in (0.0, 1.05) for dz in (-0.35, 0.35)]) * height_m
    targets = np.zeros((n_frames, 3))
    need = np.zeros(n_frames)
    d_min = f * height_m / (MAX_CHARACTER_FRACTION * h)
    last = np.array([0.0, 0.45 * height_m, 0.0])
    for i in range(n_frames):
        here = hips[i][np.all(np.isfinite(hips[i]), axis=1)]
        if len(here) == 0:
            targets[i], need[i] = last, d_min
            continue
        ground = here * np.array([1.0, 0.0, 1.0])
        pts = (ground[:, None, :] + offsets[None]).reshape(-1, 3)
        lo, hi = pts.min(0), pts.max(0)
        target = (lo + hi) / 2
        rel = (pts - target) @ R.T  # camera coordinates with the camera at the target
        dist_x = f * np.abs(rel[:, 0]) / (FRAME_MARGIN[0] * w / 2) - rel[:, 2]
        dist_y = f * np.abs(rel[:, 1]) / (FRAME_MARGIN[1] * h / 2) - rel[:, 2]
        targets[i], need[i] = target, max(d_min, float(dist_x.max()), float(dist_y.max()))
        last = target
    window = max(1, int(round(2 * fps)) | 1)
    spread = maximum_filter1d(need, window, mode="nearest")
    sigma = 0.25 * fps
    distances = np.maximum(gaussian_filter1d(spread, sigma, mode="nearest"), need)
    smooth = gaussian_filter1d(targets, 0.5 * fps, axis=0, mode="nearest")
    return Shot(smooth, distances)


@dataclass
class _PreparedScene:
    shot: Shot
    statics: list = field(default_factory=list)  # (mesh, colour)
    cast: list = field(default_factory=list)  # (design, (F, P, 4, 4) part poses, hips (F, 3))
    sky: np.ndarray | None = None
    problems: list[str] = field(default_factory=list)


class StoryFilm:
    """The story film's frames: ``len(film)`` of them, ``frames()`` yields them in order.

    ``layout`` is ``[("title", n), ("scene", n_0), ..., ("ending", n)]``; scene ``k`` has
    ``round(duration_k * fps)`` frames (at least 1), as the sound track counts them
    (:func:`app.player.video_export.story_audio`). Render on one thread (pyrender)."""

    def __init__(self, story: Story, fps: float = FILM_FPS, size: tuple[int, int] = FILM_SIZE,
                 motions_dir: str | Path = MOTIONS_DIR):
        self.story, self.fps, self.size = story, float(fps), (int(size[0]), int(size[1]))
        labels = Path(motions_dir) / "labels.csv"
        try:
            with open(labels, newline="", encoding="utf-8") as fh:
                rows = list(csv.DictReader(fh))
        except OSError as exc:
            raise StoryBeamError(f"{labels}: cannot read the motion library ({exc})") from None
        first: dict[str, str] = {}
        for r in rows:
            first.setdefault(r["label"], r["trial"])
        self.animator = SceneAnimator({r["trial"]: Path(motions_dir) / r["file"] for r in rows}, first, fps=self.fps,
                                      character_height_m=FILM_CHARACTER_HEIGHT_M, placement=PREVIEW_PLACEMENT)
        lead, tail = card_frames(self.fps)
        self.layout = ([("title", lead)] + [("scene", max(1, int(round(s.duration * self.fps)))) for s in story.scenes]
                       + [("ending", tail)])
        self.problems: list[str] = []
        self.shots: list[Shot] = []  # each scene's camera, once prepared
        self._renderer = None

    def __len__(self) -> int:
        return sum(n for _, n in self.layout)

    @property
    def lead_frames(self) -> int:
        """Frames before the first scene (the title card)."""
        return self.layout[0][1]

    @property
    def tail_frames(self) -> int:
        """Frames after the last scene (the ending card)."""
        return self.layout[-1][1]

    def prepare(self, scene: Scene, n_frames: int) -> _PreparedScene:
        """Animate the scene's characters, frame the camera, draw the sky."""
        statics = [(table_mesh(GROUND_M, GROUND_M), place(scene.background).ground)]
        ground = np.asarray(place(scene.background).ground, float)
        for character in scene.characters:
            if len(character.path) >= 2:
                path = table_to_scene(np.array(character.path), PREVIEW_PLACEMENT)
                statics.append((ribbon(path, width=0.02, lift=0.001),
                                tuple(int(c) for c in 0.55 * ground + 0.45 * 255)))
        animated, problems = self.animator.animate_scene(scene.characters, "story film")
        cast = []
        for _, design, motion in animated:
            poses = design.all_part_poses(motion)
            cast.append((design, poses, poses[:, :, :3, 3].mean(axis=1)))
        hips = np.full((n_frames, max(len(cast), 1), 3), np.nan)
        for k, (_, _, centre) in enumerate(cast):
            idx = np.clip(np.arange(n_frames), 0, len(centre) - 1)
            hips[:, k] = centre[idx]
        shot = frame_camera(hips, FILM_CHARACTER_HEIGHT_M, self.fps, self.size)
        self.shots.append(shot)
        self.problems.extend(problems)
        return _PreparedScene(shot, statics, cast, sky_picture(scene.background, self.size), problems)

    def describe(self, prepared: _PreparedScene, i: int) -> SceneDescription:
        """Scene frame ``i`` as a description (what pyrender, or Kivy GL, draws)."""
        w, h = self.size
        desc = SceneDescription(prepared.shot.view(i, w, h), lighting=FILM_LIGHTING)
        for mesh, colour in prepared.statics:
            add_mesh(desc, mesh, colour)
        for design, poses, centre in prepared.cast:
            k = int(np.clip(i, 0, len(poses) - 1))
            add_character(desc, design, poses[k])
            pose = np.eye(4)
            pose[[0, 2], 3] = centre[k][[0, 2]]
            desc.add(_shadow(design.height_m), (40, 40, 40), pose, 1.0)
        return desc

    def _render(self, desc: SceneDescription):
        if self._renderer is None:
            from ar.render import PyrenderSceneRenderer  # optional: pyrender (the export falls back to 2-D without it)
            self._renderer = PyrenderSceneRenderer()
        return self._renderer.render(desc, with_depth=True)

    def check(self) -> None:
        """Draw one empty frame: raises (ImportError, a GL error) where 3-D cannot render,
        before any card is written, so the caller can fall back."""
        self._render(SceneDescription(Shot(np.zeros((1, 3)), np.ones(1)).view(0, *self.size)))

    def scene_frame(self, prepared: _PreparedScene, i: int) -> np.ndarray:
        """Scene frame ``i`` drawn by pyrender, the sky put where nothing was hit."""
        rgb, depth = self._render(self.describe(prepared, i))
        sky = depth <= 0
        out = rgb.copy()
        out[sky] = prepared.sky[sky]
        return out

    def frames(self) -> Iterator[np.ndarray]:
        """Every frame, title to ending (RGB, (H, W, 3) uint8)."""
        yield from with_cards(self.story, self.fps, self.size, self._scene_frames())

    def _scene_frames(self) -> Iterator[np.ndarray]:
        for scene, (_, n) in zip(self.story.scenes, self.layout[1:-1]):
            prepared = self.prepare(scene, n)
            for i in range(n):
                yield self.scene_frame(prepared, i)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


_SHADOWS: dict[float, object] = {}


def _shadow(height_m: float):
    """A flat dark disc under a character (one mesh per height, reused every frame)."""
    key = round(float(height_m), 4)
    if key not in _SHADOWS:
        _SHADOWS[key] = ellipsoid((0.0, 0.0005, 0.0), (0.22 * height_m, 0.0004, 0.22 * height_m))
    return _SHADOWS[key]


__all__ = ["FILM_SIZE", "FILM_FPS", "TITLE_SECONDS", "ENDING_SECONDS", "FILM_CHARACTER_HEIGHT_M",
           "CAMERA_ELEVATION_DEG", "Shot", "frame_camera", "StoryFilm"]
