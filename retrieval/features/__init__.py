"""Per-frame features of a motion: the 17 body-part relational distances the search uses
(:mod:`~retrieval.features.relational`, feature sets by name) and the weighted pose
vectors of the Forbes–Fiume baseline (:mod:`~retrieval.features.pose_vectors`), and the
frontal set one camera in front of the body sees (:mod:`~retrieval.features.frontal`)."""
from __future__ import annotations

from retrieval.features.kinetic import BODY_PARTS, kinetic_energy, kinetic_energy_from_positions
from retrieval.features.pose_vectors import JOINT_WEIGHTS, pose_frames
from retrieval.features.relational import (
    MR17,
    MR17_CANONICAL,
    FeatureError,
    FeatureSet,
    FeatureSpec,
    available_feature_sets,
    get_feature_set,
    leg_length,
    motion_features,
    HEADING_SMOOTH_SECONDS,
    body_axes,
    heading_rate,
    register_feature_set,
)
from retrieval.features.frontal import FRONTAL, FrontalFeatureSet, face_camera, mean_heading, measured_rest
from retrieval.features.storybeam_set import (
    HANDS_WEIGHT,
    HEADING_WEIGHT,
    STORYBEAM,
    STORYBEAM_NO_HANDS,
    hand_specs,
    heading_weight_of,
    mr17_columns,
    storybeam_feature_set,
)

__all__ = [
    "FeatureError",
    "FeatureSpec",
    "FeatureSet",
    "MR17",
    "MR17_CANONICAL",
    "STORYBEAM",
    "HEADING_WEIGHT",
    "HANDS_WEIGHT",
    "STORYBEAM_NO_HANDS",
    "hand_specs",
    "heading_weight_of",
    "storybeam_feature_set",
    "mr17_columns",
    "heading_rate",
    "body_axes",
    "HEADING_SMOOTH_SECONDS",
    "leg_length",
    "register_feature_set",
    "get_feature_set",
    "available_feature_sets",
    "motion_features",
    "FRONTAL",
    "FrontalFeatureSet",
    "face_camera",
    "mean_heading",
    "measured_rest",
    "JOINT_WEIGHTS",
    "pose_frames",
    "BODY_PARTS",
    "kinetic_energy",
    "kinetic_energy_from_positions",
]
