"""Scanning the table: decoded Gray-code correspondences -> 3-D points -> a height map.

Method:

1. **sub-pixel codes** -- a decoded code is a whole projector pixel (up to +-0.5 px off),
   which at a rig's baseline is about a millimetre of depth per point. Over a small
   square window of decoded pixels the map camera pixel -> projector pixel of a smooth
   surface is linear; the least-squares line through a *full* symmetric window, at its
   centre, is the window's mean, so each code is replaced by its window mean (box
   filters). Windows that are not full (shadow edges) are dropped, and so are windows
   whose codes do not fit a plane to within ``max_residual_px`` (a depth edge runs
   through them): an edge is left unknown rather than smeared.
2. **triangulation** -- camera pixels and projector codes are undistorted to normalised
   rays (``cv2.undistortPoints`` with each device's intrinsics) and intersected with
   ``cv2.triangulatePoints`` (camera ``[I|0]``, projector ``[R|T]``): points in the
   camera frame, metres.
3. **the board** -- found in the white capture; its pose (``solve_board_pose``) gives the
   board frame. The points seen inside the board's corner hull are the board's own: a
   plane is fitted to them (SVD, then refitted without points over 5 mm off, e.g. an
   object lying on the board), and ``board_plane_rms_mm`` is their RMS distance from it.
   Heights are distances above *that* plane (toward the camera), positions are
   board-frame ``(x, y)``: the points become board-frame points whose ``-z`` is their
   height, rasterised by :meth:`ar.height_map.HeightMap.from_points`.

Points are written as a binary little-endian PLY (``x y z`` float32 and the white
capture's grey level), readable by MeshLab, CloudCompare, trimesh and Open3D.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ar.boards import Board
from ar.errors import CalibrationError
from ar.geometry import invert
from ar.height_map import DEFAULT_CELL_M, HeightMap
from ar.pose import solve_board_pose
from ar.structured_light.calibrate import GrayCodeCalibration, find_board
from ar.structured_light.decode import DecodedPose
from retrieval.durable import durable_write

DEFAULT_SMOOTH_PX = 7
DEFAULT_MAX_RESIDUAL_PX = 0.8
DEFAULT_MIN_FILL = 0.3
PLANE_OUTLIER_M = 0.005


def subpixel_codes(decoded: DecodedPose, window: int = DEFAULT_SMOOTH_PX,
                   max_residual_px: float = DEFAULT_MAX_RESIDUAL_PX,
                   min_fill: float = DEFAULT_MIN_FILL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sub-pixel projector ``(col, row)`` per camera pixel and their mask (module docstring, step 1)."""
    if window <= 1:
        return decoded.col.astype(np.float64), decoded.row.astype(np.float64), decoded.mask.copy()
    k = (int(window), int(window))

    def box(a: np.ndarray) -> np.ndarray:  # window sums
        return cv2.boxFilter(a, cv2.CV_64F, k, normalize=False, borderType=cv2.BORDER_CONSTANT)

    m = decoded.mask.astype(np.float64)
    h, w = m.shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    n = box(m)
    ok = decoded.lit & (n >= max(4.0, min_fill * window * window))
    sel = np.nonzero(ok)
    # moments of the decoded pixels' offsets from the window centre, at the selected pixels
    sx, sy = box(m * xs)[sel], box(m * ys)[sel]
    sxx, sxy, syy = box(m * xs * xs)[sel], box(m * xs * ys)[sel], box(m * ys * ys)[sel]
    x0, y0, s0 = xs[sel], ys[sel], n[sel]
    mx, my = sx - x0 * s0, sy - y0 * s0
    mxx = sxx - 2 * x0 * sx + x0 * x0 * s0
    myy = syy - 2 * y0 * sy + y0 * y0 * s0
    mxy = sxy - x0 * sy - y0 * sx + x0 * y0 * s0
    A = np.stack([np.stack([s0, mx, my], -1), np.stack([mx, mxx, mxy], -1), np.stack([my, mxy, myy], -1)], -2)
    good = np.abs(np.linalg.det(A)) > 1e-6 * np.maximum(s0, 1) ** 3
    A[~good] = np.eye(3)
    out = []
    for code in (decoded.col, decoded.row):
        c = np.where(decoded.mask, code, 0).astype(np.float64)
        sc, scx, scy = box(c)[sel], box(c * xs)[sel], box(c * ys)[sel]
        rhs = np.stack([sc, scx - x0 * sc, scy - y0 * sc], -1)
        beta = np.linalg.solve(A, rhs[..., None])[..., 0]
        rss = box(c * c)[sel] - np.sum(beta * rhs, -1)
        good &= rss <= max_residual_px ** 2 * np.maximum(s0 - 3, 1)
        full = np.full((h, w), np.nan)
        full[sel] = beta[:, 0]
        out.append(full)
    mask = np.zeros((h, w), bool)
    mask[sel[0][good], sel[1][good]] = True
    return out[0], out[1], mask


