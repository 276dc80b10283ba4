"""Forward kinematics and frame-rate resampling, vectorised over all frames at once."""
from __future__ import annotations

import numpy as np

from retrieval.motion.model import Motion, Skeleton
from retrieval.motion.rotations import slerp_matrices

#: Native (file) axes -> StoryBeam world axes (Y up, right-handed). Z-up files have
#: (x, y, z)_native = (x, -z, y)_world, i.e. world = A @ native with this A.
_TO_Y_UP = {
    "y": np.eye(3),
    "z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}


def world_from_native(skeleton: Skeleton) -> np.ndarray:
    """3x3 matrix taking the file's axes to StoryBeam's Y-up world axes."""
    try:
        return _TO_Y_UP[skeleton.up_axis.lower()]
    except KeyError:
        raise ValueError(f"unknown up axis {skeleton.up_axis!r}") from None


def global_transforms(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations (T, J, 3, 3) and positions (T, J, 3) in native units and axes."""
    sk = motion.skeleton
    t, nj = motion.n_frames, sk.n_joints
    rot = np.empty((t, nj, 3, 3))
    pos = np.empty((t, nj, 3))
    offsets = sk.offsets
    jt = motion.joint_translations
    for j, joint in enumerate(sk.joints):
        if joint.parent < 0:
            rot[:, j] = motion.rotations[:, j]
            pos[:, j] = motion.root_translation
            continue
        p = joint.parent
        off = offsets[j] if jt is None else jt[:, j]
        rot[:, j] = rot[:, p] @ motion.rotations[:, j]
        # off is (3,) or, with per-frame joint translations, (T, 3): matmul broadcasts both.
        pos[:, j] = pos[:, p] + (rot[:, p] @ off[..., None])[..., 0]
    return rot, pos


def positions(motion: Motion, metres_yup: bool = True) -> np.ndarray:
    """Joint positions (T, J, 3). By default in metres with Y up (StoryBeam's world);
    ``metres_yup=False`` gives the file's own units and axes."""
    _, pos = global_transforms(motion)
    if not metres_yup:
        return pos
    a = world_from_native(motion.skeleton) * motion.skeleton.metres_per_unit
    return pos @ a.T


def rest_positions(skeleton: Skeleton, metres_yup: bool = True) -> np.ndarray:
    """(J, 3) joint positions of the rest pose (all local rotations identity)."""
    sk = skeleton
    offsets = sk.offsets
    pos = np.zeros((sk.n_joints, 3))
    for j, joint in enumerate(sk.joints):
        if joint.parent >= 0:
            pos[j] = pos[joint.parent] + offsets[j]
    if metres_yup:
        pos = pos @ (world_from_native(sk) * sk.metres_per_unit).T
    return pos


def resample(motion: Motion, fps: float) -> Motion:
    """The same motion at another frame rate: rotations by slerp, translations linearly.

    The clip keeps its duration (last frame time = (n-1)/fps_old); the new frame count is
    ``floor((n - 1) * fps / fps_old) + 1``.
    """
    if fps <= 0:
        raise ValueError("fps must be positive")
    n = motion.n_frames
    if n == 0 or abs(fps - motion.fps) < 1e-9:
        return motion.copy(fps=float(fps)) if n else motion.copy()
    m = int(np.floor((n - 1) * fps / motion.fps + 1e-9)) + 1
    src = np.arange(m) * motion.fps / fps
    i0 = np.clip(np.floor(src).astype(int), 0, n - 1)
    i1 = np.clip(i0 + 1, 0, n - 1)
    w = src - i0
    rot = slerp_matrices(
        motion.rotations[i0],
        motion.rotations[i1],
        np.broadcast_to(w[:, None], (m, motion.skeleton.n_joints)),
    )
    root = motion.root_translation[i0] * (1 - w[:, None]) + motion.root_translation[i1] * w[:, None]
    jt = None
    if motion.joint_translations is not None:
        a, b = motion.joint_translations[i0], motion.joint_translations[i1]
        jt = a * (1 - w[:, None, None]) + b * w[:, None, None]
    return Motion(motion.skeleton, rot, root, float(fps), motion.name, jt)
