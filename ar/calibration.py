"""Camera and projector-camera calibration, with validated JSON files.

Camera
    ``calibrate_camera`` detects the board in each view, runs ``cv2.calibrateCamera``,
    computes each view's reprojection RMS, drops views that fail detection, have too
    few points, or fit much worse than the others (> ``max(reject_px, 3 x median)``),
    and recalibrates on the rest.

Projector (an inverse camera)
    Method: *structured pattern lifted onto the board plane*. For each rig pose the
    projector shows three images -- dark, full white, and a checkerboard with a white
    surround (:func:`make_projector_pattern`). From the camera frames:

    1. the printed board is detected in the *dark* frame -> ``T_cam_from_board``;
    2. the ratio image ``(pattern - dark) / (white - dark)`` removes the table's and
       board's albedo and the ambient light, leaving the projected checkerboard alone;
       its corners are found with ``findChessboardCornersSB`` (full pattern required);
    3. each corner pixel is lifted onto the table plane (ray-plane intersection through
       the camera intrinsics and ``T_cam_from_board``), giving 3-D table points whose
       projector pixels are known (we drew them).

    Over several poses (tilted differently, :class:`ProjectorCalibrationSequence`),
    ``cv2.calibrateCamera`` on (table point, projector pixel) pairs gives the projector
    intrinsics, and ``cv2.stereoCalibrate`` with fixed intrinsics on (table point,
    camera pixel, projector pixel) gives the rigid ``T_proj_from_cam``.

Files are validated on load (shapes, finite values, plausible focal lengths and
principal points); problems raise :class:`ar.errors.CalibrationError` naming the file.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Iterator, Sequence

import cv2
import numpy as np

from ar.boards import Board
from ar.errors import CalibrationError
from ar.geometry import look_at, make_transform, pixels_to_plane, pose_error, project_points
from ar.pose import solve_board_pose
from retrieval.durable import durable_write

MIN_VIEW_POINTS = 8
#: Calibration files are a few kB; anything over this is refused before it is read.
MAX_CALIBRATION_BYTES = 1024 * 1024
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


# ============================================================================ files
def _as_array(data: dict, key: str, path: str | None, shape: tuple[int, ...] | None = None) -> np.ndarray:
    if key not in data:
        raise CalibrationError(f"missing key {key!r}", path)
    try:
        arr = np.asarray(data[key], dtype=np.float64)
    except (TypeError, ValueError, OverflowError):  # OverflowError: a 400-digit JSON integer
        raise CalibrationError(f"{key} must be numbers", path) from None
    if shape is not None and arr.shape != shape:
        raise CalibrationError(f"{key} must have shape {shape}, got {arr.shape}", path)
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{key} contains non-finite values", path)
    return arr


def validate_intrinsics(K: np.ndarray, dist: np.ndarray, image_size: Sequence[int], path: str | None = None,
                        what: str = "camera") -> None:
    """Reject intrinsics no real camera or projector has (raises :class:`CalibrationError`)."""
    K = np.asarray(K, np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        raise CalibrationError(f"{what} camera_matrix must be a finite 3x3 matrix", path)
    w, h = (int(v) for v in image_size)
    if w <= 0 or h <= 0:
        raise CalibrationError(f"{what} image_size must be positive, got {w}x{h}", path)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    # field of view between ~5 and ~160 degrees across the width
    if not (0.09 * w <= fx <= 12.0 * w and 0.09 * w <= fy <= 12.0 * w):
        raise CalibrationError(f"{what} focal lengths fx={fx:g}, fy={fy:g} are implausible for a {w}x{h} image", path)
    if not (0.5 < fx / fy < 2.0):
        raise CalibrationError(f"{what} aspect fx/fy={fx / fy:g} is implausible", path)
    if not (-0.5 * w <= cx <= 1.5 * w and -1.0 * h <= cy <= 2.0 * h):  # projectors have lens shift
        raise CalibrationError(f"{what} principal point ({cx:g}, {cy:g}) is far outside the {w}x{h} image", path)
    if abs(K[0, 1]) > 1e-6 * fx + 1e-9 or np.any(K[2] != [0, 0, 1]) or K[1, 0] != 0:
        raise CalibrationError(f"{what} camera_matrix must look like [[fx,0,cx],[0,fy,cy],[0,0,1]]", path)
    dist = np.asarray(dist, np.float64).ravel()
    if dist.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(dist)):
        raise CalibrationError(f"{what} dist_coeffs must be 4, 5, 8, 12 or 14 finite numbers, got {dist.size}", path)
    if np.any(np.abs(dist) > 100):
        raise CalibrationError(f"{what} dist_coeffs {dist.tolist()} are implausibly large", path)


def _optional_dict(data: dict, key: str, path: str | None) -> dict:
    """An optional diagnostic mapping (``per_view_errors``...): absent -> {}, else a dict."""
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise CalibrationError(f"{key} must be an object, got {type(value).__name__}", path)
    return dict(value)


def _read_json(path: str | Path) -> dict:
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_CALIBRATION_BYTES:
            raise CalibrationError(f"file is {size / 2**20:.1f} MB, more than the "
                                   f"{MAX_CALIBRATION_BYTES // 2**20} MB a calibration file can be", path)
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise CalibrationError("file not found", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"cannot read: {exc}", path) from None
    except json.JSONDecodeError as exc:
        raise CalibrationError(f"not valid JSON (line {exc.lineno}: {exc.msg})", path) from None
    except RecursionError:
        raise CalibrationError("not valid JSON (nested too deeply)", path) from None
    if not isinstance(data, dict):
        raise CalibrationError("expected a JSON object at top level", path)
    return data


def _save_json(path: str | Path, data: dict) -> Path:
    """Write a calibration dict as JSON (making its folder) durably and atomically
    (:func:`retrieval.durable.durable_write`: a temporary file fsynced, renamed over the
    old one, the folder fsynced), so a kill or power cut during a save leaves the old
    calibration or the new one, never an empty or partial file; returns the path."""
    path = Path(path)
    try:
        return durable_write(path, json.dumps(data, indent=2).encode("utf-8"))
    except OSError as exc:
        raise CalibrationError(f"cannot write: {exc.strerror or exc}", path) from None


@dataclass
class CameraCalibration:
    """Pinhole + distortion model of the rig camera."""

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    image_size: tuple[int, int]  # (width, height)
    rms: float
    per_view_errors: dict[str, float] = field(default_factory=dict)
    rejected_views: dict[str, str] = field(default_factory=dict)  # name -> reason
    board: str = ""

    def to_dict(self) -> dict:
        return {"camera_matrix": self.camera_matrix.tolist(), "dist_coeffs": self.dist_coeffs.ravel().tolist(),
                "image_size": list(self.image_size), "rms": float(self.rms), "board": self.board,
                "per_view_errors": self.per_view_errors, "rejected_views": self.rejected_views}

    def save(self, path: str | Path) -> Path:
        return _save_json(path, self.to_dict())

    @classmethod
    def from_dict(cls, data: dict, path: str | Path | None = None) -> "CameraCalibration":
        p = str(path) if path is not None else None
        K = _as_array(data, "camera_matrix", p, (3, 3))
        dist = _as_array(data, "dist_coeffs", p).ravel()
        size = _as_array(data, "image_size", p, (2,))
        rms = float(_as_array(data, "rms", p, ()))
        if rms < 0:
            raise CalibrationError(f"rms must be >= 0, got {rms}", p)
        validate_intrinsics(K, dist, size, p)
        return cls(K, dist, (int(size[0]), int(size[1])), rms, _optional_dict(data, "per_view_errors", p),
                   _optional_dict(data, "rejected_views", p), str(data.get("board", "")))

    @classmethod
    def load(cls, path: str | Path) -> "CameraCalibration":
        """Read and validate a camera.json (raises :class:`CalibrationError` naming the file)."""
        return cls.from_dict(_read_json(path), path)


@dataclass
class ProjectorCalibration:
    """Projector intrinsics (inverse camera) and the rigid camera -> projector transform."""

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    image_size: tuple[int, int]
    R_proj_from_cam: np.ndarray
    t_proj_from_cam: np.ndarray  # metres
    rms: float  # projector reprojection RMS (px)
    stereo_rms: float = 0.0
    per_view_errors: dict[str, float] = field(default_factory=dict)
    rejected_views: dict[str, str] = field(default_factory=dict)

    @property
    def T_proj_from_cam(self) -> np.ndarray:
        return make_transform(self.R_proj_from_cam, self.t_proj_from_cam)

    def to_dict(self) -> dict:
        return {"projector": {"camera_matrix": self.camera_matrix.tolist(),
                              "dist_coeffs": self.dist_coeffs.ravel().tolist(),
                              "image_size": list(self.image_size)},
                "proj_from_cam": {"R": self.R_proj_from_cam.tolist(), "t": self.t_proj_from_cam.ravel().tolist()},
                "rms": float(self.rms), "stereo_rms": float(self.stereo_rms),
                "per_view_errors": self.per_view_errors, "rejected_views": self.rejected_views}

    def save(self, path: str | Path) -> Path:
        return _save_json(path, self.to_dict())

    @classmethod
    def from_dict(cls, data: dict, path: str | Path | None = None) -> "ProjectorCalibration":
        p = str(path) if path is not None else None
        for key in ("projector", "proj_from_cam"):
            if not isinstance(data.get(key), dict):
                raise CalibrationError(f"missing object {key!r}", p)
        proj, ext = data["projector"], data["proj_from_cam"]
        K = _as_array(proj, "camera_matrix", p, (3, 3))
        dist = _as_array(proj, "dist_coeffs", p).ravel()
        size = _as_array(proj, "image_size", p, (2,))
        validate_intrinsics(K, dist, size, p, what="projector")
        R = _as_array(ext, "R", p, (3, 3))
        t = _as_array(ext, "t", p, (3,))
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-4 or np.linalg.det(R) < 0.99:
            raise CalibrationError("proj_from_cam.R is not a rotation matrix", p)
        if np.linalg.norm(t) > 2.0:
            raise CalibrationError(f"proj_from_cam.t = {t.tolist()} m puts the projector over 2 m from the camera", p)
        rms = float(_as_array(data, "rms", p, ()))
        stereo_rms = float(_as_array(data, "stereo_rms", p, ())) if "stereo_rms" in data else 0.0
        return cls(K, dist, (int(size[0]), int(size[1])), R, t, rms, stereo_rms,
                   _optional_dict(data, "per_view_errors", p), _optional_dict(data, "rejected_views", p))

    @classmethod
    def load(cls, path: str | Path) -> "ProjectorCalibration":
        """Read and validate a projector.json (raises :class:`CalibrationError` naming the file)."""
        return cls.from_dict(_read_json(path), path)


# ============================================================================ camera
def load_images(folder: str | Path, pattern: str = "*") -> list[tuple[str, np.ndarray]]:
    """All images in a folder, sorted by name, as (name, BGR image)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CalibrationError("image folder not found", folder)
    out = []
    for f in sorted(folder.glob(pattern)):
        if f.suffix.lower() in IMAGE_SUFFIXES:
            img = cv2.imread(str(f), cv2.IMREAD_COLOR)
            if img is None:
                raise CalibrationError("cannot decode image", f)
            out.append((f.name, img))
    if not out:
        raise CalibrationError(f"no images ({', '.join(IMAGE_SUFFIXES)}) found", folder)
    return out


