"""Kinetic energy per body part over time: how much each part of the body moves, frame by
frame — the feature the research group clusters motions with, without labels.

Method: the body is split into five parts of the canonical body (:data:`BODY_PARTS`:
torso with head, each arm, each leg). Every joint gets unit mass; its velocity is the
central difference of its world position (metres, Y up; one-sided at the ends,
:func:`numpy.gradient`) times the frame rate, divided by the performer's leg length so a
child and an adult doing the same motion give the same numbers. A part's energy at a
frame is ``½ · mean over its joints of |v|²`` (leg lengths² per second²). World
velocities, not velocities relative to the hips: travelling is part of a motion's
character (a run moves its torso fast, a dance in place does not).

The result depends on the frame rate only through the sampling of the curve (a
velocity, not a per-frame step), so clips resampled to one rate are comparable.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.features.relational import leg_length
from retrieval.motion import Motion, canonical_joint_map, positions

#: Body part -> its canonical joints (every canonical joint in exactly one part).
BODY_PARTS: dict[str, tuple[str, ...]] = {
    "torso": ("hips", "spine", "neck", "head"),
    "left_arm": ("left_shoulder", "left_elbow", "left_hand"),
    "right_arm": ("right_shoulder", "right_elbow", "right_hand"),
    "left_leg": ("left_hip", "left_knee", "left_ankle", "left_toe"),
    "right_leg": ("right_hip", "right_knee", "right_ankle", "right_toe"),
}


def kinetic_energy_from_positions(pos: np.ndarray, joint_map: Mapping[str, int], body_size: float,
                                  fps: float) -> np.ndarray:
    """(T, J, 3) positions in metres -> (T, 5) kinetic energy per body part (module
    docstring), columns in :data:`BODY_PARTS` order. A clip of one frame does not move:
    zeros."""
    pos = np.asarray(pos, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[2] != 3 or pos.shape[0] == 0:
        raise StoryBeamError(f"positions must be (frames, joints, 3) with frames > 0, got {pos.shape}")
    if not fps > 0 or not body_size > 0:
        raise StoryBeamError(f"fps and body size must be positive, got {fps} and {body_size}")
    missing = sorted({j for js in BODY_PARTS.values() for j in js} - set(joint_map))
    if missing:
        raise StoryBeamError(f"kinetic energy needs joints {', '.join(missing)}")
    if pos.shape[0] < 2:
        return np.zeros((pos.shape[0], len(BODY_PARTS)))
    vel = np.gradient(pos, axis=0) * (fps / body_size)
    speed2 = (vel ** 2).sum(axis=2)  # (T, J)
    return np.stack([0.5 * speed2[:, [joint_map[j] for j in joints]].mean(axis=1)
                     for joints in BODY_PARTS.values()], axis=1)


def kinetic_energy(motion: Motion) -> np.ndarray:
    """(T, 5) kinetic energy per body part of a motion, at its own frame rate."""
    jm = canonical_joint_map(motion.skeleton)
    return kinetic_energy_from_positions(positions(motion), jm, leg_length(motion.skeleton, jm), motion.fps)
