"""Weighted, heading-aligned pose vectors: the frame representation of the Forbes–Fiume
baseline (see :mod:`lab.experiment.baselines`).

Pose vectors (:func:`pose_frames`): the canonical joints (18) relative to the hips, turned
about the vertical so the hips face +Z (heading-invariant, like the distances), divided by
leg length, each joint's xyz multiplied by √w so squared distances weight joints by
importance ``w`` (:data:`JOINT_WEIGHTS`: trunk and limbs' middle joints count fully,
extremities a little less because they are noisier and skeletons disagree most there).
"""
from __future__ import annotations

import numpy as np

from retrieval.motion import CANONICAL_JOINTS

#: Importance of each canonical joint in the Forbes–Fiume pose space.
JOINT_WEIGHTS: dict[str, float] = {
    "hips": 1.0, "spine": 1.0, "neck": 1.0, "head": 0.8,
    "left_shoulder": 1.0, "left_elbow": 1.0, "left_hand": 0.8,
    "right_shoulder": 1.0, "right_elbow": 1.0, "right_hand": 0.8,
    "left_hip": 1.0, "left_knee": 1.0, "left_ankle": 0.8, "left_toe": 0.5,
    "right_hip": 1.0, "right_knee": 1.0, "right_ankle": 0.8, "right_toe": 0.5,
}


def pose_frames(pos: np.ndarray, joint_map: dict[str, int], body_size: float) -> np.ndarray:
    """(T, J, 3) positions (metres, Y up) -> (T, 3·18) weighted, heading-aligned pose vectors."""
    idx = [joint_map[n] for n in CANONICAL_JOINTS]
    p = pos[:, idx] - pos[:, [joint_map["hips"]]]
    across = pos[:, joint_map["left_hip"]] - pos[:, joint_map["right_hip"]]
    # facing = (left − right) × up in the ground plane (Y up, right-handed: a body facing
    # +Z has its left hip on +X); yaw is the angle that turns it onto +Z
    fx, fz = -across[:, 2], across[:, 0]
    yaw = np.arctan2(fx, fz)
    c, s = np.cos(-yaw), np.sin(-yaw)
    x, z = p[..., 0], p[..., 2]
    aligned = np.stack([c[:, None] * x + s[:, None] * z, p[..., 1], -s[:, None] * x + c[:, None] * z], axis=-1)
    w = np.sqrt(np.array([JOINT_WEIGHTS[n] for n in CANONICAL_JOINTS]))
    return (aligned * w[None, :, None] / body_size).reshape(len(pos), -1)
