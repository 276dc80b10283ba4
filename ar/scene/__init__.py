"""The renderer-agnostic scene: meshes as numpy arrays, characters, views and light.

* :mod:`ar.scene.mesh` -- ``MeshData`` (positions, normals, triangles) and the closed
  primitives (ellipsoid, capsule, box, flat ribbon), with exact normals;
* :mod:`ar.scene.characters` -- the robot, cat and kid built from those primitives on the
  canonical body, and their per-frame part poses;
* :mod:`ar.scene.description` -- the scene and board frames, ``View`` (OpenCV intrinsics
  and extrinsics, the OpenGL matrices), ``Lighting``, ``SceneDescription``;
* :mod:`ar.scene.content` -- characters, table and path put into a description.

One description feeds both renderers: pyrender (:mod:`ar.render`, headless reference and
MP4 export) and Kivy's OpenGL ES 2 (:mod:`app.ui.gl`, the app on every device). Needs
numpy, OpenCV (through :mod:`ar`) and :mod:`retrieval.motion` / :mod:`retrieval.animation`
only: no trimesh, pyrender, OpenGL or Kivy, so it runs on the tablet.
"""
from __future__ import annotations

from ar.scene.characters import (
    CHARACTER_NAMES,
    PERFORMER_NAMES,
    DEFAULT_HEIGHT_M,
    Character,
    CharacterError,
    Design,
    Palette,
    Part,
    build_character,
    rest_motion,
)
from ar.scene.content import TABLE_ROUGHNESS, add_character, add_mesh, table_mesh
from ar.scene.description import (
    CV_TO_GL,
    DrawItem,
    Lighting,
    SceneDescription,
    View,
    board_from_scene,
    board_to_scene_points,
    overhead_view,
    projector_from_scene,
    scaled_model,
    scene_ground,
    scene_to_board_points,
)
from ar.scene.mesh import MeshData, box, capsule, concatenate, ellipsoid, ribbon, sphere

__all__ = [
    # mesh
    "MeshData", "concatenate", "ellipsoid", "sphere", "capsule", "box", "ribbon",
    # characters
    "DEFAULT_HEIGHT_M", "CHARACTER_NAMES", "PERFORMER_NAMES", "CharacterError", "Part", "Character", "Palette", "Design",
    "build_character", "rest_motion",
    # description
    "CV_TO_GL", "board_from_scene", "scene_to_board_points", "board_to_scene_points", "projector_from_scene",
    "scaled_model", "scene_ground", "View", "Lighting", "DrawItem", "SceneDescription", "overhead_view",
    # content
    "TABLE_ROUGHNESS", "table_mesh", "add_character", "add_mesh",
]
