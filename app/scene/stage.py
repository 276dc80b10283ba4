"""The story on the table: every character of a scene rendered from the projector's
viewpoint through the tracked rig, for the projector screen and the MP4 export.

Per frame (the same loop as ``storybeam demo``, see :mod:`app.scene.demo_pipeline`):

1. the rig's camera sees the board (and the light the projector showed last frame, as on
   a real rig: one frame of latency) -- a live camera with calibration files, or with no
   rig attached the synthetic rig of :mod:`ar.synthetic` held by a synthetic hand
   (:func:`ar.synthetic.handheld_trajectory`);
2. the board is detected and its pose filtered (:func:`ar.pose.estimate_board_pose`,
   :class:`ar.filtering.PoseTracker`: tracking / holding / lost);
3. the characters, posed at story time ``t``, are described as seen by the projector from
   the tracked pose (an :class:`ar.scene.SceneDescription`) and drawn: by pyrender
   (:class:`ar.render.PyrenderSceneRenderer`, the MP4 export and headless tests) or, with
   ``draw=None``, by the caller -- the app draws it with Kivy GL on its UI thread
   (:mod:`app.ui.gl`) and hands the light back (:attr:`StageFrame.light_sink`) for the
   synthetic rig's next camera frame; black = no light;
4. the *camera view* is that camera frame: the table with the projected light on it,
   what an audience standing by the rig sees.

The story's table (1.2 x 0.8 m on the tablet) is played as a miniature on the marker
board (:data:`app.scene.placement.STAGE_PLACEMENT`): scaled by
:data:`app.scene.placement.STAGE_SCALE` and centred on the board, the table's long side
along the board's long side, the child's edge of the table nearest the rig's camera.
Characters stand :data:`STAGE_CHARACTER_HEIGHT_M` tall there (a little larger than the
scale alone would make them, so they read in the projected light; the path timing is kept).

A :class:`StageRenderer` owns GL state: create and use it on one thread only (the app's
:class:`app.scene.render_thread.RenderThread` through
:class:`app.scene.app_renderer.AppRenderer`, or the export's worker process).

Needs no pyrender (it is imported only when ``draw="pyrender"`` draws a first frame):
the stage runs on the tablet with ``draw=None``.
"""
from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from app.paths import MOTIONS_DIR
from app.scene.animator import SceneAnimator
from app.scene.placement import STAGE_PLACEMENT
from app.story import Scene
from ar import (DEFAULT_BOARD_SPEC, Board, CameraCalibration, PinholeModel, PoseTracker, ProjectorCalibration,
                SyntheticCamera, TrajectoryConfig, default_camera, default_projector, estimate_board_pose,
                handheld_trajectory, project_points)
from ar.camera_sources import CameraSource, open_camera_source
from ar.filtering import TrackerOutput
from ar.live import LiveStats, LiveTracker
from ar.scene import SceneDescription, View, add_character, projector_from_scene, scaled_model
from retrieval.errors import StoryBeamError
from retrieval.motion import positions

log = logging.getLogger(__name__)

STAGE_CHARACTER_HEIGHT_M = 0.10
#: the rig renders and tracks at this size whatever the output size (as the demo does)
RIG_SIZE = (640, 480)
VIEWS = ("projector", "camera")


class StageError(StoryBeamError):
    """The projector stage cannot run (no rig, bad calibration, no renderer)."""


@dataclass
class StageFrame:
    """One rendered frame and what the tracker said about it.

    ``rgb`` is the requested view; ``projector`` the light image (black = no light);
    ``character_px`` where each character's hips land in the projector image (None
    while no pose is known); ``state`` the tracker's: ``ar.TRACKING`` / ``HOLDING`` / ``LOST``.
    """

    rgb: np.ndarray
    projector: np.ndarray
    state: str
    view: str
    character_px: list = field(default_factory=list)
    problems: list = field(default_factory=list)
    live: bool = False  # a real rig (else the synthetic one)
    scene_id: str = ""
    t: float = 0.0  # story time inside the scene
    #: what the projector shows, for a caller that draws it itself (``draw=None``: then
    #: ``projector`` -- and ``rgb`` for the projector view -- is None until it is drawn)
    description: SceneDescription | None = None
    #: give the drawn light image (RGB) back here: the synthetic rig films it next frame
    light_sink: object = None


