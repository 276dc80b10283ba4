"""3-D preview of a whole scene for Play: every character retargeted, laid on its sketched
path and rendered from above the table with pyrender.

Made to run inside :class:`app.scene.render_thread.RenderThread` (pyrender's GL context must
live on that one thread). Preparing a scene (load the clip, retarget, follow the path;
:class:`app.scene.animator.SceneAnimator`) costs about a second per character, so
prepared scenes are cached by content; changing a path prepares the scene again. A
character whose motion cannot be laid on its path is reported in ``problems`` and left
out; the tablet keeps its 2-D preview meanwhile. The table is laid in the scene by
:data:`app.scene.placement.PREVIEW_PLACEMENT` (full size, seen from the child's side).

Imports :mod:`ar.render` (pyrender): import this module only where 3-D is wanted.
"""
from __future__ import annotations

import csv
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.paths import MOTIONS_DIR
from app.scene.animator import SceneAnimator
from app.scene.placement import PREVIEW_PLACEMENT, table_to_scene
from app.story import TABLE_DEPTH_M, TABLE_WIDTH_M, Scene
from ar import look_at
from ar.render import CharacterRig, ProjectorRenderer, add_path, add_table
from retrieval.errors import StoryBeamError

log = logging.getLogger(__name__)


@dataclass
class _Prepared:
    renderer: ProjectorRenderer
    rigs: list = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


class ScenePreviewRenderer:
    """``render(scene, t) -> (H, W, 3) uint8``: the scene at time ``t`` seen from above the
    child's side of the table."""

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
        self.animator = SceneAnimator(self.clip_files, self.first_of_class, fps=fps, placement=PREVIEW_PLACEMENT)

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
        w, h = self.width, self.height
        f = 0.95 * w
        K = np.array([[f, 0, w / 2 - 0.5], [0, f, h / 2 - 0.5], [0, 0, 1.0]])
        renderer = ProjectorRenderer(w, h, K, ambient=0.45, light_intensity=3.5)
        add_table(renderer, TABLE_WIDTH_M, TABLE_DEPTH_M, table_colour(scene.background))
        # above the child's edge of the table (scene -Z), looking across it
        renderer.set_view(look_at(np.array([0.0, 0.95, -0.75]), np.array([0.0, 0.0, 0.02]), np.array([0.0, 1.0, 0.0])))
        prepared = _Prepared(renderer)
        for i, character in enumerate(scene.characters):
            if len(character.path) < 2:
                continue
            add_path(renderer, f"path{i}", table_to_scene(np.array(character.path), PREVIEW_PLACEMENT),
                     (255, 255, 255), width=0.01)
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


def table_colour(background: str) -> tuple[int, int, int]:
    """The table top's colour (RGB 0..255) under a scene background."""
    return {"sky": (158, 214, 250), "grass": (140, 204, 107), "night": (40, 50, 110), "sea": (70, 140, 210),
            "castle": (237, 219, 184), "forest": (77, 140, 77), "space": (40, 30, 70),
            "sand": (245, 214, 140)}.get(background, (150, 150, 160))


__all__ = ["ScenePreviewRenderer", "table_colour"]
