"""Motion file formats, one module each: BVH (read and write), Acclaim ASF/AMC (read), the
shared text tokenizer and size limits, and :func:`load_motion`, which picks the reader by
extension. Every malformed file raises :class:`~retrieval.errors.MotionFormatError`
naming the file, the line and the problem."""
from __future__ import annotations

from retrieval.motion.formats.acclaim import (
    DEFAULT_AMC_FPS,
    AcclaimSkeleton,
    load_amc,
    load_asf,
)
from retrieval.motion.formats.bvh import (
    detect_tpose,
    detect_up_axis,
    load_bvh,
    save_bvh,
)
from retrieval.motion.formats.dispatch import (
    MOTION_EXTENSIONS,
    clear_skeleton_cache,
    find_asf,
    load_motion,
    load_skeleton,
)
from retrieval.motion.formats.textfile import MAX_FILE_BYTES, MAX_FRAMES, MAX_JOINTS

__all__ = [
    "MAX_FILE_BYTES",
    "MAX_FRAMES",
    "MAX_JOINTS",
    "load_bvh",
    "save_bvh",
    "detect_tpose",
    "detect_up_axis",
    "DEFAULT_AMC_FPS",
    "AcclaimSkeleton",
    "load_asf",
    "load_amc",
    "MOTION_EXTENSIONS",
    "load_motion",
    "load_skeleton",
    "clear_skeleton_cache",
    "find_asf",
]