# ---------------------------------------------------------------------------- rigs
class SyntheticRig:
    """No rig attached: the bench camera and projector (:mod:`ar.synthetic`) held over the
    board by a synthetic hand, so the whole chain (detection, filter, projector render,
    light on the table) runs and can be previewed and exported."""

    live = False

    def __init__(self, board: Board | None = None, fps: float = 30.0, seed: int = 0, loop_s: float = 60.0):
        """``board``: the board the hand holds the rig over (default: the default board)."""
        board = board if board is not None else Board(DEFAULT_BOARD_SPEC)
        w, h = RIG_SIZE
        self.camera_model = scaled_model(default_camera(), w, h)
        self.projector_model = scaled_model(default_projector(), w, h)
        # a bright projector (as in the demo): the light must read on the paper
        self.cam = SyntheticCamera(board, camera=self.camera_model, projector=self.projector_model,
                                   supersample=1, projector_gain=0.9)
        self.T_proj_from_cam = self.cam.proj_from_cam
        self.poses = handheld_trajectory(board, int(loop_s * fps), TrajectoryConfig(fps=fps, seed=seed,
                                                                                   distance_m=0.55))
        self._rng = np.random.default_rng(seed)

    def capture(self, i: int, light: np.ndarray) -> np.ndarray:
        """BGR camera frame number ``i`` with ``light`` (RGB, RIG_SIZE) on the table."""
        n = len(self.poses)
        k = i % (2 * n)  # ping-pong: the hand does not jump when the trajectory ends
        T = self.poses[k if k < n else 2 * n - 1 - k]
        return self.cam.render(T, projector_image=light, rng=self._rng)

    def close(self) -> None:
        pass


class LiveRig:
    """A real rig: a camera source (:mod:`ar.camera_sources`: a device number, a video
    file, a folder of images -- a recording stands in for the camera, looped and paced at
    its frame rate) and the calibration files (``camera.json`` from the calibration
    wizard, ``projector.json`` from ``storybeam calibrate projector``).

    Tracking runs on the rig's own threads (:class:`ar.live.LiveTracker`: the newest
    frame wins, dropped frames are counted): :meth:`track` returns at once with the
    newest result, so neither the UI nor the render thread ever waits for detection."""

    live = True

    def __init__(self, camera: int | str | CameraSource, camera_json: Path, projector_json: Path,
                 board: Board | None = None, first_frame_timeout_s: float = 5.0):
        cam = CameraCalibration.load(camera_json)
        proj = ProjectorCalibration.load(projector_json)
        self.camera_model = PinholeModel(cam.camera_matrix, cam.dist_coeffs, *cam.image_size)
        self.projector_model = PinholeModel(proj.camera_matrix, proj.dist_coeffs, *proj.image_size)
        self.T_proj_from_cam = proj.T_proj_from_cam
        self.board = board if board is not None else Board(DEFAULT_BOARD_SPEC)
        source = camera if isinstance(camera, CameraSource) else open_camera_source(camera, paced=True, loop=True)
        self.source_name = source.name
        self.first_frame_timeout_s = first_frame_timeout_s
        self.tracker = LiveTracker(source, self.board, self.camera_model.K, self.camera_model.dist,
                                   keep_images=True).start()

    def track(self) -> tuple[np.ndarray, TrackerOutput]:
        """The newest tracked frame (BGR) and what the tracker said; waits only for the very first."""
        deadline = time.monotonic() + self.first_frame_timeout_s
        while (result := self.tracker.latest()) is None:
            stats = self.tracker.stats()
            if stats.error or not stats.running or time.monotonic() > deadline:
                raise StageError(f"camera {self.source_name}: {stats.error or 'no frame arrived'}")
            time.sleep(0.005)
        stats = self.tracker.stats()
        if stats.error:
            raise StageError(stats.error)
        return result.image, result.output

    def capture(self, i: int, light: np.ndarray) -> np.ndarray:
        """The newest camera frame (BGR)."""
        return self.track()[0]

    def stats(self) -> LiveStats:
        """Frames captured, processed, dropped, detected (see :class:`ar.live.LiveStats`)."""
        return self.tracker.stats()

    def close(self) -> None:
        self.tracker.stop()


