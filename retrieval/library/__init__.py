"""The motion library the product searches: clips from labelled folders, the saved index
(:class:`MotionIndex`, the one search path), the choice of a clip for a story character,
the bundled library's builder, search by pose (:class:`PoseSearch`), search by performance
(:class:`ActSearch`, "Act it out") and the library's unsupervised groups (:func:`group`)."""
from __future__ import annotations

# the re-ranking kernels and what StoryBeamSearcher answers, for callers of the library
from retrieval.dtw import dtw_features_abandon, dtw_features_abandon_t, dtw_features_many
from retrieval.search import Hit
from retrieval.library.act_search import ActSearch, Augment, mirror_permutation, time_scale
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
from retrieval.library.grouping import (
    K_MAX,
    K_MIN,
    FolderGrouping,
    Group,
    Grouping,
    adjusted_rand_index,
    clip_descriptor,
    descriptor_matrix,
    group,
    group_folder,
    load_energies,
    purity,
    silhouette,
)
from retrieval.library.index import MotionIndex
from retrieval.library.motion_choice import choose_clip, clip_path
from retrieval.library.storybeam_search import DIMS as STORYBEAM_DIMS
from retrieval.library.storybeam_search import SHORTLIST, SUMMARY, StoryBeamSearcher, clip_summary
from retrieval.library.pose_search import (
    CHARACTERISTIC,
    POSE_FEATURE_SET,
    PoseSearch,
    characteristic_frame,
    pose_feature_set,
    pose_features,
    pose_floor_joints,
)

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
    "ActSearch",
    "Augment",
    "mirror_permutation",
    "time_scale",
    "StoryBeamSearcher",
    "Hit",
    "SHORTLIST",
    "SUMMARY",
    "clip_summary",
    "STORYBEAM_DIMS",
    "dtw_features_abandon",
    "dtw_features_abandon_t",
    "dtw_features_many",
    "choose_clip",
    "clip_path",
    "BUNDLE_SELECTION",
    "build_bundle",
    "pose_features",
    "pose_floor_joints",
    "PoseSearch",
    "POSE_FEATURE_SET",
    "pose_feature_set",
    "CHARACTERISTIC",
    "characteristic_frame",
    "K_MAX",
    "K_MIN",
    "Group",
    "Grouping",
    "clip_descriptor",
    "descriptor_matrix",
    "group",
    "group_folder",
    "FolderGrouping",
    "load_energies",
    "purity",
    "adjusted_rand_index",
    "silhouette",
]
