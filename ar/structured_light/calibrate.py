"""Projector-camera calibration from Gray-code captures (Moreno & Taubin, 3DIMPVT 2012).

Method, per board pose (one folder of the sequence's captures):

1. decode every camera pixel's projector column and row (:mod:`ar.structured_light.decode`);
2. find the printed board's corners in the *white* capture (the board under full light);
3. **local homographies** -- around each corner, the decoded pixels within a square
   window (``window`` px either side) give camera -> projector pairs; a homography fitted
   to them (RANSAC, 1.5 px, then least squares on the inliers) carries the corner into the
   projector image at sub-pixel precision although each decoded code is a whole projector
   pixel. Lens distortion is what makes the map only *locally* a homography; when the
   camera's intrinsics are known the window's pixels are undistorted first, which leaves
   only the projector's (small) distortion inside the window. Corners with fewer than
   ``min_pixels`` decoded pixels around them (the board's black squares and shadows carry
   no code) or whose fit leaves the projector are skipped.

Then, over all poses: the camera's intrinsics (``cv2.calibrateCamera`` on the board
corners, unless given), the projector's (``cv2.calibrateCamera`` on board points ->
projector corners, the projector as an inverse camera, with one round of bad-pose
rejection), and ``cv2.stereoCalibrate`` with both intrinsics fixed for the rigid
camera -> projector transform ``x_p = R x_c + T`` (metres). The reported ``rms`` is
stereoCalibrate's, over both images; per-pose errors are each pose's camera and
projector reprojection RMS under that final model.

The file (``projector.json``) is a :class:`ar.calibration.ProjectorCalibration` file (the
rig loads it as it is) plus the camera's calibration, ``R``/``T`` and the per-pose figures.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import cv2
import numpy as np

from ar.boards import Board
from ar.calibration import (MIN_VIEW_POINTS, CameraCalibration, ProjectorCalibration, calibrate_from_correspondences,
                            validate_intrinsics)
from ar.errors import CalibrationError
from retrieval.durable import durable_write
from ar.structured_light.decode import (DEFAULT_BLACK_THRESHOLD, DEFAULT_WHITE_THRESHOLD, DecodedPose,
                                        decode_pose_folder, pose_folders)

DEFAULT_WINDOW_PX = 24
MIN_WINDOW_PIXELS = 40
#: camera and projector model: k1, k2, p1, p2 (k3 is fixed: a planar board in a few poses cannot
#: separate it, and a wild k3 bends the scan far from the board)
PROJECTOR_FLAGS = cv2.CALIB_FIX_K3
CAMERA_FLAGS = cv2.CALIB_FIX_K3


@dataclass
class PoseCorners:
    """One pose's board corners: board points (N,3), camera pixels (N,2), projector pixels (N,2)."""

    name: str
    object_points: np.ndarray
    camera_pixels: np.ndarray
    projector_pixels: np.ndarray
    board_points_seen: int  # corners found in the camera image (some may lack a projector point)


def _undistort(px: np.ndarray, camera: CameraCalibration | None) -> np.ndarray:
    if camera is None:
        return px
    return cv2.undistortPoints(px.reshape(-1, 1, 2).astype(np.float64), camera.camera_matrix, camera.dist_coeffs,
                               P=camera.camera_matrix).reshape(-1, 2)