def _calibration_files(folder: Path | None) -> tuple[Path, Path] | None:
    if folder is None:
        return None
    camera_json, projector_json = Path(folder) / "camera.json", Path(folder) / "projector.json"
    return (camera_json, projector_json) if camera_json.is_file() and projector_json.is_file() else None


def open_rig(profile_dir: Path | None, board: Board, fps: float = 30.0,
             camera: int | str | CameraSource | None = 0):
    """A :class:`LiveRig` when calibration files are found and the camera source opens,
    else the :class:`SyntheticRig` (preview mode). Never raises for a missing rig.

    ``camera``: a device number, a video file or a folder of images (``storybeam app
    --camera``, the teacher's setting), or a source already open (the Kivy camera, made by
    the app on its main thread); ``None`` = the synthetic rig. Calibration files come from
    the profile folder, else (for a recording) from the recording's folder."""
    if camera is not None:
        path = Path(str(camera))
        files = _calibration_files(profile_dir)
        recording = not isinstance(camera, CameraSource) and not str(camera).strip().isdigit()
        if files is None and recording:
            files = _calibration_files(path if path.is_dir() else path.parent)
        if files is not None:
            try:
                return LiveRig(camera, *files, board=board)
            except (StoryBeamError, OSError) as exc:
                log.warning("rig not usable, projector preview uses the synthetic rig: %s", exc)
        else:
            log.info("no camera.json + projector.json for camera %s: the projector uses the synthetic rig", camera)
    return SyntheticRig(board, fps=fps)


