""""Act it out": the child performs a movement in front of the camera, and the nearest
library motions come back. The one flow behind the editor's *Act it out* view
(:mod:`app.ui.act_view`) and ``storybeam search --video`` (:mod:`app.commands.search_cmd`).

A take (:meth:`ActItOut.take_from_source`) reads frames from a camera source
(:class:`ar.camera_sources.CameraSource`: the Kivy camera on the tablet, a video file on a
desktop or in the tests) for ``seconds`` of the source's clock, runs each frame through the
pose estimator (:class:`ar.body.BodyTracker`) and keeps only the landmarks
(:class:`ar.body.BodyTake`). :meth:`ActItOut.judge` says whether enough of the body was
seen (:class:`TakeVerdict`: at least :data:`MIN_SEEN` of the frames show the whole body
inside the picture with the face visible; otherwise the reason the child is shown as a
picture: :data:`STEP_BACK`, :data:`LIFT_HEAD`, :data:`NO_BODY`), and
:meth:`ActItOut.results` searches the frontal-feature library
(:class:`retrieval.library.ActSearch`).

**Privacy.** No camera frame is stored, exported or logged. A frame lives only while it
is processed: it is handed to the tracker and to the caller's ``on_frame`` (the preview
shows it) and then dropped; the take keeps the landmarks alone, in memory. Nothing here
writes a file; the log gets counts only. The teacher switches the feature off for a class
with the profile setting :data:`ACT_SETTING` (``on`` / ``off``, stored like every other
setting in the profile's SQLite database: :func:`set_act_it_out_allowed`).
"""
from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Collection

import numpy as np

from app.services.background import BackgroundLoad
from retrieval.errors import StoryBeamError
from retrieval.motion import LANDMARK_INDEX  # BlazePose's landmarks by name

if TYPE_CHECKING:
    from ar.body import BodyPose, BodyTake
    from ar.camera_sources import CameraSource
    from retrieval.library import ActSearch, Match

log = logging.getLogger(__name__)

#: the profile setting of the teacher's switch: ``"off"`` hides *Act it out* for the class
ACT_SETTING = "act_it_out_camera"
#: how long a take lasts (seconds of the camera's clock)
TAKE_SECONDS = 3.5
#: the share of a take's frames that must show the whole body for a search
MIN_SEEN = 0.80
#: a landmark counts as seen at this visibility or more (MediaPipe's own default threshold)
MIN_VISIBILITY = 0.5
#: the nearest motions shown for a take
RESULTS = 6

#: why a take was refused: the body is cut off by the picture's edge (too close)
STEP_BACK = "step_back"
#: why a take was refused: the face is not seen (head bowed or turned away)
LIFT_HEAD = "lift_head"
#: why a take was refused: no body found in most frames
NO_BODY = "no_body"
REASONS = (STEP_BACK, LIFT_HEAD, NO_BODY)

#: the face: all must be seen (else "lift your head"), and inside the picture (else "step back")
FACE = tuple(LANDMARK_INDEX[n] for n in ("nose", "left_eye", "right_eye"))
#: the body from shoulders to ankles: all must be inside the picture and seen (else "step back")
BODY = tuple(LANDMARK_INDEX[n] for n in ("left_shoulder", "right_shoulder", "left_hip", "right_hip", "left_knee",
                                   "right_knee", "left_ankle", "right_ankle"))
