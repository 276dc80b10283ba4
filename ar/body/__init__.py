"""Body pose from the tablet's camera for "Act it out" (issue 18): BlazePose, run by a
TFLite interpreter, with StoryBeam's own loop around the two models.

Modules:

* :mod:`ar.body.models` -- the vendored model files (``assets/models/blazepose/``, hashes
  checked) and the interpreter (``ai_edge_litert``, else ``tflite_runtime``; the only
  importer of either): ``PoseModelError``, ``pose_runtime_available``;
* :mod:`ar.body.blazepose` -- MediaPipe's pre/post-processing: SSD anchors, detection
  decoding, weighted NMS, letterbox, the rotated body region, crop, landmark decoding,
  heatmap refinement, projection back to the frame;
* :mod:`ar.body.smoothing` -- MediaPipe's one-euro and low-pass landmark filters;
* :mod:`ar.body.acquire` -- finding the body wherever it is (issue 27): the tiles of the
  detection pass that runs when the whole frame shows nobody, and whom to follow;
* :mod:`ar.body.tracker` -- ``BodyTracker`` (detect -> track -> re-detect -> smooth),
  ``BodyPose``, ``BodyTake``, ``track_frames``, ``LANDMARK_NAMES``.

Needs numpy and OpenCV (the core ``ar``); never Kivy or a renderer. ``import ar.body``
works without an interpreter; :class:`BodyTracker` then raises ``PoseModelError``.
The pipeline and how it was checked against MediaPipe: docs/notebook/pose.md.
"""
from __future__ import annotations

from ar.body.blazepose import Detection, Rect
from ar.body.models import DEFAULT_MODEL_DIR, MODEL_FILES, PoseModelError, pose_runtime_available, runtime_name
from ar.body.tracker import LANDMARK_NAMES, BodyPose, BodyTake, BodyTracker, FrameTiming, track_frames

__all__ = [
    "LANDMARK_NAMES", "BodyPose", "BodyTracker", "BodyTake", "FrameTiming", "track_frames",
    "PoseModelError", "pose_runtime_available", "runtime_name", "DEFAULT_MODEL_DIR", "MODEL_FILES",
    "Rect", "Detection",
]
