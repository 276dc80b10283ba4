"""*Scan the table*: the teacher's step after calibration that measures the table's shape
(the boxes and pencil cases the children put on it) and stores it with the calibration.

Method: the rig, held still over the table with the board in view, projects OpenCV's
Gray-code sequence (:mod:`ar.structured_light.patterns`) and captures one camera frame per
pattern (:func:`capture_sequence`); :func:`scan_captures` decodes them, triangulates
every decoded camera pixel with the Gray-code calibration and rasterises the points above
the board plane into an :class:`ar.height_map.HeightMap`
(:func:`ar.structured_light.scan.scan_pose`); :func:`save_scan` writes it beside
``camera.json`` and ``projector.json`` as ``table.npz`` (:data:`ar.HEIGHT_MAP_FILE`,
a durable write: a power cut leaves the old scan or the new one). The projector stage
reads it (:class:`app.player.stage.StageRenderer`) and the characters walk on it.

Without a rig (this machine, a test, the app's preview mode), :func:`synthetic_scan`
renders the same sequence on the synthetic rig's table with boxes of known size on it
(:class:`ar.structured_light.synthetic.GrayCodeScene`) and scans it with the synthetic
rig's own (true) calibration, so the whole chain runs end to end.

Kivy-free; the UI runs :meth:`app.services.CalibrationWizard.run_next` off its thread.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ar import HEIGHT_MAP_FILE, Board, HeightMap, HeightMapError, look_at

#: Seconds the projector is given to show a pattern before the camera frame is kept
#: (a projector and a camera each add a frame or two of latency).
SETTLE_S = 0.2
#: Camera frames dropped after each pattern (frames already in the camera's buffer).
FLUSH_FRAMES = 2
#: The synthetic table's boxes (board frame, metres: x0, y0, x1, y1, height): a pencil
#: case at the board's far corner and a low book beside it -- one higher than a step, one
#: lower (:data:`retrieval.animation.STEP_MAX_M`).
SYNTHETIC_BOXES = ((0.15, 0.17, 0.22, 0.24, 0.045), (0.02, 0.20, 0.08, 0.26, 0.02))


def capture_sequence(patterns: Sequence[np.ndarray], show: Callable[[np.ndarray], None],
                     read: Callable[[], np.ndarray | None], settle_s: float = SETTLE_S,
                     flush_frames: int = FLUSH_FRAMES, sleep: Callable[[float], None] = time.sleep) -> list[np.ndarray]:
    """One camera frame per projected pattern: ``show(pattern)`` (RGB, the projector
    window), wait ``settle_s``, drop ``flush_frames`` stale frames, keep the next
    ``read()``. Raises :class:`ar.HeightMapError` when the camera gives no frame."""
    frames = []
    for k, pattern in enumerate(patterns):
        show(np.ascontiguousarray(np.repeat(pattern[..., None], 3, axis=2) if pattern.ndim == 2 else pattern))
        sleep(settle_s)
        frame = None
        for _ in range(flush_frames + 1):
            frame = read()
            if frame is None:
                raise HeightMapError(f"the camera stopped during the scan (pattern {k + 1} of {len(patterns)})")
        frames.append(frame)
    return frames


def scan_captures(captures: Sequence[np.ndarray], calibration, board: Board) -> HeightMap:
    """The height map from one pose's Gray-code captures (patterns, white, black) and a
    Gray-code calibration (:class:`ar.structured_light.calibrate.GrayCodeCalibration`).
    Raises :class:`ar.HeightMapError` when the board is not seen or nothing decodes."""
    from ar.structured_light.decode import decode_images  # deferred: the scan's decoding, only when scanning
    from ar.structured_light.scan import scan_pose  # deferred: as above

    decoded = decode_images(list(captures), tuple(calibration.projector.image_size), "scan")
    if not decoded.mask.any():
        raise HeightMapError("no projected pattern was seen: is the projector on and aimed at the table?")
    scan = scan_pose(decoded, calibration, board)
    if scan.height_map is None:
        raise HeightMapError("the board was not found: keep the whole printed board in the camera's view")
    return scan.height_map


def save_scan(height_map: HeightMap, folder: str | Path) -> Path:
    """Write the scan beside the calibration (``folder/table.npz``, durably); returns the path."""
    return height_map.save(Path(folder) / HEIGHT_MAP_FILE)


def describe_scan(height_map: HeightMap) -> str:
    """The teacher's one-line summary: the area seen and the tallest thing on it."""
    x0, x1, y0, y1 = height_map.extent
    known = height_map.heights[height_map.known]
    top = float(known.max()) * 1000 if known.size else 0.0
    return (f"{(x1 - x0) * 100:.0f} x {(y1 - y0) * 100:.0f} cm, {100 * height_map.known_fraction:.0f} % seen, "
            f"tallest {top:.0f} mm")


def synthetic_rig_calibration(camera):
    """The synthetic rig's true Gray-code calibration (camera, projector, extrinsics)."""
    from ar.calibration import CameraCalibration, ProjectorCalibration  # deferred: OpenCV, only when scanning
    from ar.structured_light.calibrate import GrayCodeCalibration  # deferred: as above

    T = camera.proj_from_cam
    return GrayCodeCalibration(
        CameraCalibration(camera.camera.K, camera.camera.dist, camera.camera.size, 0.0, board=str(camera.board.spec)),
        ProjectorCalibration(camera.projector.K, camera.projector.dist, camera.projector.size, T[:3, :3], T[:3, 3], 0.0),
        board=str(camera.board.spec))


def synthetic_scan_pose(board: Board, proj_from_cam: np.ndarray, height_m: float = 0.5) -> np.ndarray:
    """``T_cam_from_board`` of a rig held still ``height_m`` over the board, the projector
    looking down at its centre from the child's side, a little tilted (as a teacher holds it)."""
    c = board.centre
    eye = c + np.array([-0.12, 0.02, -height_m])
    T_proj_from_board = look_at(eye, c, np.array([-1.0, 0.0, 0.0]))
    return np.linalg.inv(proj_from_cam) @ T_proj_from_board


def synthetic_scan(board: Board, boxes: Sequence[tuple[float, float, float, float, float]] = SYNTHETIC_BOXES,
                   supersample: int = 1) -> tuple[list[np.ndarray], object]:
    """The synthetic rig's captures of the Gray-code sequence over a table with ``boxes``
    (``(x0, y0, x1, y1, height)``, board metres) and its true calibration."""
    from ar.structured_light.synthetic import Box, GrayCodeScene  # deferred: the bench renderer, only without a rig
    from ar.synthetic import SyntheticCamera  # deferred: as above

    camera = SyntheticCamera(board, supersample=supersample)
    scene = GrayCodeScene(camera, [Box(*b) for b in boxes])
    captures = scene.capture_graycode(synthetic_scan_pose(board, camera.proj_from_cam))
    return captures, synthetic_rig_calibration(camera)


__all__ = ["SETTLE_S", "FLUSH_FRAMES", "SYNTHETIC_BOXES", "capture_sequence", "scan_captures", "save_scan",
           "describe_scan", "synthetic_rig_calibration", "synthetic_scan_pose", "synthetic_scan"]