def local_homography_corners(decoded: DecodedPose, corners: np.ndarray, camera: CameraCalibration | None = None,
                             window: int = DEFAULT_WINDOW_PX,
                             min_pixels: int = MIN_WINDOW_PIXELS) -> tuple[np.ndarray, np.ndarray]:
    """Projector pixel of each camera ``corners`` (N,2) by a local homography (module
    docstring); returns ``(projector_px (N,2), ok (N,) bool)``."""
    h, w = decoded.mask.shape
    # the projector's extent as decoded (a corner mapped outside the codes seen is refused)
    pw, ph = (int(decoded.col.max()) + 1, int(decoded.row.max()) + 1) if decoded.mask.any() else (0, 0)
    out = np.full((len(corners), 2), np.nan)
    ok = np.zeros(len(corners), bool)
    for i, (cx, cy) in enumerate(np.asarray(corners, np.float64)):
        x0, x1 = max(0, int(round(cx)) - window), min(w, int(round(cx)) + window + 1)
        y0, y1 = max(0, int(round(cy)) - window), min(h, int(round(cy)) + window + 1)
        if x1 <= x0 or y1 <= y0:
            continue
        ys, xs = np.nonzero(decoded.mask[y0:y1, x0:x1])
        if len(xs) < min_pixels:
            continue
        ys, xs = ys + y0, xs + x0
        cam = _undistort(np.stack([xs, ys], 1).astype(np.float64), camera)
        proj = np.stack([decoded.col[ys, xs], decoded.row[ys, xs]], 1).astype(np.float64)
        H, inliers = cv2.findHomography(cam, proj, cv2.RANSAC, 1.5)
        if H is None or inliers is None or int(inliers.sum()) < min_pixels:
            continue
        keep = inliers.ravel().astype(bool)
        H, _ = cv2.findHomography(cam[keep], proj[keep], 0)
        if H is None:
            continue
        c = _undistort(np.array([[cx, cy]]), camera)[0]
        p = H @ np.array([c[0], c[1], 1.0])
        if abs(p[2]) < 1e-12:
            continue
        p = p[:2] / p[2]
        if np.all(np.isfinite(p)) and -0.5 <= p[0] <= pw - 0.5 and -0.5 <= p[1] <= ph - 0.5:
            out[i], ok[i] = p, True
    return out, ok


def find_board(decoded: DecodedPose, board: Board):
    """The board's corners in the pose's white capture (then the black one); ``None`` when absent."""
    for image in (decoded.white, decoded.black):
        det = board.detect(image)
        if det is not None and det.n >= MIN_VIEW_POINTS:
            return det
    return None


def faint_light_reason(decoded: DecodedPose) -> str:
    """Why (almost) nothing decoded, with the figure that says which threshold to lower."""
    gain = np.percentile(decoded.white.astype(np.int16) - decoded.black.astype(np.int16), 90)
    return (f"only {100 * decoded.mask.mean():.1f} % of pixels decoded: the brightest tenth of the image gains "
            f"{gain:.0f} grey levels when the projector turns white -- a dim projector or a bright room; "
            f"lower --black-threshold below that (and --white-threshold if needed)")


def pose_corners(decoded: DecodedPose, board: Board, camera: CameraCalibration | None = None,
                 window: int = DEFAULT_WINDOW_PX) -> PoseCorners | str:
    """One pose's board corners with their projector pixels, or the reason the pose is unusable."""
    if decoded.mask.mean() < 0.01:
        return faint_light_reason(decoded)
    det = find_board(decoded, board)
    if det is None:
        return "board not found in the white (or black) capture"
    proj, ok = local_homography_corners(decoded, det.image_points, camera, window)
    if ok.sum() < MIN_VIEW_POINTS:
        return f"only {int(ok.sum())} of {det.n} board corners lie in decoded projector light"
    return PoseCorners(decoded.name, det.object_points[ok], det.image_points[ok], proj[ok], det.n)


