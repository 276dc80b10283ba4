"""Following the board's corners between detections (pyramidal Lucas-Kanade, re-anchored by each).

A hand-held rig in classroom light loses the board's markers in many frames -- motion
blur, a dim table, a board small in the image -- while its corners stay plainly visible
and move only a few pixels from one frame to the next. :class:`CornerFlow` keeps the pose
through those frames:

1. **anchor** (every frame the detector posed the board): the detected corners, plus the
   board's other corners the pose puts inside the image (refined onto the image's X-corner
   with ``cv2.cornerSubPix`` and kept only when the refinement lands within
   ``max_snap_px`` of the projection -- a corner hidden by a hand or off the board's
   paper does not snap and is left out), with this grey frame;
2. **follow** (a frame the detector missed): every point is followed into the new frame by
   pyramidal Lucas-Kanade (``cv2.calcOpticalFlowPyrLK``), starting where the board's motion
   over the last two frames puts it (constant velocity), and back again; a point whose
   backward track misses its start by more than ``max_fb_px`` (the forward-backward check,
   Kalal et al., ICPR 2010) or that leaves the image is dropped. Corners of squares (ChArUco,
   checker) are then snapped onto the new frame's X-corner (``cornerSubPix``), so the points
   cannot drift along an edge frame after frame; the board's corners the followed pose
   puts in the image and that are not followed yet (uncovered again as a hand moves off)
   join the followed points when they snap onto an X-corner, as at anchoring;
3. **pose**: ``cv2.solvePnP`` (iterative, from the previous pose as the guess) on the
   followed points; points whose reprojection error exceeds ``max_point_px`` (and three
   times the median) are dropped and the pose solved again;
4. **refusal**: the followed pose is refused -- the follower resets and the rig reads the
   frame as lost -- when fewer than :data:`ar.pose.MIN_POINTS` points survive, the RMS
   reprojection error exceeds ``max_rms_px``, the pose jumps from the previous frame's by
   more than ``max_jump_deg`` / ``max_jump_m`` (a pose solved from slipped points flips or
   leaps; a hand does not move that far in one frame), the points landed more than
   ``max_surprise_squares`` of a square from where the motion put them (a board's corners
   repeat every square: followed that far from the guess, each may have slipped onto its
   neighbour, all alike, and a wrong pose would fit them well), or the points have been
   followed ``max_frames`` frames without a detection.

The rig's loop (:meth:`ar.rig.RigTracker.step`) detects first and follows only when the
detector found nothing, so a followed pose is always at most ``max_frames`` frames from a
detection, and detected frames cost only the anchoring (a copy and a few corner refinements).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ar.boards import Board, BoardDetection
from ar.geometry import from_rvec_tvec, invert, project_points
from ar.pose import MIN_POINTS, PoseEstimate, pose_estimate, reprojection_residuals


@dataclass
class FlowParams:
    """The follower's settings (pixels of the tracked frame; per frame for the jump limits)."""

    win_px: int = 15  # Lucas-Kanade window side
    levels: int = 3  # pyramid levels above the frame (4 images: motion up to ~8 x win/2 px)
    max_fb_px: float = 1.0  # forward-backward error above which a point is dropped
    max_snap_px: float = 1.5  # how far cornerSubPix may move a point (anchoring and following)
    max_point_px: float = 3.0  # a point's reprojection error above which it is dropped
    max_rms_px: float = 2.0  # the followed pose's RMS reprojection error above which it is refused
    max_jump_deg: float = 8.0  # rotation between two consecutive frames' poses above which it is refused
    max_jump_m: float = 0.04  # translation likewise
    max_frames: int = 150  # frames followed without a detection (5 s at 30 fps)
    max_surprise_squares: float = 0.5  # median distance from the motion's guess, in squares


