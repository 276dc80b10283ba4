"""The story on the table: every character of a scene rendered from the projector's
viewpoint through the tracked rig, for the projector screen and the MP4 export.

Per frame (the same loop as ``storybeam demo``, see :mod:`app.scene.demo_pipeline`):

1. the rig's camera sees the board (and the light the projector showed last frame, as on
   a real rig: one frame of latency) -- a live camera with calibration files, or with no
   rig attached the synthetic rig of :mod:`ar.synthetic` held by a synthetic hand
   (:func:`ar.synthetic.handheld_trajectory`);
2. the board is detected and its pose filtered (:func:`ar.pose.estimate_board_pose`,
   :class:`ar.filtering.PoseTracker`: tracking / holding / lost);
3. the characters, posed at story time ``t``, are rendered through the projector from the
   tracked pose (:class:`ar.render.projector_view.ProjectorRenderer`): black = no light;
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

Imports :mod:`ar.render` (pyrender): import this module only where 3-D is wanted.
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
from ar.render import CharacterRig, ProjectorRenderer, projector_from_scene, scaled_model
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
    """A real rig: OpenCV camera ``camera_index`` and the profile's calibration files
    (``camera.json`` from the calibration wizard, ``projector.json`` from
    ``storybeam calibrate projector``)."""

    live = True

    def __init__(self, camera_index: int, camera_json: Path, projector_json: Path):
        cam = CameraCalibration.load(camera_json)
        proj = ProjectorCalibration.load(projector_json)
        self.camera_model = PinholeModel(cam.camera_matrix, cam.dist_coeffs, *cam.image_size)
        self.projector_model = PinholeModel(proj.camera_matrix, proj.dist_coeffs, *proj.image_size)
        self.T_proj_from_cam = proj.T_proj_from_cam
        self._cap = cv2.VideoCapture(camera_index)
        if not self._cap.isOpened():
            raise StageError(f"camera {camera_index} cannot be opened")

    def capture(self, i: int, light: np.ndarray) -> np.ndarray:
        ok, frame = self._cap.read()
        if not ok or frame is None:
            raise StageError("the rig's camera stopped sending frames")
        return frame

    def close(self) -> None:
        self._cap.release()


def open_rig(profile_dir: Path | None, board: Board, fps: float = 30.0, camera_index: int = 0):
    """A :class:`LiveRig` when the profile has both calibration files and the camera opens,
    else the :class:`SyntheticRig` (preview mode). Never raises for a missing rig."""
    if profile_dir is not None:
        camera_json, projector_json = Path(profile_dir) / "camera.json", Path(profile_dir) / "projector.json"
        if camera_json.is_file() and projector_json.is_file():
            try:
                return LiveRig(camera_index, camera_json, projector_json)
            except (StoryBeamError, OSError) as exc:
                log.warning("rig not usable, projector preview uses the synthetic rig: %s", exc)
    return SyntheticRig(board, fps=fps)


# ---------------------------------------------------------------------------- renderer
class StageRenderer:
    """``render(scene, t, view) -> StageFrame``: one rig frame per call (the hand moves on
    in real time), the scene's characters posed at story time ``t``.

    Prepared scenes are cached by content (preparing = retargeting and laying each
    character's clip on its path, about a second per character)."""

    def __init__(self, rig=None, profile_dir: Path | None = None, fps: float = 30.0,
                 motions_dir: Path | None = None, rig_fps: float | None = None):
        """``fps``: the animation's frame rate; ``rig_fps``: how often the rig is sampled
        (one call of :meth:`render` = one rig frame; default ``fps``)."""
        self.board = Board(DEFAULT_BOARD_SPEC)
        self.fps = fps
        self.rig_fps = rig_fps or fps
        self.rig = rig if rig is not None else open_rig(profile_dir, self.board, self.rig_fps)
        model = self.rig.projector_model
        if self.rig.live:  # render the light at the projector's own size (up to 1280 wide)
            k = min(1.0, 1280 / model.width)
            model = scaled_model(model, int(model.width * k), int(model.height * k))
        self.light_model = model
        self.projector = ProjectorRenderer(model.width, model.height, model.K)
        self.tracker = PoseTracker()
        self.animator = SceneAnimator.from_library(motions_dir or MOTIONS_DIR, fps=fps,
                                                   character_height_m=STAGE_CHARACTER_HEIGHT_M,
                                                   placement=STAGE_PLACEMENT)
        self._key: str | None = None
        self._rigs: list = []
        self._names: list[str] = []
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
        for name in self._names:
            self.projector.remove(name)
        self._rigs, self._names, self._hips_tracks, self.problems = [], [], [], []
        for i, character in enumerate(scene.characters):
            if len(character.path) < 2:
                continue
            try:
                design, motion = self.animator.animate(character)
            except (StoryBeamError, ValueError, OSError) as exc:
                self.problems.append(f"{character.kind} {character.id}: {exc}")
                log.warning("projector stage leaves out %s: %s", character.id, exc)
                continue
            rig = CharacterRig(self.projector, design, prefix=f"stage{i}")
            rig.bind(motion)
            self._rigs.append(rig)
            self._names.extend(rig.names)
            self._hips_tracks.append(positions(motion)[:, 0])  # for character_px
        self._key = key

    def render(self, scene: Scene, t: float, view: str = "projector") -> StageFrame:
        if view not in VIEWS:
            raise StageError(f"unknown stage view {view!r}; choose one of {', '.join(VIEWS)}")
        self.prepare(scene)
        i = self._tick
        self._tick += 1
        frame_bgr = self.rig.capture(i, self._prev_light)
        cam = self.rig.camera_model
        estimate = estimate_board_pose(frame_bgr, self.board, cam.K, cam.dist)
        # a live rig is tracked in real time; the synthetic one at its own frame rate
        stamp = time.monotonic() - self._t0 if self.rig.live else i / self.rig_fps
        track = self.tracker.update(estimate, stamp)
        m = self.light_model
        light = np.zeros((m.height, m.width, 3), np.uint8)
        character_px: list = []
        if track.T_cam_from_board is not None:
            self.projector.set_board_pose(track.T_cam_from_board, self.rig.T_proj_from_cam, self.board)
            frame = int(round(max(t, 0.0) * self.fps))
            for rig in self._rigs:
                rig.show_frame(frame)
            light = np.ascontiguousarray(self.projector.render()[..., :3])
            T_proj_from_scene = projector_from_scene(track.T_cam_from_board, self.rig.T_proj_from_cam, self.board)
            for hips in self._hips_tracks:
                f = int(np.clip(frame, 0, len(hips) - 1))
                px = project_points(hips[f][None], T_proj_from_scene, m.K, np.zeros(5))[0]
                character_px.append((float(px[0]), float(px[1])))
        rig_light = light if light.shape[:2] == RIG_SIZE[::-1] else cv2.resize(light, RIG_SIZE)
        self._prev_light = rig_light
        if view == "camera":
            rgb = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2RGB)
        else:
            rgb = light
        return StageFrame(rgb, light, track.state, view, character_px, list(self.problems), self.live,
                          scene.id, float(t))

    def close(self) -> None:
        try:
            self.projector.close()
        finally:
            self.rig.close()


__all__ = ["StageError", "StageFrame", "SyntheticRig", "LiveRig", "open_rig", "StageRenderer",
           "STAGE_CHARACTER_HEIGHT_M", "RIG_SIZE", "VIEWS"]
