"""How well an animated character follows its path and keeps its feet planted.

* **Path error** (cm on the table, at the character's size): mean over frames of the
  distance from the root's ground point (the hips projected on the table) to the drawn
  polyline. The hips sway a little within each step, so even a perfect follower scores
  a few millimetres.
* **Foot skate** (cm per metre travelled): the horizontal slide of foot points that are
  on the ground, weighted by how close they are to it, per metre the root travels. It is
  a ratio of two lengths, so it reads the same at the character's size and at the
  capture's human size ("cm per metre" of a 1.7 m actor). The points judged are the
  four sole points that touch the table (each foot's heel and toe tip, see
  :func:`retrieval.animation.retarget.sole_points`); a point's weight is
  ``clip(2 - 2**(h / H), 0, 1)`` for height ``h`` above the table and
  ``H`` = 0.03 leg lengths (2.5 cm for a human): the soft
  contact weighting of Zhang et al. (2018, "Mode-adaptive neural networks"). The slide
  of a foot is the mean of its two points; the two feet add up.
* **Transition cost**: the pose distance (:func:`retrieval.animation.transitions.pose_features`,
  leg-length units) between the outgoing and incoming frames of a transition.
"""
from __future__ import annotations

import numpy as np

from retrieval.animation.retarget import skeleton_leg_length, sole_points
from retrieval.animation.transitions import pose_distance, pose_features
from retrieval.motion import Motion


def point_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """(N,) distance from each 2-D point to the nearest point of a 2-D polyline."""
    p = np.asarray(points, dtype=np.float64)[:, None, :]
    a = polyline[:-1][None]
    b = polyline[1:][None]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-18), 0.0, 1.0)
    nearest = a + t[..., None] * ab
    return np.linalg.norm(p - nearest, axis=-1).min(axis=1)


def path_error_cm(motion: Motion, polyline: np.ndarray, frames: slice | np.ndarray | None = None) -> float:
    """Mean distance (cm) of the root's ground point to the path (see module docstring).
    The motion's world X, Z are the board's x, y."""
    mpu = motion.skeleton.metres_per_unit
    ground = motion.root_translation[:, [0, 2]] * mpu
    if frames is not None:
        ground = ground[frames]
    return float(point_to_polyline(ground, np.asarray(polyline, dtype=np.float64)).mean() * 100.0)


#: Sole points moving faster than this (leg lengths per second, about 0.85 m/s for an
#: adult) are swinging, not standing: a walking toe passes 1–2 cm over the floor.
SWING_SPEED_LEGS = 1.0


def foot_skate(
    motion: Motion, height_tol_legs: float = 0.03, swing_speed_legs: float | None = SWING_SPEED_LEGS
) -> tuple[float, float]:
    """(total weighted slide, root distance travelled), both in metres at the motion's
    own size. ``swing_speed_legs=None`` counts fast low points too (stricter)."""
    pts = sole_points(motion)
    h = pts[:, :, 1]
    leg = skeleton_leg_length(motion.skeleton)
    tol = height_tol_legs * leg
    w = np.clip(2.0 - np.power(2.0, np.maximum(h, 0.0) / tol), 0.0, 1.0)
    slide = np.linalg.norm(np.diff(pts[:, :, [0, 2]], axis=0), axis=-1)  # (T-1, 4)
    wmid = np.minimum(w[1:], w[:-1])
    if swing_speed_legs is not None:
        wmid = wmid * (slide * motion.fps < swing_speed_legs * leg)
    total = float((slide * wmid).sum() / 2.0)  # two points per foot
    root = motion.root_translation[:, [0, 2]] * motion.skeleton.metres_per_unit
    travelled = float(np.linalg.norm(np.diff(root, axis=0), axis=1).sum())
    return total, travelled


def foot_skate_cm_per_m(motion: Motion, swing_speed_legs: float | None = SWING_SPEED_LEGS) -> float:
    """Foot skate in cm per metre travelled (scale-free; see module docstring)."""
    total, travelled = foot_skate(motion, swing_speed_legs=swing_speed_legs)
    return float(total / max(travelled, 1e-9) * 100.0)


def transition_cost(a: Motion, a_frame: int, b: Motion, b_frame: int) -> float:
    """Pose distance between frame ``a_frame`` of ``a`` and frame ``b_frame`` of ``b``."""
    fa = pose_features(a.slice(max(0, a_frame - 1), a_frame + 2))
    fb = pose_features(b.slice(max(0, b_frame - 1), b_frame + 2))
    ia = min(1, a_frame)
    ib = min(1, b_frame)
    return float(pose_distance(fa[ia : ia + 1], fb[ib : ib + 1])[0, 0])