def capture_from_camera(index: int, n_views: int, board: Board, interval_s: float = 1.0) -> list[tuple[str, np.ndarray]]:
    """Grab ``n_views`` frames in which the board is detected from a live camera.

    Frames at least ``interval_s`` apart are kept so the user can move the board between
    them. (Headless: no preview window; the app provides the guided UI.)
    """
    cap = cv2.VideoCapture(index)
    if not cap.isOpened():
        raise CalibrationError(f"cannot open camera {index}")
    views, last = [], 0.0
    try:
        while len(views) < n_views:
            ok, frame = cap.read()
            if not ok:
                raise CalibrationError(f"camera {index} stopped delivering frames")
            det = board.detect(frame)
            now = time.monotonic()
            if det is not None and det.n >= MIN_VIEW_POINTS and now - last >= interval_s:
                views.append((f"live_{len(views):02d}", frame))
                last = now
    finally:
        cap.release()
    return views


def _view_rms(obj, img, rvec, tvec, K, dist) -> float:
    proj, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    return float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img.reshape(-1, 2)) ** 2, 1))))


def _calibrate_views(obj: list, img: list, size: tuple[int, int], flags: int, K0=None):
    K0 = None if K0 is None else K0.copy()
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, size, K0, None, flags=flags)
    errs = [_view_rms(o, i, r, t, K, dist) for o, i, r, t in zip(obj, img, rvecs, tvecs)]
    return rms, K, dist, rvecs, tvecs, errs


