"""Render an animated character on the table: projector view, camera view, overhead.

* **projector view** — what the projector emits (black = no light): the character
  rendered through the projector's intrinsics from the projector pose that the tracker
  estimated (:class:`ar.render.projector_view.ProjectorRenderer`).
* **camera view** — what the rig's camera (or a bystander) sees: the synthetic camera
  frame of the board and table with the projected light composited on the table
  (:class:`ar.synthetic.SyntheticCamera`). The light is cast onto the table plane, as a
  real projector's would be, so the character looks "painted" on the table and seen
  from the camera it is distorted exactly as a real projection.
* **overhead** — a preview for authoring: the character in 3-D on a grey table with the
  drawn path, from above and in front.

Motions are in StoryBeam's Y-up world, which is this module's *scene frame*: metres,
origin at the board centre on the table, +X = board +x, +Z = board +y (see
:mod:`ar.render.projector_view`; :func:`ar.render.projector_view.board_to_scene_points`
maps board-frame points into it).
"""
from __future__ import annotations

import numpy as np

from ar import look_at
from ar.render.characters import part_mesh
from ar.render.projector_view import ProjectorRenderer
from ar.scene import Character, MeshData, ribbon, scaled_model, table_mesh  # noqa: F401 (scaled_model re-exported)
from retrieval.motion import Motion


class CharacterRig:
    """A character's parts as nodes of a :class:`ProjectorRenderer`, posed per frame.

    Each part is one static mesh; animating means setting one 4x4 pose per part per
    frame, which is cheap (no mesh upload)."""

    def __init__(self, renderer: ProjectorRenderer, character: Character, prefix: str = "char"):
        self.renderer = renderer
        self.character = character
        self.names = []
        for k, part in enumerate(character.parts):
            mesh = part_mesh(part.mesh, part.colour)
            name = f"{prefix}/{k}:{part.name}"
            renderer.add(name, mesh)
            self.names.append(name)
        self._poses: np.ndarray | None = None
        self._motion: Motion | None = None

    def bind(self, motion: Motion) -> None:
        """Precompute every frame's part poses (forward kinematics once for the clip)."""
        self._poses = self.character.all_part_poses(motion)
        self._motion = motion

    def show_frame(self, frame: int) -> None:
        if self._poses is None:
            raise RuntimeError("bind a motion first")
        f = int(np.clip(frame, 0, len(self._poses) - 1))
        for name, pose in zip(self.names, self._poses[f]):
            self.renderer.set_pose(name, pose)


def path_ribbon(points_xz: np.ndarray, width: float = 0.006, lift: float = 0.0005) -> MeshData:
    """A flat ribbon on the table along a path (the child's drawn line): :func:`ar.scene.ribbon`."""
    return ribbon(points_xz, width, lift)


def add_table(renderer: ProjectorRenderer, width_m: float, depth_m: float, colour, name: str = "table") -> None:
    """A table top ``width_m`` along scene X by ``depth_m`` along Z, 1 cm thick, its top
    surface at y = 0 (just under anything standing on it), centred on the scene origin."""
    renderer.add(name, part_mesh(table_mesh(width_m, depth_m), colour))


def add_path(renderer: ProjectorRenderer, name: str, points_xz: np.ndarray, colour, width: float = 0.006) -> None:
    """The child's drawn path as a flat ribbon of ``colour`` on the table (:func:`path_ribbon`)."""
    renderer.add(name, part_mesh(path_ribbon(points_xz, width=width), colour))


class OverheadView:
    """An authoring preview: grey table, the path, the character; camera above-front."""

    def __init__(self, character: Character, path_xz: np.ndarray | None, width: int = 640, height: int = 480,
                 eye=(0.0, 0.32, 0.30), target=(0.0, 0.0, 0.0)):
        f = 0.9 * width
        K = np.array([[f, 0, width / 2 - 0.5], [0, f, height / 2 - 0.5], [0, 0, 1.0]])
        self.renderer = ProjectorRenderer(width, height, K, ambient=0.45, light_intensity=3.5)
        add_table(self.renderer, 1.2, 1.0, (150, 150, 160))
        if path_xz is not None and len(path_xz) > 1:
            add_path(self.renderer, "path", path_xz, (255, 230, 0))
        self.rig = CharacterRig(self.renderer, character)
        self.renderer.set_view(look_at(np.asarray(eye, float), np.asarray(target, float), np.array([0.0, 1.0, 0.0])))

    def render(self, frame: int) -> np.ndarray:
        self.rig.show_frame(frame)
        return self.renderer.render()

    def close(self) -> None:
        self.renderer.close()
