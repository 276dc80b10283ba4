"""Rotation helpers (vectorised over leading axes): Euler angles <-> matrices, slerp.

Euler order strings list axes outermost first: "ZYX" means ``R = Rz(a) @ Ry(b) @ Rx(c)``
for angles ``(a, b, c)`` given in that same order. This is how BVH channel lists and
Acclaim ``dof`` lists compose.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def axis_rotation(axis: str, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices about one axis ("X", "Y" or "Z") for angles in radians."""
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    o, z = np.ones_like(angle), np.zeros_like(angle)
    a = axis.upper()
    if a == "X":
        m = [[o, z, z], [z, c, -s], [z, s, c]]
    elif a == "Y":
        m = [[c, z, s], [z, o, z], [-s, z, c]]
    elif a == "Z":
        m = [[c, -s, z], [s, c, z], [z, z, o]]
    else:
        raise ValueError(f"unknown axis {axis!r}")
    return np.moveaxis(np.array(m), (0, 1), (-2, -1))


def euler_to_matrix(angles: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """(..., k) angles composed in ``order`` (k letters) -> (..., 3, 3) matrices."""
    angles = np.asarray(angles, dtype=np.float64)
    if degrees:
        angles = np.deg2rad(angles)
    out = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for k, axis in enumerate(order):
        out = out @ axis_rotation(axis, angles[..., k])
    return out


def matrix_to_euler(matrices: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """(..., 3, 3) matrices -> (..., 3) angles for a 3-axis ``order`` (inverse of
    :func:`euler_to_matrix`)."""
    m = np.asarray(matrices, dtype=np.float64)
    flat = m.reshape(-1, 3, 3)
    # scipy's upper-case (intrinsic) sequence "ZYX" is exactly Rz @ Ry @ Rx.
    ang = Rotation.from_matrix(flat).as_euler(order.upper(), degrees=degrees)
    return ang.reshape(m.shape[:-2] + (3,))


def slerp_matrices(a: np.ndarray, b: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """Spherical interpolation between rotation matrices ``a`` and ``b`` (same shape
    (..., 3, 3)); ``t`` broadcasts against the leading axes."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    shape = a.shape
    qa = Rotation.from_matrix(a.reshape(-1, 3, 3)).as_quat()
    qb = Rotation.from_matrix(b.reshape(-1, 3, 3)).as_quat()
    dot = np.sum(qa * qb, axis=-1, keepdims=True)
    qb = np.where(dot < 0, -qb, qb)
    dot = np.abs(dot).clip(-1.0, 1.0)
    t = np.broadcast_to(np.asarray(t, dtype=np.float64), shape[:-2]).reshape(-1, 1)
    theta = np.arccos(dot)
    sin = np.sin(theta)
    small = sin < 1e-6
    w_a = np.where(small, 1 - t, np.sin((1 - t) * theta) / np.where(small, 1, sin))
    w_b = np.where(small, t, np.sin(t * theta) / np.where(small, 1, sin))
    q = w_a * qa + w_b * qb
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return Rotation.from_quat(q).as_matrix().reshape(shape)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def min_rotation(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Smallest rotations (..., 3, 3) taking unit vectors ``u`` onto unit vectors ``v``."""
    u, v = _unit(u), _unit(v)
    axis = np.cross(u, v)
    s = np.linalg.norm(axis, axis=-1)
    c = np.clip(np.sum(u * v, axis=-1), -1.0, 1.0)
    # Opposite vectors: rotate by pi about any axis perpendicular to u.
    alt = np.cross(u, np.array([1.0, 0.0, 0.0]))
    alt = np.where(np.linalg.norm(alt, axis=-1, keepdims=True) < 1e-6, np.cross(u, [0.0, 1.0, 0.0]), alt)
    axis = np.where((s < 1e-9)[..., None], _unit(alt), axis / np.maximum(s, 1e-12)[..., None])
    angle = np.arctan2(s, c)
    k = np.zeros(axis.shape + (3,))
    k[..., 0, 1], k[..., 0, 2] = -axis[..., 2], axis[..., 1]
    k[..., 1, 0], k[..., 1, 2] = axis[..., 2], -axis[..., 0]
    k[..., 2, 0], k[..., 2, 1] = -axis[..., 1], axis[..., 0]
    sa, ca = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + sa * k + (1 - ca) * (k @ k)
