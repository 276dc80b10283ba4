"""The rig: one frame loop -- camera frame in, tracked board and projector pose out.

:class:`RigTracker` owns the chain every caller runs (the projector stage, ``storybeam
demo``, ``storybeam bench ar``, ``storybeam stress --only tracking`` and the live
tracker's thread, :class:`ar.live.LiveTracker`); :meth:`RigTracker.step` is it:

1. **region detection** (:class:`ar.pose.RegionPoseEstimator`): the board is searched in
   the region the last pose predicts (shrunk when the markers are large), the whole
   frame when that fails or no pose is recent;
2. **the rig's own light left out**: when the caller says what the projector showed
   (:class:`ProjectedLight`), the detected corners that light fell on are dropped before
   the pose is solved -- projected light on the printed board moves the refined corners
   (a bright character over a black square shifts it by a pixel or more), which raises
   the fit's reprojection error and sinks the pose's confidence under the tracker's
   threshold. Corners are kept all when fewer than :data:`ar.pose.MIN_POINTS` would be left;
3. **board pose** (IPPE + Levenberg-Marquardt, :func:`ar.pose.solve_board_pose`);
   when the detector found nothing, the pose is **followed**: the corners of the last detection are followed into
   this frame by pyramidal Lucas-Kanade and posed by solvePnP (:class:`ar.corner_flow.CornerFlow`,
   re-anchored by every detection, refused when its points drift or the pose jumps), and
   the region search goes on from that pose. The whole-frame search and the detector's
   rescue pass for dim, small and blurred boards (:meth:`ar.boards.Board.detect_enhanced`)
   run when nothing is being followed, when following fails, and on every
   :data:`RESCUE_EVERY`-th followed frame (a find re-anchors the follower). :attr:`RigState.found_by` says which:
   ``detected``, ``followed`` or ``lost``;
4. **filter and tracking state** (:class:`ar.filtering.PoseTracker`: Kalman filter,
   tracking / holding / lost), driven by the *frame's* timestamp, never the wall clock;
5. **projector pose**: ``T_proj_from_board = T_proj_from_cam @ T_cam_from_board`` of the
   filtered (or held) pose.

The rigs that feed it frames:

* :class:`SyntheticRig` -- no rig attached: the synthetic camera and projector of
  :mod:`ar.synthetic` held over the board by a synthetic hand; frame ``i`` is taken at
  ``i / fps`` seconds, so what it tracks depends on frame numbers only, not on how
  busy the machine is;
* :class:`LiveRig` -- a camera source and the calibration files; tracking runs on
  :class:`ar.live.LiveTracker`'s threads (newest frame wins) and :meth:`LiveRig.step`
  returns the newest result at once.

Both answer ``step(light) -> RigState`` with the camera image in :attr:`RigState.image`;
:func:`open_rig` picks one.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ar.boards import DEFAULT_BOARD_SPEC, Board, BoardDetection
from ar.calibration import CameraCalibration, ProjectorCalibration
from ar.camera_sources import CameraSource, open_camera_source
from ar.corner_flow import CornerFlow, FlowParams
from ar.errors import RigError
from ar.filtering import PoseTracker, TrackerOutput
from ar.geometry import project_points, scale_intrinsics
from ar.live import LiveStats, LiveTracker
from ar.pose import MIN_POINTS, PoseEstimate, RegionPoseEstimator
from ar.synthetic import (PinholeModel, SyntheticCamera, TrajectoryConfig, default_camera, default_projector,
                          handheld_trajectory)
from retrieval.errors import StoryBeamError

log = logging.getLogger(__name__)

#: the synthetic rig's camera and projector size (the rig tracks at this size whatever the output size)
RIG_SIZE = (640, 480)
#: a projector pixel brighter than this (0..255, brightest channel) is lit
LIT_THRESHOLD = 20
#: a corner is left out when light fell within this many squares of it on the board: a
#: corner is found from the squares and markers around it (ChArUco corners are placed from
#: the neighbouring markers, then refined on the square edges), so light anywhere on that
#: neighbourhood can move it -- by several pixels (measured on the synthetic rig, light
#: 8 mm from a corner of a 40 mm square moved it by 8 px); half a square also covers the
#: hand's motion between the frame the light was drawn for and the frame that films it
LIT_RADIUS_SQUARES = 0.5
#: while the board's corners are followed, the detector's rescue pass runs on every this-many-th
#: frame (and whenever following fails): following costs a few ms, the rescue pass several times that
RESCUE_EVERY = 4


@dataclass
class ProjectedLight:
    """What the rig's projector showed: ``image`` (RGB or grey, any size), drawn through
    ``model``'s pinhole ``K`` (the light's intrinsics at the size it was drawn, scaled here
    when the image came back at another size; the renderers draw without lens distortion)
    from ``T_proj_from_board`` (``None``: drawn from no pose, nothing to leave out)."""

    image: np.ndarray
    model: PinholeModel
    T_proj_from_board: np.ndarray | None

    def lit(self, points_board: np.ndarray, radius_m: float) -> np.ndarray:
        """(N,) bool: which board points (z = 0) the light fell near. Method: the square of
        side ``2 radius_m`` around each point is projected into the light image through
        the pose it was drawn from; a point is lit when a pixel of that square's bounding
        box is brighter than :data:`LIT_THRESHOLD`."""
        points = np.asarray(points_board, np.float64).reshape(-1, 3)
        out = np.zeros(len(points), bool)
        if self.T_proj_from_board is None or not len(points):
            return out
        img = np.asarray(self.image)
        h, w = img.shape[:2]
        K = scale_intrinsics(self.model.K, w / self.model.width, h / self.model.height)
        offsets = radius_m * np.array([[0, 0, 0], [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
        around = (points[:, None, :] + offsets[None]).reshape(-1, 3)
        in_front = (around @ self.T_proj_from_board[:3, :3].T + self.T_proj_from_board[:3, 3])[:, 2] > 0
        px = project_points(around, self.T_proj_from_board, K).reshape(len(points), -1, 2)
        ok = in_front.reshape(len(points), -1).all(1) & np.isfinite(px).all((1, 2))
        for k in np.flatnonzero(ok):
            x0, y0 = np.maximum(np.floor(px[k].min(0)).astype(int), 0)
            x1, y1 = np.ceil(px[k].max(0)).astype(int) + 1
            window = img[y0:max(y0, min(h, y1)), x0:max(x0, min(w, x1))]
            out[k] = window.size > 0 and int(window.max()) > LIT_THRESHOLD
        return out


@dataclass
class RigState:
    """One tracked frame: which one, what the tracker said, where the projector is.

    ``output``: the tracker's answer (state, filtered or held ``T_cam_from_board``,
    confidence, the raw estimate); ``T_proj_from_board``: the projector's pose from that
    pose (None while no pose is known); ``search``: the detector's path this frame
    (``region``, ``full``, ``fallback``, ``lost``); ``lit_points``: corners left out
    under the rig's own light; ``detect_pose_ms``: the step's time (detection, pose,
    filter); ``latency_ms``: from the frame's arrival to the result (live rigs);
    ``image``: the camera frame (BGR) when the rig keeps it; ``found_by``: how this frame's
    estimate was found -- ``detected`` (the detector), ``followed`` (corners followed from
    the last detection, :mod:`ar.corner_flow`) or ``lost`` (neither: the tracker holds or
    has lost the pose)."""

    frame_index: int
    timestamp_s: float
    output: TrackerOutput
    T_proj_from_board: np.ndarray | None
    search: str
    lit_points: int = 0
    detect_pose_ms: float = 0.0
    latency_ms: float = 0.0
    image: np.ndarray | None = None
    found_by: str = "lost"

    @property
    def state(self) -> str:
        """``ar.TRACKING``, ``HOLDING`` or ``LOST``."""
        return self.output.state

    @property
    def T_cam_from_board(self) -> np.ndarray | None:
        """The filtered (or held) board pose."""
        return self.output.T_cam_from_board

    @property
    def estimate(self) -> PoseEstimate | None:
        """This frame's unfiltered estimate (None = board not found)."""
        return self.output.raw

    @property
    def confidence(self) -> float:
        return self.output.confidence