@dataclass
class GrayCodeCalibration:
    """The calibrated pair: camera, projector (with ``R``, ``T``: ``x_p = R x_c + T``), and per-pose figures."""

    camera: CameraCalibration
    projector: ProjectorCalibration
    per_pose: dict[str, dict] = field(default_factory=dict)  # name -> camera_px, projector_px (RMS), corners
    rejected_poses: dict[str, str] = field(default_factory=dict)
    projector_rms: float = 0.0  # the projector-only intrinsic fit
    window_px: int = DEFAULT_WINDOW_PX
    board: str = ""  # the board spec the captures show

    @property
    def R(self) -> np.ndarray:
        return self.projector.R_proj_from_cam

    @property
    def T(self) -> np.ndarray:
        return self.projector.t_proj_from_cam

    @property
    def rms(self) -> float:
        return self.projector.rms

    def to_dict(self) -> dict:
        data = self.projector.to_dict()
        data.update({"method": "graycode (Moreno-Taubin local homographies)", "camera": self.camera.to_dict(),
                     "R": self.R.tolist(), "T": self.T.ravel().tolist(), "rms": float(self.rms),
                     "camera_rms": float(self.camera.rms), "projector_rms": float(self.projector_rms),
                     "per_pose": self.per_pose, "rejected_poses": self.rejected_poses, "window_px": self.window_px, "board": self.board})
        return data

    def save(self, path: str | Path) -> Path:
        """Write ``projector.json`` durably (a kill mid-save leaves the old file or the new one)."""
        try:
            return durable_write(Path(path), json.dumps(self.to_dict(), indent=2).encode("utf-8"))
        except OSError as exc:
            raise CalibrationError(f"cannot write: {exc.strerror or exc}", path) from None

    @classmethod
    def load(cls, path: str | Path) -> "GrayCodeCalibration":
        """Read a Gray-code ``projector.json`` (validated; errors name the file)."""
        projector = ProjectorCalibration.load(path)  # validates size, JSON, the projector and R, t
        data = json.loads(Path(path).read_text())
        if not isinstance(data.get("camera"), dict):
            raise CalibrationError("no 'camera' object: this projector.json was not written by "
                                   "`storybeam calibrate projector --graycode`", path)
        camera = CameraCalibration.from_dict(data["camera"], path)
        per_pose = data.get("per_pose", {})
        rejected = data.get("rejected_poses", {})
        if not isinstance(per_pose, dict) or not isinstance(rejected, dict):
            raise CalibrationError("per_pose and rejected_poses must be objects", path)
        return cls(camera, projector, per_pose, rejected, float(data.get("projector_rms", 0.0)),
                   int(data.get("window_px", DEFAULT_WINDOW_PX)), str(data.get("board", "")))


def _pose_rms(obj: np.ndarray, img: np.ndarray, R: np.ndarray, t: np.ndarray, K: np.ndarray, d: np.ndarray) -> float:
    proj, _ = cv2.projectPoints(obj, cv2.Rodrigues(R)[0], t, K, d)
    return float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img.reshape(-1, 2)) ** 2, 1))))


