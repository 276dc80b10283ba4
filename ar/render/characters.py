"""Characters for pyrender and for files: the trimesh / pyrender form of
:mod:`ar.scene.characters` (the numpy builder every renderer shares).

* :func:`part_mesh` -- a part's :class:`ar.scene.MeshData` as a smooth-shaded, coloured
  ``pyrender.Mesh`` (uploaded once, then only posed);
* :func:`to_trimesh` -- the same mesh as a ``trimesh.Trimesh`` (exports, checks);
* :func:`save_character` -- the rest-pose preview ``<name>.glb`` and its ``<name>.json``.

The builder's names are re-exported so existing imports keep working.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyrender
import trimesh

from ar.scene import (
    CHARACTER_NAMES,
    DEFAULT_HEIGHT_M,
    Character,
    CharacterError,
    Design,
    MeshData,
    Palette,
    Part,
    build_character,
    rest_motion,
)


def material(colour, roughness: float = 0.7) -> pyrender.MetallicRoughnessMaterial:
    """A matte, non-metallic material of ``colour`` (RGB 0..255)."""
    rgb = np.asarray(colour, np.float64) / 255.0
    return pyrender.MetallicRoughnessMaterial(baseColorFactor=[*rgb, 1.0], metallicFactor=0.0,
                                              roughnessFactor=roughness)


def part_mesh(mesh: MeshData, colour, roughness: float = 0.7) -> pyrender.Mesh:
    """``mesh`` with its own vertex normals (smooth shading) and a matte ``colour``."""
    prim = pyrender.Primitive(positions=mesh.vertices, normals=mesh.normals, indices=mesh.faces,
                              material=material(colour, roughness), mode=pyrender.constants.GLTF.TRIANGLES)
    return pyrender.Mesh([prim])


def to_trimesh(mesh: MeshData, colour=None) -> trimesh.Trimesh:
    """``mesh`` as a trimesh (vertices, faces, normals kept), optionally face-coloured."""
    out = trimesh.Trimesh(mesh.vertices.astype(np.float64), mesh.faces.astype(np.int64),
                          vertex_normals=mesh.normals.astype(np.float64), process=False)
    if colour is not None:
        out.visual.face_colors = np.array([*colour, 255], dtype=np.uint8)
    return out


def save_character(character: Character, folder: str | Path) -> Path:
    """Write the rest-pose mesh (``<name>.glb``) and metadata (``<name>.json``: height,
    parts and joints) to ``folder``; returns the JSON path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    poses = character.all_part_poses(rest_motion(character), [0])[0]
    mesh = trimesh.util.concatenate([to_trimesh(p.mesh.transformed(T), p.colour)
                                     for p, T in zip(character.parts, poses)])
    mesh.export(folder / f"{character.name}.glb")
    meta = {
        "name": character.name,
        "height_m": character.height_m,
        "joints": character.skeleton.names,
        "parts": [{"name": p.name, "joint": p.joint, "colour": list(p.colour),
                   "faces": int(len(p.mesh.faces))} for p in character.parts],
        "bounds_m": mesh.bounds.round(4).tolist(),
    }
    path = folder / f"{character.name}.json"
    path.write_text(json.dumps(meta, indent=2))
    return path


__all__ = ["material", "part_mesh", "to_trimesh", "save_character",
           # re-exported from ar.scene.characters
           "CHARACTER_NAMES", "DEFAULT_HEIGHT_M", "Character", "CharacterError", "Design", "Palette", "Part",
           "build_character", "rest_motion"]