class RigTracker:
    """The frame loop: region detection -> board pose -> filter -> projector pose (module docstring).

    Keeps state between frames (the detector's region, the filter): feed one camera's
    frames in order, from one thread at a time."""

    def __init__(self, board: Board, K: np.ndarray, dist: np.ndarray, T_proj_from_cam: np.ndarray | None = None,
                 estimator: RegionPoseEstimator | None = None, tracker: PoseTracker | None = None,
                 lit_radius_squares: float = LIT_RADIUS_SQUARES, flow: FlowParams | None | bool = None,
                 rescue: bool = True):
        """``T_proj_from_cam``: the rig's extrinsics (None: no projector pose);
        ``estimator`` / ``tracker``: the detector and the filter (defaults: the product's);
        ``lit_radius_squares``: how near a corner light may fall (:data:`LIT_RADIUS_SQUARES`);
        ``flow``: the corner follower's settings (None: the defaults; False: detection only);
        ``rescue``: the default detector's rescue pass for dim, small and blurred boards."""
        self.board = board
        self.lit_radius_m = lit_radius_squares * board.spec.square_m
        self.T_proj_from_cam = None if T_proj_from_cam is None else np.asarray(T_proj_from_cam, np.float64)
        self.estimator = estimator or RegionPoseEstimator(board, K, dist, rescue=rescue)
        self.tracker = tracker or PoseTracker()
        self.flow = None if flow is False else CornerFlow(board, K, dist, flow if isinstance(flow, FlowParams) else None)
        self.found_counts = {"detected": 0, "followed": 0, "lost": 0}
        self._next_index = 0

    @property
    def counts(self) -> dict:
        """Frames per detector path since start (``region``, ``full``, ``fallback``, ``lost``)."""
        return self.estimator.counts

    def step(self, image: np.ndarray, timestamp_s: float, frame_index: int | None = None,
             light: ProjectedLight | None = None) -> RigState:
        """Track one camera frame (grey or BGR) taken at ``timestamp_s`` (the frame's own time:
        the tracker's hold and filter run on it). ``light``: what the projector showed while
        the frame was taken (its lit corners are left out). ``frame_index``: default, the
        count of frames stepped so far."""
        index = self._next_index if frame_index is None else int(frame_index)
        self._next_index = index + 1
        dropped = [0]

        def unlit(detection: BoardDetection) -> BoardDetection:
            keep = ~light.lit(detection.object_points, self.lit_radius_m)
            if keep.all() or keep.sum() < MIN_POINTS:
                return detection
            dropped[0] = int((~keep).sum())
            return BoardDetection(detection.object_points[keep], detection.image_points[keep],
                                  detection.ids[keep], detection.total_points)

        t0 = time.perf_counter()
        select = unlit if light is not None else None
        # while the corners can be followed, the whole-frame search and the (costly) rescue pass wait
        # for following to fail, except on every RESCUE_EVERY-th followed frame (a find re-anchors)
        defer = (self.flow is not None and self.flow.active
                 and self.flow.frames_followed % RESCUE_EVERY != RESCUE_EVERY - 1)
        estimate = (self.estimator.estimate(image, select, rescue=False, whole=False) if defer
                    else self.estimator.estimate(image, select))
        found_by = "detected" if estimate is not None else "lost"
        if self.flow is not None:
            gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
            if estimate is None:
                estimate = self.flow.follow(gray)
                if estimate is not None:
                    found_by = "followed"
                    self.estimator.observe(estimate.T_cam_from_board)
                elif defer:
                    estimate = self.estimator.retry(image, select)
                    found_by = "detected" if estimate is not None else "lost"
            if found_by == "detected":
                self.flow.anchor(gray, estimate)
            elif found_by == "lost":
                self.flow.reset()  # no motion is carried across a gap
        self.found_counts[found_by] += 1
        output = self.tracker.update(estimate, timestamp_s)
        T_proj = (self.T_proj_from_cam @ output.T_cam_from_board
                  if self.T_proj_from_cam is not None and output.T_cam_from_board is not None else None)
        ms = (time.perf_counter() - t0) * 1000
        return RigState(index, float(timestamp_s), output, T_proj, self.estimator.last_path,
                        dropped[0] if found_by == "detected" else 0, ms, found_by=found_by)


