"""The one renderer behind the app's render thread: the Play preview and the projector stage.

The app (:mod:`app.ui.app`) hands :class:`app.player.render_thread.RenderThread` a
*factory*; the thread calls it once, on itself, and then calls the renderer with each
job: a bare :class:`app.story.Scene` (the Play preview, :mod:`app.player.preview`) or a
:class:`StageJob` (the projector stage, :mod:`app.player.stage`).

This module stays light (no pyrender, no OpenCV at import): the app imports it at
start-up, and the 3-D modules are loaded by the render thread on its first job.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from app.story import Scene
from retrieval.errors import StoryBeamError

log = logging.getLogger(__name__)

#: the profile setting (:meth:`app.story.storage.ProfileStore.get_setting`) that holds the
#: teacher's choice of the rig's camera source: a device number, a video file or a folder
CAMERA_SETTING = "rig_camera"
#: the camera source when neither ``--camera`` nor the setting names one
DEFAULT_CAMERA = "0"
#: the camera choice that names the Kivy camera (Android's camera): ``kivy`` (camera 0) or
#: ``kivy:N``; made by the app on Kivy's main thread (:mod:`app.ui.kivy_camera`), not here
KIVY_CAMERA = "kivy"
#: the rig's calibration files, in the profile folder (or beside a recording)
CALIBRATION_FILES = ("camera.json", "projector.json")


def kivy_camera_index(choice: object) -> int | None:
    """The camera index when ``choice`` names the Kivy camera (``kivy`` = 0, ``kivy:N`` = N), else None."""
    if not isinstance(choice, str):
        return None
    text = choice.strip().lower()
    if text == KIVY_CAMERA:
        return 0
    head, sep, index = text.partition(":")
    return int(index) if head == KIVY_CAMERA and sep and index.isdigit() else None


def has_calibration(folder: Path | None) -> bool:
    """True when ``folder`` holds both calibration files (:data:`CALIBRATION_FILES`)."""
    return folder is not None and all((Path(folder) / name).is_file() for name in CALIBRATION_FILES)


def default_camera_choice(profile_dir: Path | None, android: bool) -> str | None:
    """The rig camera when neither ``--camera`` nor the teacher's setting names one: on
    Android the Kivy camera (the tablet's own) once the rig is calibrated, else None (the
    synthetic rig: there is no OpenCV device to open); elsewhere :data:`DEFAULT_CAMERA`."""
    if not android:
        return DEFAULT_CAMERA
    return KIVY_CAMERA if has_calibration(profile_dir) else None


def saved_camera_choice(db: Path, default: str | None = DEFAULT_CAMERA) -> str | None:
    """The teacher's saved rig camera (:data:`CAMERA_SETTING`) when it is still usable,
    else ``default``; a saved choice that no longer opens is reported as a warning."""
    from app.story.storage import ProfileStore  # deferred: app start-up only

    saved = None
    if Path(db).is_file():
        try:
            with ProfileStore(db) as store:
                saved = store.get_setting(CAMERA_SETTING)
        except StoryBeamError:
            pass  # an unreadable profile is the app's to recover (it opens a fresh one); the default camera
    if saved:
        try:
            return check_camera_choice(saved)
        except StoryBeamError as exc:
            print(f"warning: the saved rig camera cannot be used ({exc}); using camera {default}")
    return default


@dataclass(frozen=True)
class StageJob:
    """A render request for the projector stage (vs. a bare Scene for the Play preview)."""

    scene: Scene
    view: str = "projector"
    #: a camera source the UI thread made (the Kivy camera, :mod:`app.ui.kivy_camera`):
    #: the stage's live rig reads it; a new one replaces the stage's rig
    camera: object = None


def check_camera_choice(text: str) -> str:
    """A rig camera choice as it is saved and used: a device number as is; the Kivy camera
    (``kivy``, ``kivy:N``: opened by the app on its main thread, so not checked here); a
    video file or a folder of images only if it opens (else
    :class:`ar.camera_sources.CameraSourceError`, naming the source and the problem)."""
    from ar.camera_sources import CameraSourceError, open_camera_source  # deferred: OpenCV, only to check a recording

    choice = (text or "").strip()
    if not choice:
        raise CameraSourceError("''", "empty camera source (expected a number, kivy, a video file or a folder)")
    index = kivy_camera_index(choice)
    if index is not None:
        return KIVY_CAMERA if index == 0 else f"{KIVY_CAMERA}:{index}"
    if not choice.isdigit():
        open_camera_source(choice, paced=False).close()
    return choice


#: who draws the 3-D frames: Kivy GL on the UI thread, or pyrender on the render thread
RENDERERS = ("kivy-gl", "pyrender")


class AppRenderer:
    """Serves both jobs on the render thread; each 3-D renderer (and its GL context) is
    created lazily there, on its first job."""

    def __init__(self, profile_dir: Path | None = None, rig=None, camera: int | str | None = 0,
                 draw: str | None = "pyrender"):
        """``rig``: use this rig instead of looking for one (tests); ``camera``: the rig's
        camera source (a device number, a video file, a folder of images); ``draw``:
        ``"pyrender"`` draws here and answers images, None answers what to draw -- an
        :class:`ar.scene.SceneDescription` for the Play preview, a
        :class:`app.player.stage.StageFrame` carrying one for the stage -- and the app
        draws it with Kivy GL on its UI thread (:mod:`app.ui.gl`; no pyrender needed)."""
        self.profile_dir = profile_dir
        self.rig = rig
        self.camera = camera
        self.draw = draw
        self._preview = None
        self._stage = None
        self._stage_camera = None  # the ready camera source (StageJob.camera) the stage was opened with

    def __call__(self, job: Scene | StageJob, t: float):
        # The 3-D modules (retargeting, OpenCV; pyrender only when draw="pyrender", on the
        # first frame) take a while to import: loaded here, on the render thread's first
        # job, so the app's first frame never waits for them.
        from app.player.preview import ScenePreviewRenderer  # deferred: to the render thread (retargeting, OpenCV)
        from app.player.stage import StageError, StageRenderer  # deferred: as above
        from ar.rig import SyntheticRig  # deferred: as above (OpenCV)

        if isinstance(job, StageJob):
            if self._stage is not None and job.camera is not self._stage_camera:
                self._stage.close()  # the UI made a new camera (or released it): reopen the rig on it
                self._stage = None
            if self._stage is None:
                # a Kivy camera choice is opened by the UI thread and arrives in the job;
                # without one (no calibration, no camera) the synthetic rig
                camera = job.camera if job.camera is not None else (
                    None if kivy_camera_index(self.camera) is not None else self.camera)
                self._stage = StageRenderer(rig=self.rig, profile_dir=self.profile_dir, camera=camera,
                                            draw=self.draw)
                self._stage_camera = job.camera
            try:
                return self._stage.render(job.scene, t, job.view)
            except StageError as exc:
                if not self._stage.live:
                    raise
                # the rig's camera went away mid-show: keep the show going on the synthetic rig
                log.warning("live rig failed, projector stage switches to the synthetic rig: %s", exc)
                self._stage.close()
                self._stage = StageRenderer(rig=SyntheticRig(self._stage.board), draw=self.draw,
                                            height_map=self._stage.height_map)  # the table keeps its scan
                return self._stage.render(job.scene, t, job.view)
        if self._preview is None:
            self._preview = ScenePreviewRenderer()
        if self.draw is None:
            return self._preview.describe(job, t)
        return self._preview.render(job, t)


def app_renderer_factory(profile_dir: Path | None = None, camera: int | str | None = 0,
                         renderer: str = "kivy-gl") -> Callable[[], AppRenderer]:
    """The app's renderer factory (runs on the render thread); marked as able to draw
    the projector stage, which :meth:`app.ui.app.StoryBeamApp.stage_available` checks.
    ``camera``: the rig's camera source (``storybeam app --camera``, the teacher's setting);
    ``renderer``: ``"kivy-gl"`` (the UI thread draws the descriptions: every device) or
    ``"pyrender"`` (the render thread draws images; desktop with pyrender only), kept on
    the factory as ``make.renderer`` for the app to read."""
    if renderer not in RENDERERS:
        raise ValueError(f"renderer {renderer!r}: choose one of {', '.join(RENDERERS)}")

    def make() -> AppRenderer:
        return AppRenderer(profile_dir, camera=camera, draw=None if renderer == "kivy-gl" else "pyrender")
    make.supports_stage = True
    make.renderer = renderer
    make.camera = camera  # the app opens a Kivy camera choice itself (StoryBeamApp.open_rig_camera)
    return make


__all__ = ["StageJob", "AppRenderer", "app_renderer_factory", "RENDERERS", "CAMERA_SETTING", "DEFAULT_CAMERA", "check_camera_choice",
           "KIVY_CAMERA", "CALIBRATION_FILES", "kivy_camera_index", "has_calibration", "default_camera_choice",
           "saved_camera_choice"]