def calibrate_from_correspondences(names: list[str], obj: list[np.ndarray], img: list[np.ndarray],
                                   size: tuple[int, int], reject_px: float = 1.0, flags: int = 0,
                                   what: str = "camera", K0: np.ndarray | None = None) -> tuple[float, np.ndarray, np.ndarray, dict, dict, list]:
    """calibrateCamera with one round of bad-view rejection. Returns (rms, K, dist, errors, rejected, kept_indices)."""
    if len(obj) < 3:
        raise CalibrationError(f"{what} calibration needs at least 3 usable views, got {len(obj)}")
    obj = [np.asarray(o, np.float32).reshape(-1, 1, 3) for o in obj]
    img = [np.asarray(i, np.float32).reshape(-1, 1, 2) for i in img]
    rms, K, dist, _r, _t, errs = _calibrate_views(obj, img, size, flags, K0)
    limit = max(reject_px, 3.0 * float(np.median(errs)))
    keep = [i for i, e in enumerate(errs) if e <= limit]
    rejected = {names[i]: f"reprojection {errs[i]:.2f} px > {limit:.2f} px" for i in range(len(errs)) if i not in keep}
    if rejected and len(keep) >= 3:
        rms, K, dist, _r, _t, errs_k = _calibrate_views([obj[i] for i in keep], [img[i] for i in keep], size, flags, K0)
        errors = {names[i]: float(e) for i, e in zip(keep, errs_k)}
    else:
        keep = list(range(len(obj)))
        rejected = {}
        errors = {n: float(e) for n, e in zip(names, errs)}
    return float(rms), K, dist, errors, rejected, keep


