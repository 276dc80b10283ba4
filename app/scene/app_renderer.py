"""The one renderer behind the app's render thread: the Play preview and the projector stage.

The app (:mod:`app.ui.app`) hands :class:`app.scene.render_thread.RenderThread` a
*factory*; the thread calls it once, on itself, and then calls the renderer with each
job: a bare :class:`app.story.Scene` (the Play preview, :mod:`app.scene.preview`) or a
:class:`StageJob` (the projector stage, :mod:`app.scene.stage`).

This module stays light (no pyrender, no OpenCV at import): the app imports it at
start-up, and the 3-D modules are loaded by the render thread on its first job.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from app.story import Scene

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StageJob:
    """A render request for the projector stage (vs. a bare Scene for the Play preview)."""

    scene: Scene
    view: str = "projector"


class AppRenderer:
    """Serves both jobs on the render thread; each 3-D renderer (and its GL context) is
    created lazily there, on its first job."""

    def __init__(self, profile_dir: Path | None = None, rig=None):
        """``rig``: use this rig instead of looking for one (tests)."""
        self.profile_dir = profile_dir
        self.rig = rig
        self._preview = None
        self._stage = None

    def __call__(self, job: Scene | StageJob, t: float):
        # The 3-D modules need pyrender (absent on Android, where the app never makes this
        # renderer) and take ~1.5 s to import (measured): loaded here, on the render
        # thread's first job, so the app's first frame never waits for them.
        from app.scene.preview import ScenePreviewRenderer  # optional: pyrender (deferred to the render thread)
        from app.scene.stage import StageError, StageRenderer, SyntheticRig  # optional: pyrender (as above)

        if isinstance(job, StageJob):
            if self._stage is None:
                self._stage = StageRenderer(rig=self.rig, profile_dir=self.profile_dir)
            try:
                return self._stage.render(job.scene, t, job.view)
            except StageError as exc:
                if not self._stage.live:
                    raise
                # the rig's camera went away mid-show: keep the show going on the synthetic rig
                log.warning("live rig failed, projector stage switches to the synthetic rig: %s", exc)
                self._stage.close()
                self._stage = StageRenderer(rig=SyntheticRig(self._stage.board))
                return self._stage.render(job.scene, t, job.view)
        if self._preview is None:
            self._preview = ScenePreviewRenderer()
        return self._preview.render(job, t)


def app_renderer_factory(profile_dir: Path | None = None) -> Callable[[], AppRenderer]:
    """The app's renderer factory (runs on the render thread); marked as able to draw
    the projector stage, which :meth:`app.ui.app.StoryBeamApp.stage_available` checks."""
    def make() -> AppRenderer:
        return AppRenderer(profile_dir)
    make.supports_stage = True
    return make


__all__ = ["StageJob", "AppRenderer", "app_renderer_factory"]
