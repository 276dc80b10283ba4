"""3-D rendering for the rig: what the projector shows, and the characters it shows.

* :mod:`ar.render.projector_view` -- the Y-up *scene frame* on the board, the projector as
  an inverse camera (:class:`ProjectorRenderer`, headless EGL), test content;
* :mod:`ar.render.characters` -- the characters of :mod:`ar.scene.characters` (numpy) as
  pyrender meshes, trimesh and files;
* :mod:`ar.render.scene_render` -- ``PyrenderSceneRenderer``: draws an
  :class:`ar.scene.SceneDescription` (the reference the Kivy GL renderer is held to);
* :mod:`ar.render.character_render` -- a character posed per frame in a renderer
  (:class:`CharacterRig`), the table and the drawn path, the authoring overhead view.

This is the one place pyrender is imported from: importing ``ar.render`` (or any module
in it) first selects PyOpenGL's headless EGL platform, below, unless the environment
already chose one -- so every user of pyrender goes through this package. Needs
pyrender, trimesh and OpenGL, none of which exist on Android; the app imports this
package only where 3-D is wanted (see :mod:`app.player`).
"""
from __future__ import annotations

import os

# Before pyrender (via PyOpenGL) is first imported: render offscreen through EGL, no display.
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from ar.render.character_render import (  # noqa: E402  (after PYOPENGL_PLATFORM is set)
    CharacterRig,
    OverheadView,
    add_path,
    add_table,
    path_ribbon,
    scaled_model,
)
from ar.render.characters import (  # noqa: E402
    CHARACTER_NAMES,
    DEFAULT_HEIGHT_M,
    Character,
    CharacterError,
    Design,
    Palette,
    Part,
    build_character,
    material,
    part_mesh,
    rest_motion,
    save_character,
    to_trimesh,
)
from ar.render.projector_view import (  # noqa: E402
    CV_TO_GL,
    ProjectorRenderer,
    add_dots,
    add_test_scene,
    axes_mesh,
    board_from_scene,
    board_to_scene_points,
    opencv_to_pyrender_pose,
    projector_from_scene,
    pyrender_to_opencv_pose,
    scene_to_board_points,
)
from ar.render.scene_render import PyrenderSceneRenderer  # noqa: E402

__all__ = [
    # projector_view
    "CV_TO_GL", "board_from_scene", "scene_to_board_points", "board_to_scene_points", "opencv_to_pyrender_pose",
    "pyrender_to_opencv_pose", "projector_from_scene", "ProjectorRenderer", "axes_mesh", "add_test_scene", "add_dots",
    # characters
    "DEFAULT_HEIGHT_M", "CHARACTER_NAMES", "CharacterError", "Part", "Character", "Palette", "Design",
    "build_character", "rest_motion", "save_character", "material", "part_mesh", "to_trimesh",
    # character_render
    "scaled_model", "CharacterRig", "path_ribbon", "add_table", "add_path", "OverheadView",
    # scene_render
    "PyrenderSceneRenderer",
]
