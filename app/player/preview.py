"""3-D preview of a whole scene for Play: every character retargeted, laid on its sketched
path and seen from above the table.

:meth:`ScenePreviewRenderer.describe` makes the frame as an :class:`ar.scene.SceneDescription`
(numpy only: it runs on the tablet); :meth:`ScenePreviewRenderer.render` also draws it
with pyrender (:class:`ar.render.PyrenderSceneRenderer`, imported on first use) for the
MP4 export and headless tests. The app draws the description itself with Kivy GL
(:mod:`app.ui.gl`). Preparing a scene (load the clip, retarget, follow the path;
:class:`app.player.animator.SceneAnimator`) costs about a second per character, so
prepared scenes are cached by content; changing a path prepares the scene again. A
character whose motion cannot be laid on its path is reported in ``problems`` and left
out; the tablet keeps its 2-D preview meanwhile. The table is laid in the scene by
:data:`app.player.placement.PREVIEW_PLACEMENT` (full size, seen from the child's side).
"""
from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.paths import MOTIONS_DIR
from app.player.animator import SceneAnimator
from app.player.placement import PREVIEW_PLACEMENT, table_to_scene
from app.story import TABLE_DEPTH_M, TABLE_WIDTH_M, Scene
from ar import look_at
from ar.scene import Lighting, SceneDescription, View, add_character, add_mesh, ribbon, table_mesh


#: the preview's light: brighter than the projector's (a lit table, not light on a table)
PREVIEW_LIGHTING = Lighting(ambient=0.45, key_intensity=3.5)


@dataclass
class _Prepared:
    view: View
    statics: list = field(default_factory=list)  # (mesh, colour): table and paths
    cast: list = field(default_factory=list)  # (design, (F, P, 4, 4) part poses)
    problems: list[str] = field(default_factory=list)


class ScenePreviewRenderer:
    """``describe(scene, t) -> SceneDescription`` and ``render(scene, t) -> (H, W, 3) uint8``:
    the scene at time ``t`` seen from above the child's side of the table."""

    def __init__(self, width: int = 640, height: int = 426, fps: float = 30.0,
                 motions_dir: str | Path = MOTIONS_DIR):
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
        self._pyrender = None
        self.animator = SceneAnimator(self.clip_files, self.first_of_class, fps=fps, placement=PREVIEW_PLACEMENT)

    def __call__(self, scene: Scene, t: float) -> np.ndarray:
        return self.render(scene, t)

    def describe(self, scene: Scene, t: float) -> SceneDescription:
        key = json.dumps(scene.to_dict(), sort_keys=True)
        if key != self._key:
            self._prepared = self._prepare(scene)
            self._key = key
        prepared = self._prepared
        desc = SceneDescription(prepared.view, lighting=PREVIEW_LIGHTING)
        for mesh, colour in prepared.statics:
            add_mesh(desc, mesh, colour)
        frame = int(round(max(t, 0.0) * self.fps))
        for design, poses in prepared.cast:
            add_character(desc, design, poses[int(np.clip(frame, 0, len(poses) - 1))])
        return desc

    def render(self, scene: Scene, t: float) -> np.ndarray:
        """The frame drawn by pyrender (the reference renderer; imported on first use)."""
        desc = self.describe(scene, t)
        if self._pyrender is None:
            from ar.render import PyrenderSceneRenderer  # optional: pyrender (absent on Android: use describe())
            self._pyrender = PyrenderSceneRenderer()
        return self._pyrender.render(desc)

    @property
    def problems(self) -> list[str]:
        return list(self._prepared.problems) if self._prepared else []

    def close(self) -> None:
        if self._pyrender is not None:
            self._pyrender.close()
            self._pyrender = None
        self._prepared = None
        self._key = None

    # -- preparation --------------------------------------------------------------------
    def _prepare(self, scene: Scene) -> _Prepared:
        w, h = self.width, self.height
        f = 0.95 * w
        K = np.array([[f, 0, w / 2 - 0.5], [0, f, h / 2 - 0.5], [0, 0, 1.0]])
        # above the child's edge of the table (scene -Z), looking across it
        T = look_at(np.array([0.0, 0.95, -0.75]), np.array([0.0, 0.0, 0.02]), np.array([0.0, 1.0, 0.0]))
        prepared = _Prepared(View(w, h, K, T))
        prepared.statics.append((table_mesh(TABLE_WIDTH_M, TABLE_DEPTH_M), table_colour(scene.background)))
        for character in scene.characters:
            if len(character.path) >= 2:
                path = table_to_scene(np.array(character.path), PREVIEW_PLACEMENT)
                prepared.statics.append((ribbon(path, width=0.01), (255, 255, 255)))
        cast, problems = self.animator.animate_scene(scene.characters, "3-D preview")
        prepared.problems.extend(problems)
        prepared.cast.extend((design, design.all_part_poses(motion)) for _, design, motion in cast)
        return prepared


def table_colour(background: str) -> tuple[int, int, int]:
    """The table top's colour (RGB 0..255) under a scene background."""
    return {"sky": (158, 214, 250), "grass": (140, 204, 107), "night": (40, 50, 110), "sea": (70, 140, 210),
            "castle": (237, 219, 184), "forest": (77, 140, 77), "space": (40, 30, 70),
            "sand": (245, 214, 140)}.get(background, (150, 150, 160))


__all__ = ["ScenePreviewRenderer", "table_colour", "PREVIEW_LIGHTING"]
