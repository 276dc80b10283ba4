"""The rig's frame loop on a recording: ``storybeam track`` (per-frame pose and how it was found).

:func:`track_recording` steps :class:`ar.rig.RigTracker` -- the one frame loop the live rig
runs (region detection, the rescue pass for dim and small boards, corners followed between
detections, the filter) -- over every frame of a video or a folder of images, on the
recording's own clock (frame ``i`` at ``i / fps``), and reports per frame the pose (or
none), how it was found (``detected``, ``followed``, ``lost``), the RMS reprojection
error of the points it was solved from, and the step's time; the summary gives
``pose_rate`` (frames with a pose found, detected or followed; a *held* pose does not
count), ``detected_rate``, ``reproj_px_median`` and ``ms_median``.

With ``plain=True`` each frame is also searched by the plain OpenCV detector with its
default settings -- ``cv2.aruco.CharucoDetector`` (ChArUco; found = at least 4 corners,
as the issue counts it), ``cv2.aruco.ArucoDetector`` (grid) or
``cv2.findChessboardCorners`` (checker) -- so the rig and the detector a new user would
try are compared on the same frames in one run.

Without a calibration, :func:`default_camera_for` assumes a phone-like camera: a
field of view of :data:`DEFAULT_HFOV_DEG` across the long side, square pixels, the principal point
at the image centre and no lens distortion. Poses are then right up to that focal length
(the reprojection error and the found / lost counts hardly depend on it).
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from ar.boards import Board
from ar.calibration import CameraCalibration
from ar.camera_sources import CameraSource, CameraSourceError, ImageFolderSource, VideoFileSource
from ar.rig import RigTracker
from ar.synthetic import PinholeModel

#: the horizontal field of view assumed without a calibration (phone main cameras film
#: 16:9 video with about 60-70 degrees; the middle of that range)
DEFAULT_HFOV_DEG = 63.0


def default_camera_for(width: int, height: int, hfov_deg: float = DEFAULT_HFOV_DEG) -> PinholeModel:
    """A camera for a ``width x height`` frame without a calibration: ``hfov_deg`` across the
    frame's long side (a phone filming upright keeps its lens: the field of view follows the
    sensor's long side), square pixels, principal point at the centre, no distortion."""
    f = (max(width, height) / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
    return PinholeModel(K, np.zeros(5), int(width), int(height))


def open_recording(path: str | Path, fps: float | None = None) -> VideoFileSource | ImageFolderSource:
    """A video file or a folder of images, unpaced (frames as fast as they are tracked); raises
    :class:`ar.camera_sources.CameraSourceError` naming the file when it cannot be read."""
    path = Path(path).expanduser()
    if path.is_dir():
        return ImageFolderSource(path, fps=fps or 30.0)
    return VideoFileSource(path, fps=fps)


def plain_detector(board: Board) -> Callable[[np.ndarray], int]:
    """The detector a new user would try, with OpenCV's default settings and the board's whole
    predefined dictionary: a grey frame -> the number of board points it finds (0 = not found;
    ChArUco under 4 corners and a partial checkerboard count as not found)."""
    s = board.spec
    if s.kind == "checker":
        total = s.cols * s.rows

        def checker(gray: np.ndarray) -> int:
            found, _ = cv2.findChessboardCorners(gray, (s.cols, s.rows))
            return total if found else 0
        return checker
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, s.dictionary))
    if s.kind == "charuco":
        detector = cv2.aruco.CharucoDetector(cv2.aruco.CharucoBoard((s.cols, s.rows), s.square_m, s.marker_m,
                                                                    dictionary))

        def charuco(gray: np.ndarray) -> int:
            _cc, ids, _mc, _mids = detector.detectBoard(gray)
            n = 0 if ids is None else len(ids)
            return n if n >= 4 else 0
        return charuco
    grid = cv2.aruco.GridBoard((s.cols, s.rows), s.square_m, s.marker_m, dictionary)
    markers = cv2.aruco.ArucoDetector(dictionary)

    def aruco_grid(gray: np.ndarray) -> int:
        _corners, ids, _rej = markers.detectMarkers(gray)
        n = 0 if ids is None else int(np.sum(np.asarray(ids).ravel() < len(grid.getIds())))
        return 4 * n
    return aruco_grid


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def track_recording(source: CameraSource, board: Board, camera: CameraCalibration | None = None,
                    plain: bool = False, limit: int | None = None,
                    progress: Callable[[int], None] | None = None, follow: bool = True, rescue: bool = True) -> dict:
    """Step the rig's loop over ``source`` (module docstring); ``camera``: its calibration (None:
    :func:`default_camera_for` the frame size; a calibration made at another size is scaled).
    ``limit``: at most that many frames; ``follow`` / ``rescue``: the rig's corner following and
    rescue detection pass (off only to measure what each brings). Returns the report (``frames``, ``summary``,
    ``camera``); raises :class:`ar.camera_sources.CameraSourceError` when no frame can be read."""
    first = source.read()
    if first is None:
        raise CameraSourceError(source.name, "no frame could be read (empty or unreadable recording)")
    h, w = first.image.shape[:2]
    if camera is None:
        model = default_camera_for(w, h)
        cam_info = {"assumed": True, "hfov_deg": DEFAULT_HFOV_DEG, "principal_point": "image centre",
                    "distortion": "none"}
    else:
        model = PinholeModel(camera.camera_matrix, camera.dist_coeffs, *camera.image_size)
        if (model.width, model.height) != (w, h):
            model = model.scaled(w, h)
        cam_info = {"assumed": False, "calibrated_size": list(camera.image_size)}
    cam_info.update(size=[w, h], K=np.round(model.K, 3).tolist(), dist=np.asarray(model.dist).ravel().tolist())
    rig = RigTracker(board, model.K, model.dist, flow=None if follow else False, rescue=rescue)
    plain_count = plain_detector(board) if plain else None
    frames: list[dict] = []
    frame = first
    while frame is not None and (limit is None or len(frames) < limit):
        state = rig.step(frame.image, frame.timestamp_s, frame.index)
        est = state.estimate if state.found_by != "lost" else None
        row = {"index": frame.index, "t_s": round(frame.timestamp_s, 4), "found_by": state.found_by,
               "state": state.state, "search": state.search, "ms": round(state.detect_pose_ms, 3),
               "n_points": est.n_points if est is not None else 0,
               "reproj_px": round(est.rms_px, 4) if est is not None else None,
               "rvec": None, "tvec_m": None}
        if est is not None:
            rvec, _ = cv2.Rodrigues(np.ascontiguousarray(est.T_cam_from_board[:3, :3]))
            row["rvec"] = np.round(rvec.ravel(), 6).tolist()
            row["tvec_m"] = np.round(est.T_cam_from_board[:3, 3], 6).tolist()
        if plain_count is not None:
            t0 = time.perf_counter()
            row["plain_points"] = plain_count(cv2.cvtColor(frame.image, cv2.COLOR_BGR2GRAY))
            row["plain_ms"] = round((time.perf_counter() - t0) * 1000, 3)
        frames.append(row)
        if progress is not None:
            progress(1)
        frame = source.read()
    return {"source": source.name, "board": str(board.spec), "fps": source.fps, "camera": cam_info,
            "follow": follow, "rescue": rescue,
            "summary": summarise(frames), "frames": frames}


