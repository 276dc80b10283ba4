"""Rigid-transform helpers shared by the AR modules.

Convention: ``T_a_from_b`` is a 4x4 matrix that maps points written in frame *b* into
frame *a* (``p_a = T_a_from_b @ p_b``). OpenCV's ``rvec, tvec`` from solvePnP is
``T_cam_from_board``. Cameras (and the projector, an inverse camera) use OpenCV's axes:
+x right, +y down, +z forward.
"""
from __future__ import annotations

import cv2
import numpy as np


def make_transform(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """4x4 transform from a 3x3 rotation and a translation."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, np.float64).ravel()
    return T


def from_rvec_tvec(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """OpenCV (rvec, tvec) -> 4x4 transform."""
    R, _ = cv2.Rodrigues(np.asarray(rvec, np.float64).reshape(3, 1))
    return make_transform(R, tvec)


def to_rvec_tvec(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """4x4 transform -> OpenCV (rvec (3,1), tvec (3,1))."""
    rvec, _ = cv2.Rodrigues(np.ascontiguousarray(T[:3, :3]))
    return rvec.reshape(3, 1), T[:3, 3].reshape(3, 1).copy()


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform (cheaper and exacter than np.linalg.inv)."""
    R = T[:3, :3]
    return make_transform(R.T, -R.T @ T[:3, 3])


def rotation_angle_deg(R: np.ndarray) -> float:
    """Angle of a rotation matrix, degrees (robust near 0 and 180)."""
    c = (np.trace(R) - 1.0) / 2.0
    s = np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    return float(np.degrees(np.arctan2(s, c)))


def pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """(rotation error deg, translation error mm) between two ``T_cam_from_board`` poses.

    Translation error is the distance between the board origins as seen from the
    camera; rotation error is the angle of ``R_est^T R_true``.
    """
    rot = rotation_angle_deg(T_est[:3, :3].T @ T_true[:3, :3])
    trans = float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3]) * 1000.0)
    return rot, trans


def look_at(eye: np.ndarray, target: np.ndarray, up_hint: np.ndarray) -> np.ndarray:
    """``T_cam_from_world`` for an OpenCV camera at ``eye`` looking at ``target``.

    ``up_hint`` is the world direction that should appear *up* in the image (-y).
    """
    eye = np.asarray(eye, np.float64)
    z = np.asarray(target, np.float64) - eye
    z /= np.linalg.norm(z)
    x = np.cross(-np.asarray(up_hint, np.float64), z)  # image +y is down = -up
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R_world_from_cam = np.stack([x, y, z], 1)
    return invert(make_transform(R_world_from_cam, eye))


def scale_intrinsics(K: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """Camera matrix ``K`` for the same lens at ``sx`` x ``sy`` the resolution. Focal
    lengths scale; the principal point scales about pixel corners (OpenCV puts pixel
    centres at integers, so ``c' = (c + 0.5)·s - 0.5``): the image covers the same field
    of view. A new array."""
    K = np.array(K, copy=True)
    K[0, 0] *= sx
    K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
    K[1, 1] *= sy
    K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
    return K


def project_points(points: np.ndarray, T_cam_from_world: np.ndarray, K: np.ndarray,
                   dist: np.ndarray | None = None) -> np.ndarray:
    """Project (N,3) world points to (N,2) pixels through a pose and intrinsics."""
    rvec, tvec = to_rvec_tvec(T_cam_from_world)
    d = np.zeros(5) if dist is None else np.asarray(dist, np.float64).ravel()
    px, _ = cv2.projectPoints(np.asarray(points, np.float64).reshape(-1, 1, 3), rvec, tvec, K, d)
    return px.reshape(-1, 2)


def pixels_to_plane(pixels: np.ndarray, T_cam_from_board: np.ndarray, K: np.ndarray,
                    dist: np.ndarray | None = None) -> np.ndarray:
    """Lift (N,2) pixels onto the board plane z = 0: (N,3) board points (NaN behind the camera).

    Undistorts each pixel to a ray and intersects it with the plane; this is how
    projected pattern corners seen by the camera become 3-D table points.
    """
    d = np.zeros(5) if dist is None else np.asarray(dist, np.float64).ravel()
    norm = cv2.undistortPoints(np.asarray(pixels, np.float64).reshape(-1, 1, 2), K, d).reshape(-1, 2)
    rays = np.concatenate([norm, np.ones((len(norm), 1))], 1)
    return rays_to_plane(rays, T_cam_from_board)


def rays_to_plane(rays_cam: np.ndarray, T_cam_from_board: np.ndarray) -> np.ndarray:
    """Intersect (N,3) camera-frame ray directions with the board plane z = 0."""
    T_board_from_cam = invert(T_cam_from_board)
    R, o = T_board_from_cam[:3, :3], T_board_from_cam[:3, 3]
    d = rays_cam @ R.T
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -o[2] / d[:, 2]
    pts = o[None, :] + s[:, None] * d
    pts[~(s > 0)] = np.nan
    return pts
