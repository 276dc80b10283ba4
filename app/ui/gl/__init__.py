"""Kivy's OpenGL ES 2 renderer for :class:`ar.scene.SceneDescription` (characters, table,
stage): what draws the 3-D Play preview and the projector screen wherever the app runs,
Android included (no pyrender, no PyOpenGL).

* :mod:`app.ui.gl.shaders` -- the GLSL ES 1.00 shaders (pyrender's shading, reduced);
* :mod:`app.ui.gl.renderer` -- ``KivyGLRenderer``: an ``Fbo`` with depth, meshes uploaded
  once, ``draw`` (a texture for the screen) and ``render`` (an RGB array);
* :mod:`app.ui.gl.stage` -- ``kivy_gl_stage_renderer``: the projector stage as
  ``(scene, t, view) -> RGB`` drawn by Kivy GL (benchmarks, headless checks); imported
  by its own path (it loads the stage: OpenCV, the animation), not from here, so the
  app's start-up does not wait for it.

Import after :func:`app.ui.env.prepare_kivy_env`, and draw on Kivy's main thread only.
"""
from __future__ import annotations

from app.ui.gl.renderer import PROJECTOR_SUPERSAMPLE, SUPERSAMPLE, VERTEX_FORMAT, KivyGLError, KivyGLRenderer, kivy_matrix
from app.ui.gl.shaders import FRAGMENT, VERTEX

__all__ = ["KivyGLRenderer", "KivyGLError", "VERTEX_FORMAT", "SUPERSAMPLE", "PROJECTOR_SUPERSAMPLE", "kivy_matrix", "VERTEX", "FRAGMENT"]