# ---------------------------------------------------------------------------- renderer
class StageRenderer:
    """``render(scene, t, view) -> StageFrame``: one rig frame per call (the hand moves on
    in real time), the scene's characters posed at story time ``t``.

    Prepared scenes are cached by content (preparing = retargeting and laying each
    character's clip on its path, about a second per character)."""

    def __init__(self, rig=None, profile_dir: Path | None = None, fps: float = 30.0,
                 motions_dir: Path | None = None, rig_fps: float | None = None, camera: int | str | None = 0,
                 draw="pyrender"):
        """``draw``: who draws the light -- ``"pyrender"`` (headless, the MP4 export), a
        callable ``SceneDescription -> RGB``, or None: the caller draws
        :attr:`StageFrame.description` (the app, with Kivy GL on its UI thread).
        ``fps``: the animation's frame rate; ``rig_fps``: how often the rig is sampled
        (one call of :meth:`render` = one rig frame; default ``fps``); ``camera``: the
        camera source :func:`open_rig` tries when no ``rig`` is given."""
        self.board = Board(DEFAULT_BOARD_SPEC)
        self.fps = fps
        self.rig_fps = rig_fps or fps
        self.rig = rig if rig is not None else open_rig(profile_dir, self.board, self.rig_fps, camera)
        model = self.rig.projector_model
        if self.rig.live:  # render the light at the projector's own size (up to 1280 wide)
            k = min(1.0, 1280 / model.width)
            model = scaled_model(model, int(model.width * k), int(model.height * k))
        self.light_model = model
        self.draw = draw
        self._pyrender = None  # made on the first frame drawn with draw="pyrender"
        self.tracker = PoseTracker()
        self.animator = SceneAnimator.from_library(motions_dir or MOTIONS_DIR, fps=fps,
                                                   character_height_m=STAGE_CHARACTER_HEIGHT_M,
                                                   placement=STAGE_PLACEMENT)
        self._key: str | None = None
        self._cast: list = []  # (design, (F, P, 4, 4) part poses) per character on stage
        self._hips_tracks: list = []
        self.problems: list[str] = []
        self._tick = 0
        self._t0 = time.monotonic()
        self._prev_light = np.zeros((*RIG_SIZE[::-1], 3), np.uint8)

    @property
    def live(self) -> bool:
        return bool(self.rig.live)

    def __call__(self, scene: Scene, t: float, view: str = "projector") -> StageFrame:
        return self.render(scene, t, view)

    def prepare(self, scene: Scene) -> None:
        """Put ``scene``'s characters on stage (no-op if it is already there)."""
        key = json.dumps(scene.to_dict(), sort_keys=True)
        if key == self._key:
            return
        self._cast, self._hips_tracks, self.problems = [], [], []
        for i, character in enumerate(scene.characters):
            if len(character.path) < 2:
                continue
            try:
                design, motion = self.animator.animate(character)
            except (StoryBeamError, ValueError, OSError) as exc:
                self.problems.append(f"{character.kind} {character.id}: {exc}")
                log.warning("projector stage leaves out %s: %s", character.id, exc)
                continue
            self._cast.append((design, design.all_part_poses(motion)))
            self._hips_tracks.append(positions(motion)[:, 0])  # for character_px
        self._key = key

    def render(self, scene: Scene, t: float, view: str = "projector") -> StageFrame:
        if view not in VIEWS:
            raise StageError(f"unknown stage view {view!r}; choose one of {', '.join(VIEWS)}")
        self.prepare(scene)
        i = self._tick
        self._tick += 1
        if self.rig.live:  # tracked on the rig's own threads, in real time (newest frame wins)
            frame_bgr, track = self.rig.track()
        else:  # the synthetic rig, tracked here at its own frame rate
            frame_bgr = self.rig.capture(i, self._prev_light)
            cam = self.rig.camera_model
            estimate = estimate_board_pose(frame_bgr, self.board, cam.K, cam.dist)
            track = self.tracker.update(estimate, i / self.rig_fps)
        m = self.light_model
        light = np.zeros((m.height, m.width, 3), np.uint8)
        character_px: list = []
        desc = None
        if track.T_cam_from_board is not None:
            frame = int(round(max(t, 0.0) * self.fps))
            T_proj_from_scene = projector_from_scene(track.T_cam_from_board, self.rig.T_proj_from_cam, self.board)
            desc = self.describe(T_proj_from_scene, frame)
            if self.draw is not None:
                light = self._draw(desc)
            for hips in self._hips_tracks:
                f = int(np.clip(frame, 0, len(hips) - 1))
                px = project_points(hips[f][None], T_proj_from_scene, m.K, np.zeros(5))[0]
                character_px.append((float(px[0]), float(px[1])))
        if self.draw is None and desc is not None:  # the caller draws it, and gives the light back
            light = None
        else:
            self.take_light(light)
        if view == "camera":
            rgb = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2RGB)
        else:
            rgb = light
        return StageFrame(rgb, light, track.state, view, character_px, list(self.problems), self.live,
                          scene.id, float(t), desc, None if light is not None else self.take_light)

    def describe(self, T_proj_from_scene: np.ndarray, frame: int) -> SceneDescription:
        """What the projector shows at animation ``frame`` from ``T_proj_from_scene``: every
        character on stage at its part poses, through the light model's intrinsics."""
        m = self.light_model
        desc = SceneDescription(View(m.width, m.height, m.K, T_proj_from_scene))
        for design, poses in self._cast:
            add_character(desc, design, poses[int(np.clip(frame, 0, len(poses) - 1))])
        return desc

    def _draw(self, desc: SceneDescription) -> np.ndarray:
        if callable(self.draw):
            return self.draw(desc)
        if self._pyrender is None:
            from ar.render import PyrenderSceneRenderer  # optional: pyrender (absent on Android, where draw=None)
            self._pyrender = PyrenderSceneRenderer()
        return self._pyrender.render(desc)

    def take_light(self, light: np.ndarray) -> None:
        """The light image just shown (RGB, any size): the synthetic rig films it on the
        table in its next camera frame. Safe to call from another thread."""
        light = np.asarray(light)
        self._prev_light = light if light.shape[:2] == RIG_SIZE[::-1] else cv2.resize(light, RIG_SIZE)

    def close(self) -> None:
        try:
            if self._pyrender is not None:
                self._pyrender.close()
                self._pyrender = None
        finally:
            self.rig.close()


__all__ = ["StageError", "StageFrame", "SyntheticRig", "LiveRig", "open_rig", "StageRenderer",
           "STAGE_CHARACTER_HEIGHT_M", "RIG_SIZE", "VIEWS"]
