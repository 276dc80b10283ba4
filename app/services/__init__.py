"""Kivy-free services between the UI and the heavier parts (motion library, AR rig).

* :mod:`app.services.catalog` -- ``MotionCatalog``: the bundled clips by class at once,
  "more like this" through the retrieval index once it has loaded in the background;
* :mod:`app.services.thumbnails` -- stick-figure thumbnails of clips, made on a
  background thread;
* :mod:`app.services.calibration_wizard` -- the teacher's camera calibration as steps the
  UI runs one at a time (board, capture, solve, save, scan the table), done by ``ar``,
  and its Gray-code mode for the projector (``GrayCodeWizard``);
* :mod:`app.services.table_scan` -- *Scan the table*: the Gray-code sequence projected and
  captured, scanned into a height map stored beside the calibration (``table.npz``);
* :mod:`app.services.act_it_out` -- "Act it out": a camera take tracked into body
  landmarks (``ar.body``), its verdict (enough of the body seen?) and the nearest motions
  (``retrieval.library.ActSearch``); no frame is kept;
* :mod:`app.services.background` -- ``BackgroundLoad``: work done once on a background
  thread (the search indexes), with callbacks when it has ended;
* :mod:`app.services.gallery` -- saving a story's video where the family finds it (the
  desktop's videos folder, Android's Movies collection through MediaStore) and sharing it;
* :mod:`app.services.recording` -- recording a scene's narration (Android AudioRecord
  through pyjnius, sounddevice on a desktop) into a crash-safe ``.part`` file;
* :mod:`app.services.speech` -- spoken prompts (Android TextToSpeech, espeak-ng on a
  desktop, silence where neither exists).

The UI must start fast and keep working where a part is missing (no numba on Android, no
pyrender, no bundled clips): each service answers from cheap data at once and loads the
heavy part when it is first needed. No Kivy, no OpenGL, so all of it is tested directly.
"""
from __future__ import annotations

from app.services.act_it_out import (
    ACT_SETTING,
    LIFT_HEAD,
    NO_BODY,
    SKELETON_BONES,
    STEP_BACK,
    ActItOut,
    ActItOutError,
    ActLibrary,
    TakeVerdict,
    act_it_out_allowed,
    judge_poses,
    set_act_it_out_allowed,
)
from app.services.calibration_wizard import CalibrationStep, CalibrationWizard, GrayCodeWizard
from app.services.catalog import ClipInfo, MotionCatalog
from app.services.gallery import (
    VIDEO_SAVE_SETTING,
    DesktopGallery,
    Gallery,
    GalleryError,
    SavedVideo,
    gallery_for,
    set_video_saving_allowed,
    video_saving_allowed,
)
from app.services.recording import (
    RECORD_RATE,
    ArraySource,
    ChunkRecorder,
    ChunkSource,
    RecordingError,
    discard_stale,
    find_recorder,
)
from app.services.background import BackgroundLoad
from app.services.speech import EspeakSpeaker, SilentSpeaker, Speaker, find_speaker
from app.services.thumbnails import (
    BONES,
    HEAD,
    VIEW_YAW_DEG,
    StickFrames,
    ThumbnailCache,
    clip_stick_frames,
    library_files,
    stick_frames,
)

__all__ = [
    "MotionCatalog", "ClipInfo",
    "ThumbnailCache", "StickFrames", "stick_frames", "clip_stick_frames", "library_files", "BONES", "HEAD",
    "VIEW_YAW_DEG",
    "CalibrationWizard", "CalibrationStep", "GrayCodeWizard", "BackgroundLoad",
    "ActItOut", "ActItOutError", "ActLibrary", "TakeVerdict", "judge_poses", "act_it_out_allowed",
    "set_act_it_out_allowed", "ACT_SETTING", "STEP_BACK", "LIFT_HEAD", "NO_BODY", "SKELETON_BONES",
    "ChunkRecorder", "ChunkSource", "ArraySource", "RecordingError", "RECORD_RATE", "find_recorder", "discard_stale",
    "Speaker", "SilentSpeaker", "EspeakSpeaker", "find_speaker",
    "Gallery", "DesktopGallery", "GalleryError", "SavedVideo", "gallery_for", "VIDEO_SAVE_SETTING",
    "video_saving_allowed", "set_video_saving_allowed",
]