# ---------------------------------------------------------------------------- rigs
class SyntheticRig:
    """No rig attached: the bench camera and projector (:mod:`ar.synthetic`) held over the
    board by a synthetic hand, so the whole chain (detection, filter, projector render,
    light on the table) runs and can be previewed and exported. Frame ``i`` is taken at
    ``i / fps`` s; the hand's path ping-pongs every ``loop_s`` seconds."""

    live = False

    def __init__(self, board: Board | None = None, fps: float = 30.0, seed: int = 0, loop_s: float = 60.0,
                 size: tuple[int, int] = RIG_SIZE):
        """``board``: the board the hand holds the rig over (default: the default board)."""
        self.board = board if board is not None else Board(DEFAULT_BOARD_SPEC)
        self.fps = fps
        w, h = size
        self.camera_model = default_camera().scaled(w, h)
        self.projector_model = default_projector().scaled(w, h)
        # a bright projector (as in the demo): the light must read on the paper
        self.cam = SyntheticCamera(self.board, camera=self.camera_model, projector=self.projector_model,
                                   supersample=1, projector_gain=0.9)
        self.T_proj_from_cam = self.cam.proj_from_cam
        self.poses = handheld_trajectory(self.board, int(loop_s * fps),
                                         TrajectoryConfig(fps=fps, seed=seed, distance_m=0.55))
        self.tracker = RigTracker(self.board, self.camera_model.K, self.camera_model.dist, self.T_proj_from_cam)
        self._rng = np.random.default_rng(seed)
        self._dark = np.zeros((h, w, 3), np.uint8)
        self._i = 0

    def true_pose(self, i: int) -> np.ndarray:
        """``T_cam_from_board`` of frame ``i`` (the hand's path, played forth and back)."""
        n = len(self.poses)
        k = i % (2 * n)  # ping-pong: the hand does not jump when the trajectory ends
        return self.poses[k if k < n else 2 * n - 1 - k]

    def capture(self, i: int, light: np.ndarray | None) -> np.ndarray:
        """BGR camera frame number ``i`` with ``light`` (RGB, resized to the projector's size) on the table."""
        p = self.projector_model
        if light is None:
            light = self._dark
        elif light.shape[:2] != (p.height, p.width):
            light = cv2.resize(light, (p.width, p.height))
        return self.cam.render(self.true_pose(i), projector_image=light, rng=self._rng)

    def step(self, light: ProjectedLight | None = None) -> RigState:
        """The next camera frame, with ``light`` (what the projector showed last) on the table, tracked."""
        i = self._i
        self._i += 1
        frame = self.capture(i, None if light is None else light.image)
        state = self.tracker.step(frame, i / self.fps, i, light)
        state.image = frame
        return state

    def close(self) -> None:
        pass