#: the detected skeleton drawn over the preview: pairs of landmark indices
SKELETON_BONES: tuple[tuple[int, int], ...] = tuple(
    (LANDMARK_INDEX[a], LANDMARK_INDEX[b]) for a, b in (
        ("left_shoulder", "right_shoulder"), ("left_hip", "right_hip"),
        ("left_shoulder", "left_hip"), ("right_shoulder", "right_hip"),
        ("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"),
        ("right_shoulder", "right_elbow"), ("right_elbow", "right_wrist"),
        ("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("left_ankle", "left_heel"),
        ("left_heel", "left_foot_index"), ("left_ankle", "left_foot_index"),
        ("right_hip", "right_knee"), ("right_knee", "right_ankle"), ("right_ankle", "right_heel"),
        ("right_heel", "right_foot_index"), ("right_ankle", "right_foot_index"),
        ("left_ear", "left_eye"), ("left_eye", "nose"), ("nose", "right_eye"), ("right_eye", "right_ear")))

OnFrame = Callable[[int, np.ndarray, "BodyPose | None"], object]


class ActItOutError(StoryBeamError):
    """The camera feature cannot run (no pose runtime, no library, a camera that fails)."""


def act_it_out_allowed(store) -> bool:
    """The teacher's switch (:data:`ACT_SETTING`): on unless the teacher turned it off."""
    return store.get_setting(ACT_SETTING, "on") != "off"


def set_act_it_out_allowed(store, allowed: bool) -> None:
    """Turn the camera feature on or off for the class (one committed settings row)."""
    store.set_setting(ACT_SETTING, "on" if allowed else "off")


def frame_problem(pose: BodyPose | None, image_size: tuple[int, int],
                  min_visibility: float = MIN_VISIBILITY) -> str | None:
    """What keeps one frame from showing the whole body, or None when it does.

    :data:`NO_BODY`: no pose; :data:`STEP_BACK`: a landmark of the face or of the body
    (:data:`FACE`, :data:`BODY`) lies outside the picture, or a body landmark is not seen
    (hidden below the picture, behind something); :data:`LIFT_HEAD`: the face is inside
    the picture but not seen (a bowed or turned head)."""
    if pose is None:
        return NO_BODY
    w, h = image_size
    xy = np.asarray(pose.image_xy, float)
    vis = np.asarray(pose.visibility, float)
    keys = list(FACE + BODY)
    inside = (xy[keys, 0] >= 0) & (xy[keys, 0] < w) & (xy[keys, 1] >= 0) & (xy[keys, 1] < h)
    if not inside.all() or (vis[list(BODY)] < min_visibility).any():
        return STEP_BACK
    if (vis[list(FACE)] < min_visibility).any():
        return LIFT_HEAD
    return None


@dataclass(frozen=True)
class TakeVerdict:
    """Whether a take shows enough of the body to search with.

    ``ok``: at least ``min_seen`` of the frames show the whole body; else ``reason`` is
    the picture the child gets (:data:`NO_BODY` when a body was found in fewer than half
    of the frames, otherwise the more frequent of :data:`STEP_BACK` and :data:`LIFT_HEAD`).
    ``seen`` and ``detected``: the share of frames showing the whole body, and showing a
    body at all; ``problems``: frames per reason."""

    ok: bool
    reason: str | None
    seen: float
    detected: float
    frames: int
    problems: dict[str, int]

    def as_dict(self) -> dict[str, Any]:
        return {"ok": self.ok, "reason": self.reason, "seen": self.seen, "detected": self.detected,
                "frames": self.frames, "problems": dict(self.problems)}


def judge_poses(poses: list, image_size: tuple[int, int], min_seen: float = MIN_SEEN,
                min_visibility: float = MIN_VISIBILITY) -> TakeVerdict:
    """The :class:`TakeVerdict` of a list of poses (None where no body was found)."""
    counts = dict.fromkeys(REASONS, 0)
    for pose in poses:
        problem = frame_problem(pose, image_size, min_visibility)
        if problem is not None:
            counts[problem] += 1
    n = len(poses)
    seen = (n - sum(counts.values())) / n if n else 0.0
    detected = (n - counts[NO_BODY]) / n if n else 0.0
    if n and seen >= min_seen:
        return TakeVerdict(True, None, seen, detected, n, counts)
    if detected < 0.5:
        reason = NO_BODY
    else:
        reason = LIFT_HEAD if counts[LIFT_HEAD] > counts[STEP_BACK] else STEP_BACK
    return TakeVerdict(False, reason, seen, detected, n, counts)


def _default_tracker_factory():
    """A fresh :class:`ar.body.BodyTracker` (the pose runtime and the vendored models)."""
    from ar.body import BodyTracker  # deferred: loads the TFLite runtime, only when the camera is used

    return BodyTracker()


class ActItOut:
    """The Act-it-out flow over one motion library: takes, verdicts, results.

    ``search``: the library's :class:`retrieval.library.ActSearch` (or anything with its
    ``search_take``); ``tracker_factory``: makes the pose estimator on first use (default
    :class:`ar.body.BodyTracker`). One tracker is kept between a preview and the take that
    follows it (it tracks from the last landmarks instead of detecting again)."""

    def __init__(self, search: ActSearch | None, tracker_factory: Callable[[], Any] | None = None,
                 take_seconds: float = TAKE_SECONDS, min_seen: float = MIN_SEEN):
        self.search = search
        self.tracker_factory = tracker_factory or _default_tracker_factory
        self.take_seconds = float(take_seconds)
        self.min_seen = float(min_seen)
        self._tracker = None

    @property
    def tracker(self):
        if self._tracker is None:
            self._tracker = self.tracker_factory()
        return self._tracker

    def watch(self, source: CameraSource, until: Callable[[], bool], on_frame: OnFrame | None = None) -> int:
        """The preview before a take: track frames (shown through ``on_frame``, then
        dropped) until ``until()`` is true or the source ends. Returns the frames read."""
        n = 0
        while not until():
            got = source.read()
            if got is None:
                break
            pose = self.tracker.process(got.image, got.timestamp_s)
            if on_frame is not None:
                on_frame(got.index, got.image, pose)
            n += 1
            del got  # the frame goes now (privacy: nothing of it is kept)
        return n

    def take_from_source(self, source: CameraSource, seconds: float | None = None,
                         on_frame: OnFrame | None = None, stop: threading.Event | None = None,
                         max_frames: int | None = None) -> BodyTake:
        """Track ``seconds`` (default :attr:`take_seconds`) of ``source``'s clock, or to the
        end of a recording (``seconds=0``: the whole recording), or ``max_frames``, or until
        ``stop`` is set. Each frame is tracked, handed to ``on_frame(index, frame, pose)``
        and dropped: the returned :class:`ar.body.BodyTake` holds landmarks only."""
        from ar.body import BodyTake  # deferred: the pose package, only when the camera is used

        seconds = self.take_seconds if seconds is None else float(seconds)
        poses: list = []
        pose_ms: list[float] = []
        size: tuple[int, int] | None = None
        t_first = t_last = None
        tracker = self.tracker
        while stop is None or not stop.is_set():
            if max_frames is not None and len(poses) >= max_frames:
                break
            got = source.read()
            if got is None:
                break
            if t_first is None:
                t_first = got.timestamp_s
            elif seconds > 0 and got.timestamp_s - t_first >= seconds - 1e-6:
                break  # this frame is past the take (and is dropped unseen)
            h, w = got.image.shape[:2]
            if size is None:
                size = (int(w), int(h))
            elif size != (w, h):
                raise ActItOutError(f"camera {source.name}: the picture changed size during the take "
                                    f"({size[0]}x{size[1]} to {w}x{h})")
            t0 = time.perf_counter()
            pose = tracker.process(got.image, got.timestamp_s)
            pose_ms.append((time.perf_counter() - t0) * 1e3)
            poses.append(pose)
            t_last = got.timestamp_s
            if on_frame is not None:
                on_frame(got.index, got.image, pose)
            del got  # the frame goes now (privacy: nothing of it is kept)
        fps = source.fps
        if not fps:  # a live camera: the rate the frames came at
            span = (t_last or 0.0) - (t_first or 0.0)
            fps = (len(poses) - 1) / span if len(poses) > 1 and span > 0 else 30.0
        take = BodyTake(poses=poses, fps=float(fps), image_size=size or (0, 0), pose_ms=pose_ms)
        log.info("act it out: take of %d frames at %.1f fps", len(poses), take.fps)
        return take

    def judge(self, take: BodyTake) -> TakeVerdict:
        """Whether ``take`` shows enough of the body (:func:`judge_poses`)."""
        return judge_poses(list(take.poses), take.image_size, self.min_seen)

    def results(self, take: BodyTake, k: int = RESULTS, exclude: Collection[str] = ()) -> list[Match]:
        """The ``k`` library motions nearest to the take (the library without ``exclude``)."""
        if self.search is None:
            raise ActItOutError("no motion library to search (Act it out needs the frontal-feature library)")
        world, image_xy, _visibility, valid = take.arrays()
        if not valid.any():
            return []
        return self.search.search_take(world, image_xy, valid, fps=take.fps, image_size=take.image_size, k=k,
                                       exclude=exclude)


class ActLibrary(BackgroundLoad):
    """The frontal-feature search over a motion folder, built once on a background thread.

    ``ready`` / ``error`` say where it stands; :meth:`when_ready` runs a callback on the
    loading thread once loading has ended (the UI moves it onto its own thread)."""

    thread_name = "storybeam-act-library"

    def __init__(self, folder: str | Path, build: Callable[[Path], Any] | None = None):
        super().__init__()
        self.folder = Path(folder)
        self.search: ActSearch | None = None
        self.error: str | None = None
        self._build = build

    def _work(self) -> None:
        try:
            build = self._build
            if build is None:
                from retrieval.library import ActSearch  # deferred: the search stack loads off the UI thread

                build = ActSearch.build
            self.search = build(self.folder)
        except (StoryBeamError, ImportError, OSError, ValueError) as exc:
            self.error = str(exc)
            log.warning("act it out: the motion library cannot be searched: %s", exc)


def pose_runtime_problem() -> str | None:
    """Why the pose estimator cannot run here (no TFLite runtime, models missing), or None."""
    try:
        from ar.body import pose_runtime_available  # deferred: the pose package, only to ask
    except ImportError as exc:
        return f"the pose estimator is not installed ({exc})"
    try:
        ok = pose_runtime_available()
    except StoryBeamError as exc:
        return str(exc)
    return None if ok else "no TFLite runtime (ai-edge-litert or tflite-runtime) is installed"


__all__ = ["ActItOut", "ActItOutError", "ActLibrary", "TakeVerdict", "judge_poses", "frame_problem",
           "act_it_out_allowed", "set_act_it_out_allowed", "pose_runtime_problem", "ACT_SETTING", "TAKE_SECONDS",
           "MIN_SEEN", "MIN_VISIBILITY", "RESULTS", "STEP_BACK", "LIFT_HEAD", "NO_BODY", "REASONS",
           "FACE", "BODY", "SKELETON_BONES"]