def calibrate_camera(views: Iterable[tuple[str, np.ndarray]], board: Board, reject_px: float = 1.0,
                     flags: int = 0) -> CameraCalibration:
    """Intrinsics and distortion from several views of ``board`` (see module docstring)."""
    names, obj, img, rejected = [], [], [], {}
    size = None
    for name, image in views:
        h, w = image.shape[:2]
        if size is None:
            size = (w, h)
        elif size != (w, h):
            raise CalibrationError(f"{name}: image size {w}x{h} differs from the first image's {size[0]}x{size[1]}")
        det = board.detect(image)
        if det is None:
            rejected[name] = "board not detected"
        elif det.n < MIN_VIEW_POINTS:
            rejected[name] = f"only {det.n} board points"
        else:
            names.append(name)
            obj.append(det.object_points)
            img.append(det.image_points)
    if size is None:
        raise CalibrationError("no images given")
    rms, K, dist, errors, rejected_fit, _keep = calibrate_from_correspondences(names, obj, img, size, reject_px, flags)
    rejected.update(rejected_fit)
    return CameraCalibration(K, dist.ravel(), size, rms, errors, rejected, str(board.spec))


# ============================================================================ projector
@dataclass
class ProjectorPattern:
    """The images the projector shows during calibration, and the pattern's corner pixels."""

    dark: np.ndarray
    white: np.ndarray
    pattern: np.ndarray
    corners: np.ndarray  # (N,2) projector pixels, in findChessboardCornersSB order
    inner: tuple[int, int]  # (cols, rows) inner corners
    centre: tuple[float, float]  # requested pattern centre (projector px), to recreate it from a capture log