def triangulate(cam_px: np.ndarray, proj_px: np.ndarray, calib: GrayCodeCalibration) -> np.ndarray:
    """Camera-frame points (N,3) from camera pixels and projector pixels (each (N,2))."""
    cam, proj = calib.camera, calib.projector
    xc = cv2.undistortPoints(cam_px.reshape(-1, 1, 2).astype(np.float64), cam.camera_matrix, cam.dist_coeffs)
    xp = cv2.undistortPoints(proj_px.reshape(-1, 1, 2).astype(np.float64), proj.camera_matrix, proj.dist_coeffs)
    P1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    P2 = np.hstack([calib.R, calib.T.reshape(3, 1)])
    X = cv2.triangulatePoints(P1, P2, xc.reshape(-1, 2).T, xp.reshape(-1, 2).T)
    with np.errstate(divide="ignore", invalid="ignore"):
        pts = (X[:3] / X[3]).T
    return pts


def fit_plane(points: np.ndarray, outlier_m: float = PLANE_OUTLIER_M) -> tuple[np.ndarray, float, np.ndarray]:
    """Least-squares plane ``n . x = d`` (unit ``n``), refitted once without points over
    ``outlier_m`` off; returns ``(n, d, inliers)``."""
    keep = np.ones(len(points), bool)
    for _ in range(2):
        sel = points[keep]
        c = sel.mean(0)
        n = np.linalg.svd(sel - c, full_matrices=False)[2][2]
        d = float(n @ c)
        keep = np.abs(points @ n - d) <= outlier_m
        if keep.sum() < 3:
            raise CalibrationError("the board's points do not lie on a plane")
    return n, d, keep


@dataclass
class Scan:
    """One pose's scan: camera-frame points, their camera pixels and grey levels, the
    board's pose and plane fit where the board was seen, and the height map."""

    points: np.ndarray  # (N,3) camera frame, metres
    pixels: np.ndarray  # (N,2) camera pixels
    grey: np.ndarray  # (N,) uint8, white capture
    T_cam_from_board: np.ndarray | None = None
    board_plane_rms_mm: float | None = None
    board_points: int = 0
    heights: np.ndarray | None = None  # (N,) metres above the board plane
    height_map: HeightMap | None = None
    note: str = ""  # why there is no height map, when there is none

    def summary(self) -> dict:
        out = {"points": int(len(self.points)), "board_seen": self.T_cam_from_board is not None,
               "board_plane_rms_mm": self.board_plane_rms_mm, "board_points": self.board_points}
        if self.note:
            out["note"] = self.note
        if self.height_map is not None:
            hm = self.height_map
            out["height_map"] = {"rows": hm.shape[0], "cols": hm.shape[1], "cell_mm": hm.cell_m * 1000,
                                 "extent_m": list(hm.extent), "known_fraction": hm.known_fraction,
                                 "max_height_mm": float(hm.heights[hm.known].max() * 1000) if hm.known.any() else None}
        return out


def scan_pose(decoded: DecodedPose, calib: GrayCodeCalibration, board: Board | None = None,
              smooth_px: int = DEFAULT_SMOOTH_PX, cell_m: float = DEFAULT_CELL_M, max_depth_m: float = 5.0) -> Scan:
    """Points (and, where ``board`` is seen, the height map) from one decoded pose (module docstring)."""
    if decoded.image_size != tuple(calib.camera.image_size):
        raise CalibrationError(f"pose {decoded.name}: images are {decoded.image_size[0]}x{decoded.image_size[1]}, the "
                               f"calibration's camera is {calib.camera.image_size[0]}x{calib.camera.image_size[1]}")
    col, row, mask = subpixel_codes(decoded, smooth_px)
    ys, xs = np.nonzero(mask)
    pix = np.stack([xs, ys], 1).astype(np.float64)
    pts = triangulate(pix, np.stack([col[ys, xs], row[ys, xs]], 1), calib)
    good = np.all(np.isfinite(pts), 1) & (pts[:, 2] > 0) & (pts[:, 2] < max_depth_m)
    scan = Scan(pts[good], pix[good], decoded.white[ys[good], xs[good]])
    if board is None:
        return scan
    det = find_board(decoded, board)
    est = None if det is None else solve_board_pose(det, calib.camera.camera_matrix, calib.camera.dist_coeffs)
    if est is None:
        scan.note = "board not found in the white capture: no height map (the points are in the camera frame)"
        return scan
    hull = cv2.convexHull(det.image_points.astype(np.float32)).reshape(-1, 2)
    region = np.zeros(decoded.mask.shape, np.uint8)
    cv2.fillConvexPoly(region, np.round(hull).astype(np.int32), 1)
    region = cv2.erode(region, np.ones((3, 3), np.uint8))  # a pixel in, so edge points are the board's
    px = scan.pixels.astype(np.int64)
    inside = region[px[:, 1], px[:, 0]].astype(bool)
    if inside.sum() < 50:
        scan.note = (f"only {int(inside.sum())} decoded points on the board (50 needed for its plane): "
                     f"no height map; if the light is faint, lower --black-threshold / --white-threshold")
        scan.T_cam_from_board = est.T_cam_from_board
        return scan
    n, d, keep = fit_plane(scan.points[inside])
    dist = scan.points[inside][keep] @ n - d
    scan.board_plane_rms_mm = float(np.sqrt(np.mean(dist ** 2)) * 1000)
    scan.board_points = int(keep.sum())
    scan.T_cam_from_board = est.T_cam_from_board
    # heights: distance from the fitted plane toward the camera (origin); positions: the board frame
    toward_camera = -np.sign(d) if d != 0 else 1.0
    scan.heights = toward_camera * (scan.points @ n - d)
    board_pts = (invert(est.T_cam_from_board) @ np.hstack([scan.points, np.ones((len(scan.points), 1))]).T).T[:, :3]
    board_pts[:, 2] = -scan.heights
    scan.height_map = HeightMap.from_points(board_pts, cell_m=cell_m)
    return scan


