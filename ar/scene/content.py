"""Scene content shared by every view: characters posed on the table, the table, a path.

Each helper appends :class:`ar.scene.description.DrawItem` s to a
:class:`ar.scene.description.SceneDescription`; the meshes are made once by the caller
(or the character builder) and reused frame after frame, so a renderer uploads them once.
"""
from __future__ import annotations

import numpy as np

from ar.scene.characters import Character
from ar.scene.description import Colour, SceneDescription
from ar.scene.mesh import MeshData, box

#: the table top's roughness (a matt board), as the test content of :mod:`ar.render` uses
TABLE_ROUGHNESS = 0.7


def table_mesh(width_m: float, depth_m: float) -> MeshData:
    """A table top ``width_m`` along scene X by ``depth_m`` along Z, 1 cm thick, its top
    surface at y = -0.0001 (just under anything standing on it), centred on the origin."""
    return box((width_m, 0.01, depth_m), (0.0, -0.0051, 0.0))


def add_character(desc: SceneDescription, character: Character, part_poses: np.ndarray) -> None:
    """Every part of ``character`` at its (P, 4, 4) scene-frame pose."""
    for part, pose in zip(character.parts, part_poses):
        desc.add(part.mesh, part.colour, pose)


def add_mesh(desc: SceneDescription, mesh: MeshData, colour: Colour, roughness: float = TABLE_ROUGHNESS) -> None:
    """A static mesh (table, path ribbon) at the scene origin."""
    desc.add(mesh, colour, None, roughness)


__all__ = ["TABLE_ROUGHNESS", "table_mesh", "add_character", "add_mesh"]