def make_projector_pattern(size: tuple[int, int], inner: tuple[int, int] = (9, 6), fill: float = 0.45,
                           centre: tuple[float, float] | None = None) -> ProjectorPattern:
    """A checkerboard of ``fill`` x the projector image, centred at pixel ``centre``, on a white surround.

    The surround gives ``findChessboardCornersSB`` its quiet zone; 9 x 6 inner corners
    (odd + even) make the pattern's orientation unambiguous. Moving ``centre`` between
    steps places the pattern beside the printed board and spreads the corners over the
    whole projector image (which constrains the principal point and distortion).
    """
    w, h = size
    cols, rows = inner
    sq = int(min(fill * w / (cols + 1), fill * h / (rows + 1)))
    pw, ph = sq * (cols + 1), sq * (rows + 1)
    cx, cy = centre if centre is not None else (w / 2, h / 2)
    x0 = int(np.clip(round(cx - pw / 2), sq // 2, w - pw - sq // 2))
    y0 = int(np.clip(round(cy - ph / 2), sq // 2, h - ph - sq // 2))
    pattern = np.full((h, w), 255, np.uint8)
    for j in range(rows + 1):
        for i in range(cols + 1):
            if (i + j) % 2 == 0:
                pattern[y0 + j * sq:y0 + (j + 1) * sq, x0 + i * sq:x0 + (i + 1) * sq] = 0
    xs, ys = np.meshgrid(np.arange(1, cols + 1), np.arange(1, rows + 1))
    corners = np.stack([x0 + xs.ravel() * sq - 0.5, y0 + ys.ravel() * sq - 0.5], 1).astype(np.float64)
    return ProjectorPattern(np.zeros((h, w), np.uint8), np.full((h, w), 255, np.uint8), pattern, corners, inner,
                            (float(cx), float(cy)))


def place_pattern(step: "CaptureStep", T_cam_from_board: np.ndarray, proj_from_cam_guess: np.ndarray,
                  projector_K_guess: np.ndarray, projector_size: tuple[int, int],
                  inner: tuple[int, int] = (9, 6)) -> ProjectorPattern:
    """The pattern for ``step``, placed so it lands on the table at ``step.pattern_target_m``.

    Placement only needs a rough projector model (nominal values, or the previous
    estimate): the calibration uses the corners' exact projector pixels, whatever they
    are, so placement error costs nothing but coverage.
    """
    q = project_points(np.append(step.pattern_target_m, 0.0)[None], proj_from_cam_guess @ T_cam_from_board,
                       projector_K_guess)[0]
    return make_projector_pattern(projector_size, inner, centre=(float(q[0]), float(q[1])))


def detect_projected_corners(dark: np.ndarray, white: np.ndarray, pattern_frame: np.ndarray,
                             pattern: ProjectorPattern, smooth_sigma: float = 1.0) -> np.ndarray | None:
    """Camera pixels of the projected checkerboard corners (full pattern) or ``None``.

    The ratio ``(pattern - dark) / (white - dark)`` cancels albedo and ambient light, so
    the printed board under the projection does not confuse the corner finder.
    """
    g = [cv2.cvtColor(f, cv2.COLOR_BGR2GRAY).astype(np.float32) if f.ndim == 3 else f.astype(np.float32)
         for f in (dark, white, pattern_frame)]
    lit = g[1] - g[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(lit > 8.0, (g[2] - g[0]) / lit, 1.0)
    ratio_f = np.clip(ratio, 0, 1).astype(np.float32)
    ratio = (ratio_f * 255.0 + 0.5).astype(np.uint8)
    # dividing by a dim "white" amplifies noise: smooth a little before the sub-pixel refinement
    if smooth_sigma > 0:
        ratio_f = cv2.GaussianBlur(ratio_f, (0, 0), smooth_sigma)
    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    found, corners = cv2.findChessboardCornersSB(ratio, pattern.inner, flags=flags)
    if not found or corners is None or len(corners) != len(pattern.corners):
        return None
    corners = corners.reshape(-1, 1, 2).astype(np.float32)
    # saddle-point refinement on the float ratio image (window scaled to the square size)
    side = float(np.median(np.linalg.norm(np.diff(corners.reshape(pattern.inner[1], pattern.inner[0], 2), axis=1), axis=-1)))
    win = int(np.clip(side * 0.35, 3, 15))
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    corners = cv2.cornerSubPix(ratio_f, corners, (win, win), (-1, -1), crit)
    corners = corners.reshape(-1, 2).astype(np.float64)
    # same 180-degree ambiguity as a printed checkerboard: pattern corner 0 is next to a black square
    H, _ = cv2.findHomography(pattern.corners, corners)
    if H is not None:
        sq = pattern.corners[1, 0] - pattern.corners[0, 0]
        probes = np.array([[pattern.corners[0] - sq / 2], [pattern.corners[0] + [sq / 2, -sq / 2]]])
        pts = cv2.perspectiveTransform(probes, H).reshape(-1, 2)
        hh, ww = ratio.shape
        vals = [float(ratio[int(np.clip(round(y), 0, hh - 1)), int(np.clip(round(x), 0, ww - 1))]) for x, y in pts]
        if vals[0] > vals[1]:
            corners = corners[::-1].copy()
    return corners


@dataclass
class CaptureStep:
    """One guided capture: where to hold the rig, and which projector images to show."""

    index: int
    instruction: str
    tilt_deg: float  # angle of the camera's view from vertical
    azimuth_deg: float  # direction the rig leans toward, around the board
    distance_m: float
    pattern_target_m: np.ndarray  # (x, y) table point, board frame, where the pattern should land
    aim_m: np.ndarray  # (x, y) table point the camera should look at (between board and pattern)
    up_board: np.ndarray  # board-frame direction that should appear up in the camera image
    shows: tuple[str, ...] = ("dark", "white", "pattern")

    def file_name(self, shown: str, suffix: str = ".png") -> str:
        return f"step_{self.index:02d}_{shown}{suffix}"


class ProjectorCalibrationSequence:
    """The guided capture sequence: yields :class:`CaptureStep` s the app (or the synthetic rig) drives.

    Each step puts the projected checkerboard *beside* the printed board (on one of its
    four sides, in turn), so the ink of the board does not hide projected corners, and
    varies the tilt and lean direction (varied views constrain the projector's focal
    length and principal point). The camera aims between board and pattern so both are
    in view.
    """

    def __init__(self, board: Board, n_steps: int = 8, distance_m: float = 0.55, max_tilt_deg: float = 30.0,
                 gap_m: float = 0.11):
        self.board = board
        self.n_steps = n_steps
        self.distance_m = distance_m
        self.max_tilt_deg = max_tilt_deg
        self.gap_m = gap_m

    def __iter__(self) -> Iterator[CaptureStep]:
        c = self.board.centre[:2]
        half = np.array(self.board.sheet_size_m) / 2
        sides = [np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.array([-1.0, 0.0]), np.array([0.0, -1.0])]
        names = {0: "right of", 1: "below", 2: "left of", 3: "above"}
        for i in range(self.n_steps):
            k = i % 4
            s = sides[k]
            target = c + s * (float(np.abs(s) @ half) + self.gap_m)
            aim = (c + target) / 2
            tilt = self.max_tilt_deg * (0.35 + 0.65 * ((i // 4) % 2))
            az = 90.0 * k + 45.0 * (1 + (i // 4) % 2) + 20.0 * (i // 8)
            dist = self.distance_m * (0.92 + 0.16 * ((i // 2) % 2))
            up = np.array([-s[1], s[0], 0.0])  # board->pattern runs along the image's long side
            text = (f"Step {i + 1}/{self.n_steps}: the projected checkerboard lands {names[k]} the board; hold the "
                    f"rig about {dist * 100:.0f} cm above the table, tilted {tilt:.0f} degrees, so board and "
                    f"checkerboard are both in view; hold still for three flashes (dark, white, pattern).")
            yield CaptureStep(i, text, tilt, az, dist, target, aim, up)

    def __len__(self) -> int:
        return self.n_steps


def rig_pose_for_step(step: CaptureStep) -> np.ndarray:
    """A ``T_cam_from_board`` realising ``step`` (used by the synthetic rig; a person follows the text)."""
    a, t = np.radians(step.azimuth_deg), np.radians(step.tilt_deg)
    aim = np.append(step.aim_m, 0.0)
    eye = aim + step.distance_m * np.array([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), -np.cos(t)])
    return look_at(eye, aim, step.up_board)


@dataclass
class ProjectorViewData:
    """Correspondences from one capture step."""

    name: str
    table_points: np.ndarray  # (N,3) board frame, z = 0
    camera_pixels: np.ndarray  # (N,2)
    projector_pixels: np.ndarray  # (N,2)


def extract_projector_view(name: str, frames: dict[str, np.ndarray], board: Board, camera: CameraCalibration,
                           pattern: ProjectorPattern) -> ProjectorViewData | str:
    """Correspondences from one step's frames, or a reason string when the step is unusable."""
    det = board.detect(frames["dark"])
    if det is None:
        return "printed board not detected in the dark frame"
    est = solve_board_pose(det, camera.camera_matrix, camera.dist_coeffs)
    if est is None:
        return "board pose could not be estimated"
    corners = detect_projected_corners(frames["dark"], frames["white"], frames["pattern"], pattern)
    if corners is None:
        return "projected checkerboard not fully visible"
    table = pixels_to_plane(corners, est.T_cam_from_board, camera.camera_matrix, camera.dist_coeffs)
    if not np.all(np.isfinite(table)):
        return "projected corners do not meet the table plane"
    return ProjectorViewData(name, table, corners, pattern.corners.copy())


def calibrate_projector(views: Sequence[ProjectorViewData], camera: CameraCalibration,
                        projector_size: tuple[int, int], rejected: dict[str, str] | None = None,
                        reject_px: float = 1.5) -> ProjectorCalibration:
    """Projector intrinsics + ``T_proj_from_cam`` from lifted correspondences (module docstring).

    Three stages: (1) ``cv2.calibrateCamera`` on (table point, projector pixel) pairs
    with a simple model (square pixels, no distortion) gives a robust start and rejects
    bad views; (2) ``cv2.stereoCalibrate`` with fixed intrinsics gives the start of
    ``T_proj_from_cam``; (3) a joint least-squares refinement of projector intrinsics,
    k1, k2 and the *single* rigid ``T_proj_from_cam`` over all views. Stage 3 uses the
    rig's rigidity (the projector pose in view i is ``T_proj_from_cam @ T_cam_from_board_i``),
    which constrains the projector far better than per-view poses do.
    """
    # scipy.optimize takes ~470 ms to import (measured with -X importtime) and only this
    # function needs it; at module level it would triple the cost of `import ar`
    from scipy.optimize import least_squares  # deferred: ~470 ms import, needed only here

    rejected = dict(rejected or {})
    names = [v.name for v in views]
    flags = cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_FIX_ASPECT_RATIO
    w, h = projector_size
    K0 = np.array([[1.5 * w, 0, w / 2 - 0.5], [0, 1.5 * w, h / 2 - 0.5], [0, 0, 1.0]])
    rms, Kp, dp, errors, rej, keep = calibrate_from_correspondences(
        names, [v.table_points for v in views], [v.projector_pixels for v in views], projector_size,
        reject_px, flags | cv2.CALIB_USE_INTRINSIC_GUESS, what="projector", K0=K0)
    rejected.update(rej)
    kept = [views[i] for i in keep]
    obj = [np.asarray(v.table_points, np.float32).reshape(-1, 1, 3) for v in kept]
    cam_px = [np.asarray(v.camera_pixels, np.float32).reshape(-1, 1, 2) for v in kept]
    proj_px = [np.asarray(v.projector_pixels, np.float32).reshape(-1, 1, 2) for v in kept]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    out = cv2.stereoCalibrate(obj, cam_px, proj_px, camera.camera_matrix, camera.dist_coeffs, Kp, dp,
                              camera.image_size, flags=cv2.CALIB_FIX_INTRINSIC, criteria=crit)
    R0, t0 = out[5], out[6].ravel()
    # camera poses of the kept views (from the camera pixels of the lifted points)
    cam_poses = []
    for v in kept:
        _ok, rv, tv = cv2.solvePnP(v.table_points, v.camera_pixels, camera.camera_matrix, camera.dist_coeffs,
                                   flags=cv2.SOLVEPNP_IPPE)
        cam_poses.append((cv2.Rodrigues(rv)[0], tv.ravel()))
    table = [v.table_points for v in kept]
    target = np.concatenate([v.projector_pixels for v in kept])

    def unpack(x):
        K = np.array([[x[0], 0, x[2]], [0, x[1], x[3]], [0, 0, 1.0]])
        d = np.array([x[4], x[5], 0.0, 0.0, 0.0])
        R = cv2.Rodrigues(x[6:9])[0]
        return K, d, R, x[9:12]

    def residuals(x):
        K, d, R, t = unpack(x)
        res = []
        for pts, (Rc, tc) in zip(table, cam_poses):
            Rp, tp = R @ Rc, R @ tc + t
            px, _ = cv2.projectPoints(pts, cv2.Rodrigues(Rp)[0], tp, K, d)
            res.append(px.reshape(-1, 2))
        return (np.concatenate(res) - target).ravel()

    x0 = np.concatenate([[Kp[0, 0], Kp[1, 1], Kp[0, 2], Kp[1, 2], 0.0, 0.0], cv2.Rodrigues(R0)[0].ravel(), t0])
    sol = least_squares(residuals, x0, method="lm", x_scale="jac")
    K, d, R, t = unpack(sol.x)
    r = sol.fun.reshape(-1, 2)
    joint_rms = float(np.sqrt(np.mean(np.sum(r ** 2, 1))))
    counts = np.cumsum([0] + [len(p) for p in table])
    errors = {v.name: float(np.sqrt(np.mean(np.sum(r[a:b] ** 2, 1)))) for v, a, b in zip(kept, counts[:-1], counts[1:])}
    validate_intrinsics(K, d, projector_size, None, what="projector")
    return ProjectorCalibration(K, d, tuple(projector_size), R, t, joint_rms, float(out[0]), errors, rejected)


CAPTURE_LOG = "capture.json"


def write_capture(folder: str | Path, captures: Sequence[tuple[CaptureStep, dict[str, np.ndarray], ProjectorPattern]],
                  projector_size: tuple[int, int]) -> Path:
    """Save a capture run: ``step_XX_{dark,white,pattern}.png`` plus ``capture.json`` (pattern placement)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    log = {"projector_size": list(projector_size), "steps": {}}
    for step, frames, pattern in captures:
        for shown, frame in frames.items():
            cv2.imwrite(str(folder / step.file_name(shown)), frame)
        log["inner"] = list(pattern.inner)
        log["steps"][f"step_{step.index:02d}"] = {"pattern_centre": list(pattern.centre), "instruction": step.instruction}
    durable_write(folder / CAPTURE_LOG, json.dumps(log, indent=2).encode("utf-8"))
    return folder


def calibrate_projector_from_folder(folder: str | Path, board: Board, camera: CameraCalibration) -> ProjectorCalibration:
    """Calibrate from a folder written by :func:`write_capture` (or the app's capture run)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CalibrationError("capture folder not found", folder)
    log = _read_json(folder / CAPTURE_LOG)
    try:
        size = (int(log["projector_size"][0]), int(log["projector_size"][1]))
        inner = (int(log["inner"][0]), int(log["inner"][1]))
        steps = {name: tuple(float(v) for v in entry["pattern_centre"]) for name, entry in log["steps"].items()}
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise CalibrationError(f"malformed capture log ({exc!r}); expected projector_size, inner, steps", folder / CAPTURE_LOG) from None
    if not steps:
        raise CalibrationError("capture log lists no steps", folder / CAPTURE_LOG)
    views, rejected = [], {}
    for step, centre in sorted(steps.items()):
        frames = {}
        for shown in ("dark", "white", "pattern"):
            f = folder / f"{step}_{shown}.png"
            img = cv2.imread(str(f)) if f.is_file() else None
            if img is None:
                raise CalibrationError("missing or unreadable frame", f)
            frames[shown] = img
        pattern = make_projector_pattern(size, inner, centre=centre)
        result = extract_projector_view(step, frames, board, camera, pattern)
        if isinstance(result, str):
            rejected[step] = result
        else:
            views.append(result)
    return calibrate_projector(views, camera, size, rejected)


def extrinsics_error(calib: ProjectorCalibration, T_proj_from_cam_true: np.ndarray) -> tuple[float, float]:
    """(rotation deg, translation mm) between an estimated and the true ``T_proj_from_cam``."""
    return pose_error(calib.T_proj_from_cam, T_proj_from_cam_true)


__all__ = [
    "CameraCalibration", "ProjectorCalibration", "CaptureStep", "ProjectorCalibrationSequence", "ProjectorPattern",
    "calibrate_camera", "calibrate_projector", "calibrate_projector_from_folder", "make_projector_pattern",
    "detect_projected_corners", "extract_projector_view", "rig_pose_for_step", "place_pattern", "load_images", "validate_intrinsics",
    "capture_from_camera", "extrinsics_error", "write_capture", "calibrate_from_correspondences", "ProjectorViewData",
    "CAPTURE_LOG", "MIN_VIEW_POINTS", "MAX_CALIBRATION_BYTES", "IMAGE_SUFFIXES",
]