def write_ply(path: str | Path, points: np.ndarray, grey: np.ndarray | None = None) -> Path:
    """A binary little-endian PLY of ``points`` (N,3) with optional grey levels (durable write)."""
    pts = np.asarray(points, "<f4").reshape(-1, 3)
    props = "property float x\nproperty float y\nproperty float z\n"
    if grey is not None:
        props += "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        rec = np.zeros(len(pts), [("p", "<f4", 3), ("c", "u1", 3)])
        rec["p"] = pts
        rec["c"] = np.repeat(np.asarray(grey, np.uint8).reshape(-1, 1), 3, 1)
        body = rec.tobytes()
    else:
        body = pts.tobytes()
    header = f"ply\nformat binary_little_endian 1.0\nelement vertex {len(pts)}\n{props}end_header\n".encode("ascii")
    try:
        return durable_write(Path(path), header + body)
    except OSError as exc:
        raise CalibrationError(f"cannot write: {exc.strerror or exc}", path) from None


def scan_picture(decoded: DecodedPose, scan: Scan, max_height_m: float | None = None, height_px: int = 360) -> np.ndarray:
    """A BGR picture of a scan: the white capture (decoded pixels tinted by their height
    where the board was seen, else green), beside the height map seen from above (board
    frame, x to the right, y down; grey where unknown), coloured blue (table) to yellow
    (``max_height_m``, default the tallest known cell), with a scale in millimetres."""
    white = cv2.cvtColor(decoded.white, cv2.COLOR_GRAY2BGR)
    hm = scan.height_map
    top = max_height_m or (float(hm.heights[hm.known].max()) if hm is not None and hm.known.any() else 0.05)
    top = max(top, 1e-3)

    def colour(h: np.ndarray) -> np.ndarray:
        v = np.clip(h / top, 0, 1)
        return cv2.applyColorMap((v * 255).astype(np.uint8).reshape(-1, 1), cv2.COLORMAP_VIRIDIS).reshape(-1, 3)

    left = white.copy()
    px = scan.pixels.astype(np.int64)
    if scan.heights is not None:
        left[px[:, 1], px[:, 0]] = (0.4 * left[px[:, 1], px[:, 0]] + 0.6 * colour(scan.heights)).astype(np.uint8)
    else:
        left[px[:, 1], px[:, 0], 1] = 255
    scale = height_px / left.shape[0]
    left = cv2.resize(left, (int(round(left.shape[1] * scale)), height_px), interpolation=cv2.INTER_AREA)
    if hm is None:
        return left
    right = colour(hm.heights.ravel()).reshape(*hm.shape, 3)
    right[~hm.known] = 128
    s = height_px / right.shape[0]
    right = cv2.resize(right, (max(1, int(round(right.shape[1] * s))), height_px), interpolation=cv2.INTER_NEAREST)
    bar = np.zeros((height_px, 60, 3), np.uint8)
    bar[:, :16] = colour(np.linspace(top, 0, height_px)).reshape(height_px, 1, 3)
    for frac in (0.0, 0.5, 1.0):
        y = int(np.clip((1 - frac) * (height_px - 1), 10, height_px - 4))
        cv2.putText(bar, f"{frac * top * 1000:.0f}", (19, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    cv2.putText(bar, "mm", (19, height_px // 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    gap = np.full((height_px, 8, 3), 255, np.uint8)
    return np.hstack([left, gap, right, gap, bar])