class CornerFlow:
    """Board pose between detections from corners followed frame to frame (module docstring).

    One camera's frames in order: :meth:`anchor` after each detection, :meth:`follow` on a
    frame the detector missed, :meth:`reset` when the pose is lost otherwise."""

    def __init__(self, board: Board, K: np.ndarray, dist: np.ndarray, params: FlowParams | None = None):
        self.board = board
        self.K = np.asarray(K, np.float64)
        self.dist = np.asarray(dist, np.float64).ravel()
        self.p = params or FlowParams()
        #: X-corners (ChArUco and checker corners) are snapped back onto the image after each step
        self.snaps = board.spec.kind in ("charuco", "checker")
        self.last_refusal = ""
        self.reset()

    def reset(self) -> None:
        """Forget the anchored points (nothing is followed until the next :meth:`anchor`)."""
        self._gray: np.ndarray | None = None
        self._img = np.zeros((0, 2), np.float32)
        self._obj = np.zeros((0, 3))
        self._ids = np.zeros(0, np.int64)
        self._T: np.ndarray | None = None
        self._velocity = np.eye(4)  # T_now @ inv(T_before) of the last two consecutive frames
        self._followed = 0

    @property
    def active(self) -> bool:
        """Whether there are points to follow."""
        return self._gray is not None and len(self._img) >= MIN_POINTS

    @property
    def frames_followed(self) -> int:
        """Frames followed since the last detection."""
        return self._followed

    # ------------------------------------------------------------------ anchoring
    def anchor(self, gray: np.ndarray, estimate: PoseEstimate) -> None:
        """Take a detected pose and this (grey) frame as the new start: the detected corners and
        the other board corners the pose puts in the image that snap onto an X-corner."""
        det = estimate.detection
        img, obj, ids = det.image_points.astype(np.float32), det.object_points, det.ids
        if self.snaps:
            extra = self._snapped_board_corners(gray, estimate.T_cam_from_board, set(ids.tolist()))
            if extra is not None:
                img = np.vstack([img, extra[0]])
                obj = np.vstack([obj, extra[1]])
                ids = np.concatenate([ids, extra[2]])
        T = estimate.T_cam_from_board
        self._velocity = T @ invert(self._T) if self._T is not None else np.eye(4)
        self._gray = gray
        self._img, self._obj, self._ids = img.reshape(-1, 2).astype(np.float32), obj, ids
        self._T = T.copy()
        self._followed = 0

    def _snapped_board_corners(self, gray: np.ndarray, T: np.ndarray, known: set):
        all_obj = self.board.all_object_points
        missing = np.array([i for i in range(len(all_obj)) if i not in known], np.int64)
        if not len(missing):
            return None
        px = project_points(all_obj[missing], T, self.K, self.dist).reshape(-1, 2)
        h, w = gray.shape[:2]
        half = self._snap_half_window(px, T)
        inside = np.all((px >= half + 1) & (px < np.array([w, h]) - half - 1), axis=1) & np.isfinite(px).all(1)
        if not inside.any():
            return None
        px, missing = px[inside].astype(np.float32), missing[inside]
        snapped = self._snap(gray, px, half)
        ok = np.linalg.norm(snapped - px, axis=1) <= self.p.max_snap_px
        if not ok.any():
            return None
        return snapped[ok], all_obj[missing[ok]], missing[ok]

    def _square_px(self, T: np.ndarray) -> float:
        """About how many pixels a square of the board spans at pose ``T``."""
        return float(self.K[0, 0] * self.board.spec.square_m / max(float(T[2, 3]), 1e-6))

    def _snap_half_window(self, px: np.ndarray, T: np.ndarray) -> int:
        """cornerSubPix half-window: a quarter of a square's size in the image, 2 to 5 px."""
        return int(np.clip(self._square_px(T) * 0.25, 2, 5))

    def _snap(self, gray: np.ndarray, px: np.ndarray, half: int) -> np.ndarray:
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.01)
        return cv2.cornerSubPix(gray, px.reshape(-1, 1, 2).copy(), (half, half), (-1, -1), crit).reshape(-1, 2)

    # ------------------------------------------------------------------ following
    def follow(self, gray: np.ndarray) -> PoseEstimate | None:
        """This frame's pose from the followed points, or ``None`` (refused; the reason in
        :attr:`last_refusal`; the follower is reset)."""
        if not self.active:
            self.last_refusal = "nothing to follow"
            return None
        if self._followed >= self.p.max_frames:
            return self._refuse(f"followed {self._followed} frames without a detection")
        p = self.p
        h, w = gray.shape[:2]
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01)
        p0 = self._img.reshape(-1, 1, 2)
        guess = project_points(self._obj, self._velocity @ self._T, self.K, self.dist).reshape(-1, 2)
        guess = np.where(np.isfinite(guess).all(1, keepdims=True), guess, self._img).astype(np.float32)
        flags = cv2.OPTFLOW_USE_INITIAL_FLOW
        p1, st, _ = cv2.calcOpticalFlowPyrLK(self._gray, gray, p0, guess.reshape(-1, 1, 2).copy(),
                                             winSize=(p.win_px, p.win_px), maxLevel=p.levels, criteria=crit,
                                             flags=flags)
        p1 = p1.reshape(-1, 2)
        back_guess = (p1 + (self._img - guess)).astype(np.float32).reshape(-1, 1, 2)  # the guessed motion, undone
        back, st_b, _ = cv2.calcOpticalFlowPyrLK(gray, self._gray, p1.reshape(-1, 1, 2).astype(np.float32),
                                                 back_guess, winSize=(p.win_px, p.win_px), maxLevel=p.levels,
                                                 criteria=crit, flags=flags)
        back = back.reshape(-1, 2)
        fb = np.linalg.norm(back - self._img, axis=1)
        keep = (st.ravel() == 1) & (st_b.ravel() == 1) & (fb <= p.max_fb_px) & np.isfinite(p1).all(1)
        keep &= np.all((p1 >= 2) & (p1 < np.array([w, h]) - 3), axis=1)
        if keep.sum() < MIN_POINTS:
            return self._refuse(f"{int(keep.sum())} points passed the forward-backward check")
        square_px = self._square_px(self._T)
        surprise = float(np.median(np.linalg.norm(p1[keep] - guess[keep], axis=1)))
        if surprise > p.max_surprise_squares * square_px:
            return self._refuse(f"points {surprise:.1f} px from the motion's guess (a square is {square_px:.1f} px)")
        img, obj, ids = p1[keep], self._obj[keep], self._ids[keep]
        if self.snaps:
            corner = ids < len(self.board.all_object_points)  # square corners, not marker corners
            if corner.any():
                half = self._snap_half_window(img, self._T)
                inner = corner & np.all((img >= half + 1) & (img < np.array([w, h]) - half - 1), axis=1)
                if inner.any():
                    snapped = self._snap(gray, img[inner].astype(np.float32), half)
                    moved = np.linalg.norm(snapped - img[inner], axis=1) <= p.max_snap_px
                    rows = np.flatnonzero(inner)
                    img[rows[moved]] = snapped[moved]
        estimate = self._solve(img, obj, ids)
        if estimate is None:
            return None
        followed = self._followed + 1
        self.anchor(gray, estimate)  # corners uncovered again (a hand moving off) join from this pose
        self._followed = followed
        return estimate

    def _solve(self, img: np.ndarray, obj: np.ndarray, ids: np.ndarray) -> PoseEstimate | None:
        p = self.p
        total = len(self.board.all_object_points)
        T_prev = self._T
        rvec0, _ = cv2.Rodrigues(np.ascontiguousarray(T_prev[:3, :3]))
        tvec0 = T_prev[:3, 3].reshape(3, 1).copy()
        T = None
        for _ in range(2):  # solve, drop the points that disagree, solve again
            if len(img) < MIN_POINTS:
                return self._refuse(f"{len(img)} points agree with the pose")
            ok, rvec, tvec = cv2.solvePnP(obj.reshape(-1, 1, 3), img.reshape(-1, 1, 2).astype(np.float64), self.K,
                                          self.dist, rvec0.copy(), tvec0.copy(), useExtrinsicGuess=True,
                                          flags=cv2.SOLVEPNP_ITERATIVE)
            if not ok:
                return self._refuse("solvePnP failed")
            T = from_rvec_tvec(rvec, tvec)
            res = reprojection_residuals(T, BoardDetection(obj, img, ids, total), self.K, self.dist)
            bad = (res > p.max_point_px) & (res > 3 * np.median(res))
            if not bad.any():
                break
            img, obj, ids = img[~bad], obj[~bad], ids[~bad]
        detection = BoardDetection(obj, img.astype(np.float64), ids, total)
        if len(img) < MIN_POINTS:
            return self._refuse(f"{len(img)} points agree with the pose")
        estimate = pose_estimate(T, detection, self.K, self.dist, p.max_rms_px)
        if estimate is None:
            return self._refuse("reprojection error over the limit")
        deg, metres = pose_change(T_prev, T)
        if deg > p.max_jump_deg or metres > p.max_jump_m:
            return self._refuse(f"pose jumped {deg:.1f} deg, {metres * 1000:.0f} mm in one frame")
        return estimate

    def _refuse(self, why: str) -> None:
        self.last_refusal = why
        self.reset()
        return None


def pose_change(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """(degrees, metres) between two ``T_cam_from_board``: the relative rotation's angle and
    how far the camera's centre moved over the board (in the board frame, so that a turn
    of the hand about the camera does not read as a leap of the board)."""
    rvec, _ = cv2.Rodrigues(np.ascontiguousarray(T_a[:3, :3].T @ T_b[:3, :3]))
    centre_a = -T_a[:3, :3].T @ T_a[:3, 3]
    centre_b = -T_b[:3, :3].T @ T_b[:3, 3]
    return math.degrees(float(np.linalg.norm(rvec))), float(np.linalg.norm(centre_b - centre_a))


__all__ = ["FlowParams", "CornerFlow", "pose_change"]
