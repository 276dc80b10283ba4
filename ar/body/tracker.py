"""Body pose from camera frames: StoryBeam's loop around the two BlazePose models.

Per frame (:meth:`BodyTracker.process`), as MediaPipe's ``pose_landmark_cpu`` graph with
``model_complexity=1`` (the "full" landmark model):

1. **Region.** When the previous frame gave a pose, its smoothed auxiliary landmarks
   place this frame's region (tracking). Otherwise the detector runs: the frame
   letterboxed to 224×224 (RGB in [−1, 1]), 2254 SSD anchors decoded, scores above 0.5,
   weighted non-maximum suppression, the best detection, letterbox removed; its mid-hip
   keypoint is the region's centre, twice its distance to the full-body keypoint the side,
   the direction between them its rotation. Both ways: a square 1.25 times that side.
   StoryBeam adds (``search=True``, :mod:`ar.body.acquire`): a look where the followed
   body was, a sweep of tiles at finer scales when the whole frame shows nobody, and a
   rule for whom to follow among several (the most central and largest, kept across
   losses).
2. **Landmarks.** The rotated region cropped to 256×256 (RGB in [0, 1], edge pixels
   replicated), the landmark model run: 39 landmarks (x, y, z, visibility, presence), a
   pose flag, a 64×64 heatmap per landmark (x, y refined from it), world landmarks.
   A flag of 0.5 or less: the body is lost. MediaPipe then reports no pose for the frame
   and detects again on the next one; StoryBeam (``redetect=True``, the default) detects
   again *in the same frame* and runs the landmark model once more on the fresh region,
   so a frame where tracking slips is not a missing frame: on 93 renders of the cartoon
   kid, 80 losses cost 191 frames, 48 of them one frame each (docs/notebook/pose.md).
3. **Back to the frame.** Landmarks rotated and scaled out of the crop into the frame;
   world landmarks rotated by the region's angle; the first 33 kept, landmarks 33 and 34
   (auxiliary) kept for the next region.
4. **Smoothing** (``smooth=True``): :mod:`ar.body.smoothing`, keyed by the frames'
   timestamps.

Outputs follow MediaPipe's conventions: image landmarks in pixels of the input frame
(x right, y down; z is MediaPipe's relative depth, in pixels as x, smaller = nearer the
camera, the hips' midpoint near 0); world landmarks in metres with the origin at the
hips' midpoint, x to the image's right, y down, z away from the camera.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from ar.body import acquire as acq
from ar.body import blazepose as bp
from ar.body.models import load_model
from ar.body.smoothing import AUXILIARY, LANDMARKS, WORLD, LandmarkSmoother, OneEuroFilter
from ar.camera_sources import CameraSource
from retrieval.errors import StoryBeamError
from retrieval.motion import LANDMARK_NAMES  # BlazePose's 33 landmarks, in the models' order

#: Default tile runs per frame while the sweep looks for a body (``BodyTracker(tiles_per_frame=...)``).
TILES_PER_FRAME = 4
#: For this long (seconds) after the followed body was last seen, only a body continuing
#: it is taken (someone passing in front of it, or hiding it, is not followed instead) ...
HOLD_S = 0.5
#: ... and until this long after, such a body is preferred to the others.
REMEMBER_S = 2.0
#: Candidates tried per detection frame until the landmark model confirms one.
MAX_CANDIDATES = 3

_DETECTOR_OUTPUTS = {"boxes": (1, bp.NUM_ANCHORS, 4 + 2 * bp.NUM_KEYPOINTS), "scores": (1, bp.NUM_ANCHORS, 1)}
_LANDMARK_OUTPUTS = {
    "landmarks": (1, bp.NUM_MODEL_LANDMARKS * 5),
    "flag": (1, 1),
    "heatmap": (1, 64, 64, bp.NUM_MODEL_LANDMARKS),
    "world": (1, bp.NUM_MODEL_LANDMARKS * 3),
}


@dataclass(frozen=True)
class BodyPose:
    """One frame's body: BlazePose's 33 landmarks (:data:`LANDMARK_NAMES`)."""

    image_xy: np.ndarray  #: (33, 2) float32 pixels of the input frame, x right, y down
    image_z: np.ndarray  #: (33,) float32 MediaPipe's relative depth, pixels (as x); smaller = nearer
    visibility: np.ndarray  #: (33,) float32 in [0, 1]: likely visible (not occluded)
    presence: np.ndarray  #: (33,) float32 in [0, 1]: likely inside the frame
    world: np.ndarray  #: (33, 3) float32 metres, origin mid-hips, x image-right, y down, z away from the camera
    score: float  #: the landmark model's pose flag (> 0.5 for a pose to be reported)


@dataclass
class FrameTiming:
    """Milliseconds spent on the last frame: detector (0 when tracked; every detector run,
    tiles included), landmark model (crop + inference + decoding), total (with smoothing);
    whether the detector ran, and how many of its runs were on tiles (the extra pass)."""

    detector_ms: float = 0.0
    landmarks_ms: float = 0.0
    total_ms: float = 0.0
    detected: bool = False
    tiles: int = 0


class BodyTracker:
    """Tracks one body through a stream of frames (see the module docstring).

    ``smooth``: MediaPipe's temporal filters (video); ``track=False`` runs the detector on
    every frame and never smooths (MediaPipe's ``static_image_mode``); ``redetect``: when
    tracking loses the body, detect again in the same frame (``False``: MediaPipe's
    graph, which waits for the next frame). ``num_threads``:
    the interpreter's threads (1 = one core). Raises :class:`ar.body.PoseModelError` when
    a model file is missing or altered, or no TFLite interpreter is installed.

    Finding a body (:mod:`ar.body.acquire`, issue 27): ``search`` (default on) adds the
    tile pass when the whole-frame detector finds nobody, down to bodies of ``min_body``
    × the frame height; ``tiles_per_frame`` bounds the tile runs per frame (a sweep then
    continues on the next frame; ``None``, the first sweep after :meth:`reset`, or
    without tracking: every tile at once). Candidates are ranked by
    :func:`ar.body.acquire.rank`. After a loss, the followed body's last place is looked
    at first (a tile around it) and only a body continuing it is taken for ``hold_s``
    seconds; until ``remember_s`` such a body is preferred; after that, whoever ranks
    first. Up to :data:`MAX_CANDIDATES` candidates are tried, best first, until the
    landmark model confirms one.
    """

    def __init__(self, model_dir: Path | None = None, smooth: bool = True, num_threads: int = 1, *,
                 track: bool = True, redetect: bool = True, search: bool = True, min_body: float = acq.MIN_BODY,
                 tiles_per_frame: int | None = TILES_PER_FRAME, hold_s: float = HOLD_S,
                 remember_s: float = REMEMBER_S):
        if not 0.0 < min_body <= 1.0:
            raise StoryBeamError(f"body tracker: min_body must be in (0, 1], got {min_body}")
        if tiles_per_frame is not None and tiles_per_frame < 1:
            raise StoryBeamError(f"body tracker: tiles_per_frame must be at least 1 (or None), got {tiles_per_frame}")
        self.smooth = bool(smooth) and bool(track)
        self.track = bool(track)
        self.redetect = bool(redetect)
        self.search = bool(search)
        self.min_body = float(min_body)
        self.tiles_per_frame = tiles_per_frame
        self.hold_s = float(hold_s)
        self.remember_s = float(remember_s)
        self._tiles: dict[tuple[int, int], list[acq.Tile]] = {}
        self.detector = load_model("detector", _DETECTOR_OUTPUTS, model_dir, num_threads)
        self.landmarker = load_model("landmarks", _LANDMARK_OUTPUTS, model_dir, num_threads)
        self.anchors = bp.ssd_anchors()
        self.timing = FrameTiming()
        self._landmark_filter = LandmarkSmoother(LANDMARKS)
        self._aux_filter = LandmarkSmoother(AUXILIARY)
        self._world_filter = OneEuroFilter(WORLD)
        self.reset()

    def reset(self) -> None:
        """Forget the tracked body, whom it was following and the filters' history (the
        next frame detects, as in a fresh tracker)."""
        self._drop_track()
        self._last_roi: bp.Rect | None = None  # the followed body's last region ...
        self._last_t = -math.inf  # ... and when it was seen
        self._sweep: list[acq.Tile] = []
        self._cursor = 0
        self._swept = False  # a sweep has run since the reset (the first one runs every tile)

    def _drop_track(self) -> None:
        """The track is lost: no region for the next frame, the filters' history cleared
        (whom it followed is kept, for re-acquisition)."""
        self._roi: bp.Rect | None = None
        self._landmark_filter.reset()
        self._aux_filter.reset()
        self._world_filter.reset()

    # ------------------------------------------------------------------ stages
    def detect(self, frame_bgr: np.ndarray, tile: acq.Tile | None = None) -> list[bp.Detection]:
        """Every detection in the frame, or in one ``tile`` of it, normalised to the whole
        frame, best first."""
        h, w = frame_bgr.shape[:2]
        if tile is None:
            matrix, padding = bp.letterbox_transform((w, h))
        else:
            matrix, padding = bp.rect_transform(tile.rect((w, h)), (w, h), bp.DETECTOR_SIZE)
        x = bp.warp_to_tensor(frame_bgr, matrix, bp.DETECTOR_SIZE, (-1.0, 1.0), cv2.BORDER_CONSTANT)
        boxes, scores = self.detector.run(x, ("boxes", "scores"))
        found = [bp.remove_letterbox(d, padding) for d in bp.weighted_nms(bp.decode_detections(boxes[0], scores[0], self.anchors))]
        return found if tile is None else [tile.to_frame(d, (w, h)) for d in found]

    def tiles(self, image_size: tuple[int, int]) -> list[acq.Tile]:
        """The extra pass's tiles for frames of ``image_size`` (:func:`ar.body.acquire.tile_grid`)."""
        if image_size not in self._tiles:
            self._tiles[image_size] = acq.tile_grid(image_size, self.min_body)
        return self._tiles[image_size]

    def _acquire(self, frame_bgr: np.ndarray, timestamp_s: float, timing: FrameTiming
                 ) -> tuple[bp.Rect, float, np.ndarray, np.ndarray] | None:
        """Find the body to follow in this frame (the :class:`BodyTracker` docstring, in
        order: the whole frame, a look where the followed body was, the tile sweep), and
        confirm it with the landmark model: (region, flag, landmarks, world), or ``None``."""
        h, w = frame_bgr.shape[:2]
        size = (w, h)
        since = timestamp_s - self._last_t
        last = self._last_roi if self.track and self._last_roi is not None and since <= self.remember_s else None
        hold = last is not None and since <= self.hold_s

        def continues(roi: bp.Rect) -> bool:
            return last is not None and acq.match_distance(roi, last, size, since) is not None

        t1 = time.perf_counter()
        found = self.detect(frame_bgr)
        ranked = acq.rank(found, size, last, since)
        if self.search and last is not None and not (ranked and continues(ranked[0][1])):
            # before following someone else, look where the followed body was, at its scale
            finest = min(t.side for t in self.tiles(size)) if self.tiles(size) else min(w, h)
            local = self.detect(frame_bgr, acq.tile_around(last, size, finest))
            timing.tiles += 1
            ranked = acq.rank(found + acq.new_detections(local, found), size, last, since)
        timing.detector_ms += (time.perf_counter() - t1) * 1e3
        tiles = self.tiles(size)
        whole = self.tiles_per_frame is None or not self.track or not self._swept
        budget = len(tiles) if whole else int(self.tiles_per_frame)
        while True:
            if hold:  # the followed body hidden or gone for a moment: nobody else is taken
                ranked = [c for c in ranked if continues(c[1])]
            for _det, roi in ranked[:MAX_CANDIDATES]:
                t1 = time.perf_counter()
                flag, lm, world = self.landmarks_in(frame_bgr, roi)
                timing.landmarks_ms += (time.perf_counter() - t1) * 1e3
                if flag > bp.POSE_PRESENCE_THRESHOLD:
                    self._cursor = 0  # the next sweep starts afresh
                    return roi, flag, lm, world
            if not (self.search and tiles and budget > 0):
                return None
            t1 = time.perf_counter()
            ranked, budget = self._sweep_tiles(frame_bgr, last, since, budget, timing)
            timing.detector_ms += (time.perf_counter() - t1) * 1e3

    def _sweep_tiles(self, frame_bgr: np.ndarray, last: bp.Rect | None, since: float, budget: int,
                     timing: FrameTiming) -> tuple[list[tuple[bp.Detection, bp.Rect]], int]:
        """Run the detector on the sweep's next tiles, at most ``budget``, up to the first
        tile with a detection: its candidates, ranked, and the budget left. A new sweep
        (cursor 0) orders the tiles coarse level first, nearest the followed body (else
        the frame centre) first; a finished one starts again on the next call."""
        h, w = frame_bgr.shape[:2]
        tiles = self.tiles((w, h))
        if self._cursor == 0 or len(self._sweep) != len(tiles):
            focus = (last.x_center * w, last.y_center * h) if last is not None else (w / 2.0, h / 2.0)
            self._sweep, self._cursor = acq.order_tiles(tiles, focus), 0
        found: list[bp.Detection] = []
        while budget > 0 and not found:
            found = self.detect(frame_bgr, self._sweep[self._cursor])
            self._cursor = (self._cursor + 1) % len(self._sweep)
            budget -= 1
            timing.tiles += 1
        self._swept = True
        return acq.rank(bp.weighted_nms(found), (w, h), last, since), budget

    def landmarks_in(self, frame_bgr: np.ndarray, roi: bp.Rect) -> tuple[float, np.ndarray, np.ndarray]:
        """Run the landmark model on ``roi``: (pose flag, image landmarks (39, 5) float32
        normalised to the frame: x, y, z (z × W = pixels), visibility, presence; world
        (39, 3) metres)."""
        h, w = frame_bgr.shape[:2]
        matrix, padding = bp.rect_transform(roi, (w, h), bp.LANDMARK_SIZE)
        x = bp.warp_to_tensor(frame_bgr, matrix, bp.LANDMARK_SIZE, (0.0, 1.0), cv2.BORDER_REPLICATE)
        raw, flag, heatmap, world = self.landmarker.run(x, ("landmarks", "flag", "heatmap", "world"))
        lm = bp.refine_from_heatmap(bp.decode_landmarks(raw), heatmap)
        lm = bp.project_landmarks(bp.remove_crop_letterbox(lm, padding), roi)
        world = bp.rotate_world(np.asarray(world, np.float32).reshape(bp.NUM_MODEL_LANDMARKS, 3), roi.rotation)
        return float(np.asarray(flag).reshape(-1)[0]), lm, world

    # ------------------------------------------------------------------ the loop
    def process(self, frame_bgr: np.ndarray, timestamp_s: float) -> BodyPose | None:
        """The body in one BGR frame (uint8 (H, W, 3)), or ``None`` when none is found.
        ``timestamp_s``: the frame's time (seconds, increasing), for the smoothing."""
        frame_bgr = _check_frame(frame_bgr)
        t0 = time.perf_counter()
        h, w = frame_bgr.shape[:2]
        timing = FrameTiming()
        roi = self._roi if self.track else None
        flag = 0.0
        if roi is not None:  # tracked from the previous frame
            t1 = time.perf_counter()
            flag, lm, world = self.landmarks_in(frame_bgr, roi)
            timing.landmarks_ms = (time.perf_counter() - t1) * 1e3
            if not flag > bp.POSE_PRESENCE_THRESHOLD:
                if not self.redetect:
                    return self._lost(timing, t0)
                self._drop_track()  # the track is lost: its filters' history no longer applies
        if not flag > bp.POSE_PRESENCE_THRESHOLD:
            timing.detected = True
            acquired = self._acquire(frame_bgr, timestamp_s, timing)
            if acquired is None:  # nobody, or no candidate the landmark model confirms
                return self._lost(timing, t0)
            roi, flag, lm, world = acquired
        size = np.array([w, h, w], np.float32)
        px = lm[:, :3] * size  # MediaPipe filters in pixels (x·W, y·H, z·W), float32
        body, aux = px[: bp.NUM_LANDMARKS], px[bp.AUX_SLICE]
        vis = lm[: bp.NUM_LANDMARKS, 3]
        world33 = world[: bp.NUM_LANDMARKS]
        # object scale of the image filters: the square through the raw auxiliary landmarks
        # (AlignmentPointsRects, unscaled): (width·W + height·H) / 2
        sq = bp.alignment_rect(lm[33, :2], lm[34, :2], (w, h))
        object_scale = float((np.float32(sq.width) * np.float32(w) + np.float32(sq.height) * np.float32(h)) / np.float32(2))
        if self.smooth:
            body, vis = self._landmark_filter.apply(body, vis, timestamp_s, object_scale)
            body = body / size * size  # back to normalised (float32) and to pixels, as MediaPipe's output
            world33 = self._world_filter.apply(world33, timestamp_s)
        if self.track:
            aux, _ = self._aux_filter.apply(aux, lm[bp.AUX_SLICE, 3], timestamp_s, object_scale)
            aux_norm = aux / size
            self._roi = bp.roi_from_points(aux_norm[0, :2], aux_norm[1, :2], (w, h))
            self._last_roi, self._last_t = self._roi, timestamp_s
        timing.total_ms = (time.perf_counter() - t0) * 1e3
        self.timing = timing
        return BodyPose(
            image_xy=body[:, :2].astype(np.float32), image_z=body[:, 2].astype(np.float32),
            visibility=np.asarray(vis, np.float32), presence=lm[: bp.NUM_LANDMARKS, 4].astype(np.float32),
            world=np.asarray(world33, np.float32), score=flag,
        )

    def _lost(self, timing: FrameTiming, t0: float) -> None:
        self._drop_track()
        timing.total_ms = (time.perf_counter() - t0) * 1e3
        self.timing = timing
        return None