def summarise(frames: list[dict]) -> dict:
    """The rates and medians of a list of per-frame rows (see :func:`track_recording`)."""
    n = len(frames)
    by = {k: sum(f["found_by"] == k for f in frames) for k in ("detected", "followed", "lost")}
    reproj = [f["reproj_px"] for f in frames if f["reproj_px"] is not None]
    ms = [f["ms"] for f in frames]
    out = {"frames": n, "pose_rate": (by["detected"] + by["followed"]) / max(1, n),
           "detected_rate": by["detected"] / max(1, n), "followed_rate": by["followed"] / max(1, n),
           "lost_rate": by["lost"] / max(1, n), "reproj_px_median": _median(reproj),
           "reproj_px_p95": float(np.percentile(reproj, 95)) if reproj else None,
           "ms_median": _median(ms), "ms_p95": float(np.percentile(ms, 95)) if ms else None,
           "longest_followed_run": _longest_run(frames, "followed")}
    if frames and "plain_points" in frames[0]:
        found = [f["plain_points"] for f in frames if f["plain_points"] > 0]
        out.update(plain_rate=len(found) / max(1, n), plain_points_median=_median(found),
                   plain_ms_median=_median([f["plain_ms"] for f in frames]))
    return out


def _longest_run(frames: list[dict], kind: str) -> int:
    best = run = 0
    for f in frames:
        run = run + 1 if f["found_by"] == kind else 0
        best = max(best, run)
    return best


def format_summary(report: dict) -> str:
    """The summary as a Markdown table (what ``storybeam track`` prints)."""
    s = report["summary"]
    pct = lambda v: "-" if v is None else f"{100 * v:.1f} %"  # noqa: E731
    num = lambda v, unit="": "-" if v is None else f"{v:.2f}{unit}"  # noqa: E731
    rows = [("frames", str(s["frames"])), ("pose (detected + followed)", pct(s["pose_rate"])),
            ("detected", pct(s["detected_rate"])), ("followed", pct(s["followed_rate"])),
            ("lost", pct(s["lost_rate"])), ("longest followed run", f"{s['longest_followed_run']} frames"),
            ("reprojection error, median / p95", f"{num(s['reproj_px_median'])} / {num(s['reproj_px_p95'])} px"),
            ("rig step, median / p95", f"{num(s['ms_median'])} / {num(s['ms_p95'])} ms")]
    if "plain_rate" in s:
        rows.append(("plain OpenCV detector finds it", f"{pct(s['plain_rate'])} "
                                                        f"(median {num(s['plain_points_median'])} points)"))
    width = max(len(r[0]) for r in rows)
    lines = [f"| {'':<{width}} | {report['source']} |", f"|{'-' * (width + 2)}|---|"]
    lines += [f"| {k:<{width}} | {v} |" for k, v in rows]
    return "\n".join(lines)


__all__ = ["DEFAULT_HFOV_DEG", "default_camera_for", "open_recording", "plain_detector", "track_recording",
           "summarise", "format_summary"]
