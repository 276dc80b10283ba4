"""The projector stage drawn by Kivy GL, behind the renderers' common call: ``(scene, t,
view) -> (H, W, 3) uint8``, for benchmarks and headless checks (the app itself draws the
stage's descriptions in :mod:`app.ui.play`).

:func:`kivy_gl_stage_renderer` is :class:`app.player.stage.StageRenderer` (tracking,
animation, the scene description) with :class:`app.ui.gl.KivyGLRenderer` as its ``draw``:
the same frames as the pyrender stage, drawn with OpenGL ES 2. Call it on Kivy's main
thread after the window exists (:func:`app.ui.env.prepare_kivy_env`, then
``import kivy.core.window``). On Mesa's software rasteriser set ``LP_NUM_THREADS=1`` for
a one-core figure.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from app.player.stage import StageRenderer
from app.story import Scene
from app.ui.gl.renderer import PROJECTOR_SUPERSAMPLE, KivyGLRenderer

StageCall = Callable[[Scene, float, str], np.ndarray]


def kivy_gl_stage_renderer(rig=None, supersample: int | None = None, **stage_kwargs) -> StageCall:
    """``render(scene, t, view="projector") -> RGB``; ``render.stage`` is the
    :class:`StageRenderer` (its last :class:`app.player.stage.StageFrame` is
    ``render.last_frame``), ``render.gl`` the :class:`KivyGLRenderer`, ``render.name`` is
    ``"kivy-gl"``. ``supersample``: default :data:`PROJECTOR_SUPERSAMPLE`, as the projector
    screen draws. ``stage_kwargs`` go to :class:`StageRenderer` (``rig``, ``fps``, ...)."""
    gl = KivyGLRenderer(PROJECTOR_SUPERSAMPLE if supersample is None else supersample)
    stage = StageRenderer(rig=rig, draw=gl.render, **stage_kwargs)

    def render(scene: Scene, t: float, view: str = "projector") -> np.ndarray:
        frame = stage.render(scene, t, view)
        render.last_frame = frame
        return frame.rgb

    render.stage, render.gl, render.name, render.last_frame = stage, gl, "kivy-gl", None
    return render


__all__ = ["kivy_gl_stage_renderer", "StageCall"]
