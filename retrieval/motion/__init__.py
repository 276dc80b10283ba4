"""The motion model: skeletons, motions, rotations, forward kinematics, the canonical body
map, the file formats (:mod:`retrieval.motion.formats`), and BlazePose landmarks as
canonical joints (:mod:`retrieval.motion.landmarks`, with the one table of BlazePose's
landmarks, :data:`LANDMARK_NAMES`).

The bottom layer of StoryBeam: it imports nothing else of StoryBeam but
:mod:`retrieval.errors`.
"""
from __future__ import annotations

from retrieval.motion.body import (
    CANONICAL_BONES,
    CANONICAL_INDEX,
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    CANONICAL_POSE_VERSION,
    JointMapError,
    body_proportions,
    canonical_joint_map,
    canonical_pose,
    canonical_rest,
)
from retrieval.motion.topology import TopologyError, topology_joint_map
from retrieval.motion.formats import (
    MOTION_EXTENSIONS,
    AcclaimSkeleton,
    clear_skeleton_cache,
    detect_tpose,
    find_asf,
    load_amc,
    load_asf,
    load_bvh,
    load_motion,
    load_skeleton,
    save_bvh,
)
from retrieval.motion.kinematics import (
    global_transforms,
    positions,
    resample,
    rest_positions,
    world_from_native,
)
from retrieval.motion.landmarks import (
    LANDMARK_INDEX,
    LANDMARK_NAMES,
    N_LANDMARKS,
    UP_OFFSETS,
    LandmarkError,
    landmarks_to_positions,
)
from retrieval.motion.model import Joint, Motion, Skeleton
from retrieval.motion.rotations import (
    axis_rotation,
    euler_to_matrix,
    matrix_to_euler,
    min_rotation,
    slerp_matrices,
)

__all__ = [
    "Joint",
    "Skeleton",
    "Motion",
    "axis_rotation",
    "euler_to_matrix",
    "matrix_to_euler",
    "slerp_matrices",
    "min_rotation",
    "world_from_native",
    "global_transforms",
    "positions",
    "rest_positions",
    "resample",
    "CANONICAL_BONES",
    "CANONICAL_INDEX",
    "canonical_pose",
    "CANONICAL_POSE_VERSION",
    "canonical_rest",
    "body_proportions",
    "CANONICAL_JOINTS",
    "CANONICAL_PARENTS",
    "JointMapError",
    "canonical_joint_map",
    "TopologyError",
    "topology_joint_map",
    "MOTION_EXTENSIONS",
    "load_motion",
    "load_skeleton",
    "clear_skeleton_cache",
    "find_asf",
    "load_bvh",
    "save_bvh",
    "detect_tpose",
    "load_asf",
    "load_amc",
    "AcclaimSkeleton",
    "LANDMARK_NAMES",
    "LANDMARK_INDEX",
    "LandmarkError",
    "landmarks_to_positions",
    "N_LANDMARKS",
    "UP_OFFSETS",
]