def _check_frame(frame: np.ndarray) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8 or min(frame.shape[:2]) < 2:
        raise StoryBeamError(f"body tracker: expected a BGR uint8 frame (H, W, 3), got {frame.dtype} {frame.shape}")
    return frame


@dataclass
class BodyTake:
    """The poses of one take (``None`` where no body was found), at ``fps``, from frames
    of ``image_size`` (W, H), with each frame's processing time (``pose_ms``)."""

    poses: list[BodyPose | None]
    fps: float
    image_size: tuple[int, int]
    pose_ms: list[float] = field(default_factory=list)

    @property
    def detect_rate(self) -> float:
        """Fraction of frames with a pose (0 for an empty take)."""
        return sum(p is not None for p in self.poses) / len(self.poses) if self.poses else 0.0

    @property
    def pose_ms_median(self) -> float:
        return float(np.median(self.pose_ms)) if self.pose_ms else float("nan")

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(world (T, 33, 3) NaN where missing, image_xy (T, 33, 2) NaN where missing,
        visibility (T, 33) 0 where missing, valid (T,) bool)."""
        t = len(self.poses)
        world = np.full((t, bp.NUM_LANDMARKS, 3), np.nan, np.float32)
        xy = np.full((t, bp.NUM_LANDMARKS, 2), np.nan, np.float32)
        vis = np.zeros((t, bp.NUM_LANDMARKS), np.float32)
        valid = np.zeros(t, bool)
        for k, p in enumerate(self.poses):
            if p is not None:
                world[k], xy[k], vis[k], valid[k] = p.world, p.image_xy, p.visibility, True
        return world, xy, vis, valid


def track_frames(frames: Iterable[np.ndarray] | CameraSource, fps: float | None = None,
                 tracker: BodyTracker | None = None, max_frames: int | None = None,
                 on_frame: Callable[[int, np.ndarray, BodyPose | None], None] | None = None) -> BodyTake:
    """Track a body through ``frames`` (BGR arrays, or a camera source read to its end or
    ``max_frames``). Timestamps: the source's own, else ``k / fps`` (``fps`` default: the
    source's, else 30). A fresh :class:`BodyTracker` (smoothing on) unless one is given
    (it is reset first). ``on_frame(k, frame, pose)`` is called after each frame."""
    tracker = tracker if tracker is not None else BodyTracker()
    tracker.reset()
    limit = max_frames if max_frames is not None else -1
    if isinstance(frames, CameraSource):
        source = frames
        rate = fps or source.fps

        def stream():
            k = 0
            while k != limit:
                f = source.read()
                if f is None:
                    return
                yield f.image, f.timestamp_s
                k += 1
    else:
        rate = fps

        def stream():
            for k, image in enumerate(frames):
                if k == limit:
                    return
                yield image, k / (fps or 30.0)
    poses: list[BodyPose | None] = []
    ms: list[float] = []
    stamps: list[float] = []
    size = (0, 0)
    for k, (image, stamp) in enumerate(stream()):
        t0 = time.perf_counter()
        pose = tracker.process(image, stamp)
        ms.append((time.perf_counter() - t0) * 1e3)
        poses.append(pose)
        stamps.append(stamp)
        size = (int(image.shape[1]), int(image.shape[0]))
        if on_frame is not None:
            on_frame(k, image, pose)
    if not rate:
        steps = np.diff(stamps)
        rate = 1.0 / float(np.median(steps)) if len(steps) and np.median(steps) > 0 else 30.0
    return BodyTake(poses, float(rate), size, ms)


__all__ = ["LANDMARK_NAMES", "BodyPose", "FrameTiming", "BodyTracker", "BodyTake", "track_frames"]