class LiveRig:
    """A real rig: a camera source (:mod:`ar.camera_sources`: a device number, a video
    file, a folder of images -- a recording stands in for the camera, looped and paced at
    its frame rate) and the calibration files (``camera.json`` from the calibration
    wizard, ``projector.json`` from ``storybeam calibrate projector``).

    Tracking runs on the rig's own threads (:class:`ar.live.LiveTracker`: the newest
    frame wins, dropped frames are counted): :meth:`step` returns at once with the
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
        rig = RigTracker(self.board, self.camera_model.K, self.camera_model.dist, self.T_proj_from_cam)
        self.tracker = LiveTracker(source, rig, keep_images=True).start()

    def step(self, light: ProjectedLight | None = None) -> RigState:
        """The newest tracked frame (its BGR image in ``image``); waits only for the very
        first. ``light``: what the projector shows now (the tracker leaves out the corners
        it falls on from the next frame). Raises :class:`ar.errors.RigError` when the camera stopped."""
        self.tracker.light = light
        deadline = time.monotonic() + self.first_frame_timeout_s
        while (result := self.tracker.latest()) is None:
            stats = self.tracker.stats()
            if stats.error or not stats.running or time.monotonic() > deadline:
                raise RigError(f"camera {self.source_name}: {stats.error or 'no frame arrived'}")
            time.sleep(0.005)
        stats = self.tracker.stats()
        if stats.error:
            raise RigError(stats.error)
        return result

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
             camera: int | str | CameraSource | None = 0) -> LiveRig | SyntheticRig:
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


__all__ = ["RIG_SIZE", "LIT_THRESHOLD", "LIT_RADIUS_SQUARES", "RESCUE_EVERY", "ProjectedLight", "RigState", "RigTracker", "SyntheticRig",
           "LiveRig", "open_rig"]