def calibrate_graycode(poses: Sequence[DecodedPose], board: Board, projector_size: tuple[int, int],
                       camera: CameraCalibration | None = None, window: int = DEFAULT_WINDOW_PX,
                       progress: Callable[[str], None] | None = None) -> GrayCodeCalibration:
    """Camera (unless given), projector and stereo calibration from decoded poses (module docstring)."""
    say = progress or (lambda _msg: None)
    if not poses:
        raise CalibrationError("no Gray-code poses given")
    size = poses[0].image_size
    for p in poses[1:]:
        if p.image_size != size:
            raise CalibrationError(f"pose {p.name}: images are {p.image_size[0]}x{p.image_size[1]}, pose "
                                   f"{poses[0].name}'s are {size[0]}x{size[1]}")
    rejected: dict[str, str] = {}
    if camera is None:
        names, obj, img = [], [], []
        for p in poses:
            det = find_board(p, board)
            if det is None:
                rejected[p.name] = "board not found in the white (or black) capture"
                continue
            names.append(p.name)
            obj.append(det.object_points)
            img.append(det.image_points)
        rms, K, d, errors, rej, _keep = calibrate_from_correspondences(names, obj, img, size, flags=CAMERA_FLAGS,
                                                                       what="camera")
        rejected.update(rej)
        camera = CameraCalibration(K, d.ravel(), size, rms, errors, rej, str(board.spec))
        say(f"camera: RMS {rms:.3f} px over {len(errors)} poses")
    elif tuple(camera.image_size) != tuple(size):
        raise CalibrationError(f"the camera calibration is for {camera.image_size[0]}x{camera.image_size[1]} images, "
                               f"the captures are {size[0]}x{size[1]}")
    views: list[PoseCorners] = []
    for p in poses:
        if p.name in rejected:
            continue
        found = pose_corners(p, board, camera, window)
        if isinstance(found, str):
            rejected[p.name] = found
        else:
            views.append(found)
            say(f"pose {p.name}: {len(found.object_points)} of {found.board_points_seen} corners in projector light")
    if len(views) < 3:
        reasons = "; ".join(f"{name}: {why}" for name, why in rejected.items())
        raise CalibrationError(f"only {len(views)} usable poses, at least 3 are needed ({reasons})")
    names = [v.name for v in views]
    prms, Kp, dp, _errors, rej, keep = calibrate_from_correspondences(
        names, [v.object_points for v in views], [v.projector_pixels for v in views], projector_size,
        reject_px=1.5, flags=PROJECTOR_FLAGS, what="projector")
    rejected.update(rej)
    views = [views[i] for i in keep]
    validate_intrinsics(Kp, dp, projector_size, None, what="projector")
    obj = [np.asarray(v.object_points, np.float32).reshape(-1, 1, 3) for v in views]
    cam_px = [np.asarray(v.camera_pixels, np.float32).reshape(-1, 1, 2) for v in views]
    proj_px = [np.asarray(v.projector_pixels, np.float32).reshape(-1, 1, 2) for v in views]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    out = cv2.stereoCalibrateExtended(obj, cam_px, proj_px, camera.camera_matrix, camera.dist_coeffs, Kp, dp, size,
                                      None, None, flags=cv2.CALIB_FIX_INTRINSIC, criteria=crit)
    stereo_rms, R, T = float(out[0]), out[5], out[6].ravel()
    rvecs, tvecs = out[9], out[10]
    per_pose = {}
    for v, rv, tv in zip(views, rvecs, tvecs):
        Rc = cv2.Rodrigues(rv)[0]
        tc = np.asarray(tv, np.float64).ravel()
        per_pose[v.name] = {
            "camera_px": _pose_rms(v.object_points, v.camera_pixels, Rc, tc, camera.camera_matrix, camera.dist_coeffs),
            "projector_px": _pose_rms(v.object_points, v.projector_pixels, R @ Rc, R @ tc + T, Kp, dp),
            "corners": int(len(v.object_points))}
    projector = ProjectorCalibration(Kp, dp.ravel(), tuple(int(v) for v in projector_size), R, T, stereo_rms,
                                     stereo_rms, {k: v["projector_px"] for k, v in per_pose.items()}, dict(rejected))
    return GrayCodeCalibration(camera, projector, per_pose, rejected, prms, window, str(board.spec))


def calibrate_graycode_folder(root: str | Path, board: Board, projector_size: tuple[int, int],
                              camera: CameraCalibration | None = None,
                              black_threshold: float = DEFAULT_BLACK_THRESHOLD,
                              white_threshold: float = DEFAULT_WHITE_THRESHOLD, window: int = DEFAULT_WINDOW_PX,
                              progress: Callable[[str], None] | None = None) -> GrayCodeCalibration:
    """:func:`calibrate_graycode` on a folder of pose folders (``DIR/<pose>/<images in sequence order>``)."""
    say = progress or (lambda _msg: None)
    poses = []
    folders = pose_folders(root)
    for i, folder in enumerate(folders):
        poses.append(decode_pose_folder(folder, projector_size, black_threshold, white_threshold))
        say(f"decoded {folder.name} ({i + 1}/{len(folders)}): {100 * poses[-1].mask.mean():.0f} % of pixels")
    return calibrate_graycode(poses, board, projector_size, camera, window, progress)
