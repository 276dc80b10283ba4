"""The motion library the product searches: clips from labelled folders, the saved index
(:class:`MotionIndex`, the one search path), the choice of a clip for a story character,
and the bundled library's builder."""
from __future__ import annotations

from retrieval.library.bundle import SELECTION as BUNDLE_SELECTION
from retrieval.library.bundle import build as build_bundle
from retrieval.library.clip import Clip, Match
from retrieval.library.dataset import (
    LabelRow,
    clip_from_motion,
    default_cache_dir,
    load_dataset,
    load_row,
    read_labels,
)
from retrieval.library.index import MotionIndex
from retrieval.library.motion_choice import choose_clip, clip_path

__all__ = [
    "Clip",
    "Match",
    "LabelRow",
    "default_cache_dir",
    "read_labels",
    "clip_from_motion",
    "load_row",
    "load_dataset",
    "MotionIndex",
    "choose_clip",
    "clip_path",
    "BUNDLE_SELECTION",
    "build_bundle",
]
