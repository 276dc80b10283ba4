"""Printable calibration/tracking boards: spec strings, detection, drawing and printing.

Spec strings (lengths in metres):

* ``charuco:5x7:0.04:0.02:DICT_6X6_250`` -- ChArUco board of 5 x 7 *squares*, square
  side 0.04 m, marker side 0.02 m, ArUco dictionary (the default board).
* ``grid:4x5:0.04:0.01:DICT_4X4_50`` -- ArUco grid of 4 x 5 *markers*, marker side
  0.04 m, gap between markers 0.01 m.
* ``checker:9x6:0.025`` -- plain checkerboard given by its *inner corners* (OpenCV's
  ``patternSize`` convention): 9 x 6 inner corners = 10 x 7 squares of 0.025 m.

Board frame (shared by every module in ``ar/``): the origin is the top-left outer corner
of the pattern as printed (page upright), +x runs to the right along the first row,
+y runs down the page, and therefore +z = x cross y points *into* the table. "Up off
the table" is -z. (This is OpenCV's own object-point convention; see
:mod:`ar.render.projector_view` for the Y-up scene frame used for 3-D content.)

A board knows its pattern extent (``pattern_size_m``) and the white paper margin around
it; :meth:`Board.texture` draws the whole sheet at a chosen pixels-per-metre so the
synthetic camera can warp it exactly, and :func:`write_board` prints it at true size.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ar.errors import BoardSpecError

DEFAULT_BOARD_SPEC = "charuco:5x7:0.04:0.02:DICT_6X6_250"
BOARD_KINDS = ("charuco", "grid", "checker")


@dataclass(frozen=True)
class BoardSpec:
    """Parsed board spec; ``cols x rows`` are squares (charuco), markers (grid) or inner corners (checker)."""

    kind: str
    cols: int
    rows: int
    square_m: float  # charuco/checker: square side; grid: marker side
    marker_m: float = 0.0  # charuco: marker side; grid: gap between markers; checker: unused
    dictionary: str = ""

    @classmethod
    def parse(cls, text: str) -> "BoardSpec":
        """Parse a spec string; raises :class:`BoardSpecError` naming the problem."""
        parts = text.strip().split(":")
        kind = parts[0].lower()
        if kind not in BOARD_KINDS:
            raise BoardSpecError(f"board spec {text!r}: unknown kind {parts[0]!r} (expected one of {', '.join(BOARD_KINDS)})")
        expected = 3 if kind == "checker" else 5
        if len(parts) != expected:
            example = {"charuco": DEFAULT_BOARD_SPEC, "grid": "grid:4x5:0.04:0.01:DICT_4X4_50", "checker": "checker:9x6:0.025"}[kind]
            raise BoardSpecError(f"board spec {text!r}: expected {expected} ':'-separated fields, like {example!r}")
        try:
            cols_s, rows_s = parts[1].lower().split("x")
            cols, rows = int(cols_s), int(rows_s)
        except ValueError:
            raise BoardSpecError(f"board spec {text!r}: size {parts[1]!r} must look like 5x7") from None
        try:
            lengths = [float(p) for p in parts[2:4]]
        except ValueError:
            raise BoardSpecError(f"board spec {text!r}: lengths must be numbers in metres") from None
        if min(cols, rows) < 2:
            raise BoardSpecError(f"board spec {text!r}: need at least 2x2, got {cols}x{rows}")
        if not all(np.isfinite(v) and 0 < v < 1.0 for v in lengths):
            raise BoardSpecError(f"board spec {text!r}: lengths must be in metres, between 0 and 1")
        dictionary = ""
        if kind != "checker":
            dictionary = parts[4].upper()
            if not dictionary.startswith("DICT_") or not hasattr(cv2.aruco, dictionary):
                raise BoardSpecError(f"board spec {text!r}: unknown ArUco dictionary {parts[4]!r}")
        if kind == "charuco" and lengths[1] >= lengths[0]:
            raise BoardSpecError(f"board spec {text!r}: marker ({lengths[1]}) must be smaller than square ({lengths[0]})")
        return cls(kind, cols, rows, lengths[0], lengths[1] if kind != "checker" else 0.0, dictionary)

    def __str__(self) -> str:
        if self.kind == "checker":
            return f"checker:{self.cols}x{self.rows}:{self.square_m:g}"
        return f"{self.kind}:{self.cols}x{self.rows}:{self.square_m:g}:{self.marker_m:g}:{self.dictionary}"


def _marker_params() -> "cv2.aruco.DetectorParameters":
    """ArUco detector settings for small, distant markers.

    Sampling 8 px per marker cell (default 4) when un-warping a candidate lets the
    default board's 2 cm markers be read at 1 m with a 700 px focal length (the bench's
    far_1.0m condition; see docs/design/ar.md). Lowering
    ``minMarkerPerimeterRate`` as well was tried and dropped: it lost corners on a
    sharp fronto-parallel print scan.
    """
    params = cv2.aruco.DetectorParameters()
    params.perspectiveRemovePixelPerCell = 8
    params.perspectiveRemoveIgnoredMarginPerCell = 0.2
    return params


#: CLAHE of the rescue pass: tiles of about 8 x 8 over the searched image, contrast
#: amplification clipped at 3 (the usual range is 2-4: less does not lift a dim board,
#: more turns sensor noise into false marker edges)
RESCUE_CLAHE_CLIP = 3.0
#: the rescue pass upsamples a searched image narrower than this (px) twice: a marker's
#: bit cells need about 3 px each to be read, a 2 cm marker seen at 320 px width has ~2
RESCUE_UPSAMPLE_BELOW_PX = 480


def _rescue_params() -> "cv2.aruco.DetectorParameters":
    """Marker settings for the rescue pass (:meth:`Board.detect_enhanced`): the product's
    (:func:`_marker_params`) plus more adaptive-threshold windows (3 to 33 px in steps of 5
    instead of 3 to 23 in 10: a blurred or dim edge is found by one of the windows between)
    and a lower threshold constant (5 instead of 7: after CLAHE the ink-paper step of a dim
    board is still small). Marker corners are refined on the contours: they seed the
    ChArUco corners' refinement and, on a board with few corners found, stand in as points."""
    params = _marker_params()
    params.adaptiveThreshWinSizeMin = 3
    params.adaptiveThreshWinSizeMax = 33
    params.adaptiveThreshWinSizeStep = 5
    params.adaptiveThreshConstant = 5
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_CONTOUR
    return params


#: point ids of ArUco marker corners stood in for ChArUco corners (4 per marker, after every corner id)
MARKER_CORNER_ID_BASE = 10000


def board_dictionary(full: "cv2.aruco.Dictionary", n_markers: int) -> "cv2.aruco.Dictionary":
    """The first ``n_markers`` codes of ``full`` (the ids a board prints), same correction radius.

    Why: OpenCV identifies each marker candidate against *every* code of the dictionary,
    so with ``DICT_6X6_250`` the default board (17 markers) paid for 250 codes: about 25 ms
    of a 640x480 frame on one core, against about 8 ms with its own 17 (docs/design/ar.md). The detections do
    not change: a candidate is accepted for code ``i`` when its bits are within
    ``r = maxCorrectionBits * errorCorrectionRate`` of ``i``; the codes of a predefined
    dictionary are at least ``2 maxCorrectionBits + 1 > 2 r`` bits apart in every rotation
    (checked for the 4x4, 5x5 and 6x6 dictionaries in the tests), so the balls of
    radius ``r`` around them are disjoint and a candidate lies within ``r`` of at most one
    code. Removing the codes the board does not print therefore only rejects candidates
    that the full dictionary would have read as ids the board does not have (and which
    board matching then threw away); every board id is found exactly as before.
    """
    return cv2.aruco.Dictionary(np.ascontiguousarray(full.bytesList[:n_markers]), full.markerSize,
                                full.maxCorrectionBits)


@dataclass
class BoardDetection:
    """Matched board points in one image: ``object_points`` (N,3) metres, ``image_points`` (N,2) px."""

    object_points: np.ndarray
    image_points: np.ndarray
    ids: np.ndarray  # (N,) point ids (charuco corner ids, marker-corner ids, checker corner index)
    total_points: int  # points on the whole board (so callers can judge partial views)

    @property
    def n(self) -> int:
        return int(len(self.image_points))


class Board:
    """One physical board: geometry, detection in an image, and drawing of its sheet."""

    def __init__(self, spec: BoardSpec | str, full_dictionary: bool = False):
        """``full_dictionary``: identify markers against the whole predefined dictionary (as
        before issue 13; the same detections, slower -- see :func:`board_dictionary`), for
        side-by-side timing in the AR bench."""
        self.spec = BoardSpec.parse(spec) if isinstance(spec, str) else spec
        s = self.spec
        if s.kind == "checker":
            self._cv_board = None
            xs, ys = np.meshgrid(np.arange(1, s.cols + 1), np.arange(1, s.rows + 1))
            self.all_object_points = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1) * s.square_m
            self.pattern_size_m = ((s.cols + 1) * s.square_m, (s.rows + 1) * s.square_m)
        else:
            full = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, s.dictionary))
            n_markers = (s.cols * s.rows) // 2 if s.kind == "charuco" else s.cols * s.rows
            if n_markers > full.bytesList.shape[0]:
                raise BoardSpecError(f"board spec {self.spec}: needs {n_markers} markers, {s.dictionary} has only {full.bytesList.shape[0]}")
            dictionary = full if full_dictionary else board_dictionary(full, n_markers)
            if s.kind == "charuco":
                board = cv2.aruco.CharucoBoard((s.cols, s.rows), s.square_m, s.marker_m, dictionary)
                self.all_object_points = np.asarray(board.getChessboardCorners(), np.float64).reshape(-1, 3)
                self.pattern_size_m = (s.cols * s.square_m, s.rows * s.square_m)
                self._detector = cv2.aruco.CharucoDetector(board, cv2.aruco.CharucoParameters(), _marker_params())
                rescue = cv2.aruco.CharucoParameters()
                rescue.tryRefineMarkers = True  # look again for the board's missing markers where the found ones put them
                self._rescue_detector = cv2.aruco.CharucoDetector(board, rescue, _rescue_params())
                self._marker_object_points = np.asarray(board.getObjPoints(), np.float64).reshape(-1, 4, 3)
            else:
                board = cv2.aruco.GridBoard((s.cols, s.rows), s.square_m, s.marker_m, dictionary)
                self.all_object_points = np.asarray(board.getObjPoints(), np.float64).reshape(-1, 3)
                self.pattern_size_m = (s.cols * s.square_m + (s.cols - 1) * s.marker_m,
                                       s.rows * s.square_m + (s.rows - 1) * s.marker_m)
                params = _marker_params()
                params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
                self._detector = cv2.aruco.ArucoDetector(dictionary, params)
                params = _rescue_params()
                params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
                self._rescue_detector = cv2.aruco.ArucoDetector(dictionary, params)
            self._cv_board = board
        #: white paper around the pattern: a checkerboard needs a quiet zone of one square
        #: for findChessboardCornersSB; ChArUco/grid need only a thin white border (5 mm),
        #: which keeps the default board (200 x 280 mm pattern) on an A4 page.
        self.margin_m = s.square_m if s.kind == "checker" else 0.005
        self._clahe = cv2.createCLAHE(clipLimit=RESCUE_CLAHE_CLIP, tileGridSize=(8, 8))

    # ----------------------------------------------------------------- geometry
    @property
    def centre(self) -> np.ndarray:
        """Centre of the pattern in the board frame (metres)."""
        return np.array([self.pattern_size_m[0] / 2, self.pattern_size_m[1] / 2, 0.0])

    @property
    def sheet_size_m(self) -> tuple[float, float]:
        """Printed sheet extent: pattern plus margin on every side."""
        return (self.pattern_size_m[0] + 2 * self.margin_m, self.pattern_size_m[1] + 2 * self.margin_m)

    # ----------------------------------------------------------------- detection
    def detect(self, image: np.ndarray, region: tuple[int, int, int, int] | None = None,
               scale: int = 1) -> BoardDetection | None:
        """Find the board in a camera image (grey or BGR); ``None`` when not (reliably) found.

        The checkerboard has no IDs, so only a complete view is accepted: a partial
        pattern cannot be assigned to the right corners and would be mis-posed.

        ``region`` ``(x0, y0, x1, y1)``: search only that part of the image (a crop, no
        copy; the points come back in full-image pixels). ``scale`` (ChArUco and grid
        boards): find the markers on the image shrunk ``scale`` times (area average),
        then refine every corner at full resolution with ``cv2.cornerSubPix`` -- a
        low-resolution corner is within about half a small pixel (``scale / 2`` px) of
        the true one, well inside the refinement window of ``3 scale`` px, so the refined
        corners are as accurate as a full-resolution search's (within 0.1 px against the
        true corners in the tests).
        """
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if region is not None:
            x0, y0, x1, y1 = (int(v) for v in region)
            h, w = gray.shape[:2]
            x0, y0, x1, y1 = max(0, x0), max(0, y0), min(w, x1), min(h, y1)
            if x1 - x0 < 16 or y1 - y0 < 16:
                return None
            found = self.detect(gray[y0:y1, x0:x1], None, scale)
            if found is not None:
                found.image_points = found.image_points + np.array([x0, y0], np.float64)
            return found
        if scale > 1 and self.spec.kind != "checker":
            return self._detect_scaled(gray, int(scale))
        return self._detect_whole(gray, rescue=False)

    def detect_enhanced(self, image: np.ndarray, region: tuple[int, int, int, int] | None = None,
                        upsample: int | None = None) -> BoardDetection | None:
        """The rescue pass for a dim, small or blurred board (what :meth:`detect` missed).

        Method: the searched image (``region``, else the whole frame) is contrast-normalised
        with CLAHE (:data:`RESCUE_CLAHE_CLIP`; a dim board's ink and paper a few grey levels
        apart are stretched locally, a gradient of light across the board is flattened),
        upsampled ``upsample`` times (default: twice when the searched image is narrower than
        :data:`RESCUE_UPSAMPLE_BELOW_PX`; bicubic) so small markers' bit cells can be read,
        and searched with wider detector settings (:func:`_rescue_params`; ChArUco: the
        board's missing markers looked for again where the found ones put them; checker:
        OpenCV's quad-based ``findChessboardCorners`` instead of the sector-based one). A ChArUco
        view with fewer than six corners keeps its markers' corners as extra points (ids from
        :data:`MARKER_CORNER_ID_BASE`). Points come back in the frame's pixels.
        """
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        h, w = gray.shape[:2]
        x0, y0, x1, y1 = (0, 0, w, h) if region is None else (max(0, int(region[0])), max(0, int(region[1])),
                                                              min(w, int(region[2])), min(h, int(region[3])))
        if x1 - x0 < 16 or y1 - y0 < 16:
            return None
        crop = self._clahe.apply(np.ascontiguousarray(gray[y0:y1, x0:x1]))
        up = (2 if x1 - x0 < RESCUE_UPSAMPLE_BELOW_PX else 1) if upsample is None else max(1, int(upsample))
        if up > 1:
            crop = cv2.resize(crop, None, fx=up, fy=up, interpolation=cv2.INTER_CUBIC)
        found = self._detect_whole(crop, rescue=True)
        if found is not None:
            found.image_points = (found.image_points + 0.5) / up - 0.5 + np.array([x0, y0], np.float64)
        return found

    def _detect_whole(self, gray: np.ndarray, rescue: bool) -> BoardDetection | None:
        """:meth:`detect` on a whole (grey) image; ``rescue``: with the rescue pass's detector settings."""
        kind = self.spec.kind
        total = len(self.all_object_points)
        if kind == "checker":
            # CALIB_CB_ACCURACY costs ~4x the time and was less accurate on the bench than
            # a cornerSubPix pass with a window scaled to the square size
            size = (self.spec.cols, self.spec.rows)
            if rescue:  # the quad-based detector: it finds some boards SB misses, and fails fast
                found, corners = cv2.findChessboardCorners(gray, size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH
                                                           | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK)
            else:
                found, corners = cv2.findChessboardCornersSB(gray, size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
            if not found or corners is None or len(corners) != total:
                return None
            grid = corners.reshape(self.spec.rows, self.spec.cols, 2)
            side = float(np.median(np.linalg.norm(np.diff(grid, axis=1), axis=-1)))
            half = int(np.clip(side * 0.3, 2, 10))
            crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 1e-3)
            corners = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2).astype(np.float32), (half, half), (-1, -1), crit)
            img = corners.reshape(-1, 2).astype(np.float64)
            img = self._orient_checker(gray, img)
            return BoardDetection(self.all_object_points.copy(), img, np.arange(total), total)
        detector = self._rescue_detector if rescue else self._detector
        if kind == "charuco":
            cc, cids, mc, mids = detector.detectBoard(gray)
            n = 0 if cids is None else len(cids)
            if n < 4 and not (rescue and mids is not None and len(mids)):
                return None
            obj = np.zeros((0, 3)) if n == 0 else self._cv_board.matchImagePoints(
                np.asarray(cc, np.float32).reshape(-1, 1, 2), np.asarray(cids, np.int32).reshape(-1, 1))[0]
            found = BoardDetection(np.asarray(obj, np.float64).reshape(-1, 3),
                                   np.asarray(cc if n else np.zeros((0, 2)), np.float64).reshape(-1, 2),
                                   np.asarray(cids if n else [], np.int64).ravel(), total)
            if rescue and n < 6 and mids is not None:  # few corners: the markers' corners stand in
                found = self._with_marker_corners(found, mc, mids)
            return found if found.n >= 4 else None
        corners, ids, _rej = detector.detectMarkers(gray)
        if ids is None or len(ids) < 1:
            return None
        obj, img = self._cv_board.matchImagePoints(corners, ids)
        if obj is None or len(obj) < 4:
            return None
        point_ids = (np.repeat(ids.ravel() * 4, 4) + np.tile(np.arange(4), len(ids)))
        return BoardDetection(np.asarray(obj, np.float64).reshape(-1, 3), np.asarray(img, np.float64).reshape(-1, 2),
                              point_ids, total)

    def _with_marker_corners(self, found: BoardDetection, marker_corners, marker_ids) -> BoardDetection:
        """``found`` plus the detected markers' four corners (ids :data:`MARKER_CORNER_ID_BASE` + 4 id + k)."""
        ids = np.asarray(marker_ids, np.int64).ravel()
        keep = ids < len(self._marker_object_points)
        if not keep.any():
            return found
        img = np.asarray(marker_corners, np.float64).reshape(-1, 4, 2)[keep].reshape(-1, 2)
        obj = self._marker_object_points[ids[keep]].reshape(-1, 3)
        point_ids = MARKER_CORNER_ID_BASE + (ids[keep, None] * 4 + np.arange(4)).ravel()
        return BoardDetection(np.vstack([found.object_points, obj]), np.vstack([found.image_points, img]),
                              np.concatenate([found.ids, point_ids]), found.total_points)

    def _detect_scaled(self, gray: np.ndarray, scale: int) -> BoardDetection | None:
        """Markers on the shrunk image, corners refined at full resolution (see :meth:`detect`)."""
        h, w = gray.shape[:2]
        small = cv2.resize(gray, (w // scale, h // scale), interpolation=cv2.INTER_AREA)
        found = self.detect(small)
        if found is None:
            return None
        pts = ((found.image_points + 0.5) * scale - 0.5).astype(np.float32).reshape(-1, 1, 2)
        half = 3 * scale
        inside = np.all((pts.reshape(-1, 2) >= half + 1) & (pts.reshape(-1, 2) < np.array([w, h]) - half - 1), axis=1)
        if not inside.all():  # a window must fit in the image
            pts, found.object_points, found.ids = pts[inside], found.object_points[inside], found.ids[inside]
            if len(pts) < 4:
                return None
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 1e-3)
        pts = cv2.cornerSubPix(gray, pts, (half, half), (-1, -1), crit)
        found.image_points = pts.reshape(-1, 2).astype(np.float64)
        return found

    def _orient_checker(self, gray: np.ndarray, img: np.ndarray) -> np.ndarray:
        """Resolve the checkerboard's 180-degree ambiguity so corner 0 is the printed top-left.

        findChessboardCornersSB may list the corners from either end. The printed square
        diagonally outside corner 0 is black and its neighbour along +x is white; sample
        both through the corner homography and reverse the order when they disagree.
        With inner-corner counts whose sum is even the board is 180-degree symmetric and
        the ambiguity cannot be resolved (the CLI warns about such specs).
        """
        s = self.spec.square_m
        H, _ = cv2.findHomography(self.all_object_points[:, :2], img)
        if H is None:
            return img
        probes = np.array([[[0.5 * s, 0.5 * s]], [[1.5 * s, 0.5 * s]]])
        pts = cv2.perspectiveTransform(probes, H).reshape(-1, 2)
        h, w = gray.shape
        vals = []
        for x, y in pts:
            xi, yi = int(round(x)), int(round(y))
            if not (1 <= xi < w - 1 and 1 <= yi < h - 1):
                return img
            vals.append(float(gray[yi - 1:yi + 2, xi - 1:xi + 2].mean()))
        return img[::-1].copy() if vals[0] > vals[1] else img

    # ----------------------------------------------------------------- drawing
    def texture(self, px_per_m: float) -> tuple[np.ndarray, float]:
        """Draw the whole sheet (pattern + white margin), grey uint8, top-left = sheet corner.

        Returns the image and the exact pixels-per-metre used (rounded so a square is a
        whole number of pixels, which keeps marker cells crisp). Pixel (u, v) covers board
        point ((u + 0.5) / ppm - m, (v + 0.5) / ppm - m) with m = ``texture_origin_m(ppm)``.
        """
        s = self.spec
        cell = s.square_m
        px_square = max(8, int(round(cell * px_per_m)))
        if s.kind == "charuco":  # make the marker's bit cells integral too
            bits = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, s.dictionary)).markerSize + 2
            px_marker = max(bits, int(round(s.marker_m / cell * px_square / bits)) * bits)
            px_square = int(round(px_marker * cell / s.marker_m))
        ppm = px_square / cell
        margin_px = int(round(self.margin_m * ppm))
        w = int(round(self.pattern_size_m[0] * ppm))
        h = int(round(self.pattern_size_m[1] * ppm))
        if s.kind == "checker":
            ys, xs = np.mgrid[0:h, 0:w]
            pattern = np.where(((xs // px_square) + (ys // px_square)) % 2 == 0, 0, 255).astype(np.uint8)
        elif s.kind == "charuco":
            pattern = self._cv_board.generateImage((w, h), marginSize=0, borderBits=1)
        else:
            pattern = self._cv_board.generateImage((w, h), marginSize=0, borderBits=1)
        sheet = np.full((h + 2 * margin_px, w + 2 * margin_px), 255, np.uint8)
        sheet[margin_px:margin_px + h, margin_px:margin_px + w] = pattern
        return sheet, ppm

    def texture_origin_m(self, px_per_m: float) -> float:
        """Margin actually drawn by :meth:`texture` at the ppm it returned (whole pixels)."""
        return round(self.margin_m * px_per_m) / px_per_m


def write_board(board: Board, out: str | Path, dpi: int = 300) -> Path:
    """Write the board sheet to print at true size: PNG with DPI metadata, or a PDF page.

    The PDF page is exactly the sheet size (pattern + margin); print at 100 % / "actual
    size" and check one square with a ruler.
    """
    out = Path(out)
    ppm = dpi / 0.0254
    sheet, ppm = board.texture(ppm)
    true_dpi = ppm * 0.0254
    suffix = out.suffix.lower()
    out.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".png":
        from PIL import Image  # optional: Pillow (absent on Android, where no board is printed)

        Image.fromarray(sheet).save(out, dpi=(true_dpi, true_dpi))
    elif suffix == ".pdf":
        import matplotlib  # optional: matplotlib (absent on Android, where no board is printed)

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt  # optional: matplotlib (after choosing the Agg backend)

        w_in = sheet.shape[1] / true_dpi
        h_in = sheet.shape[0] / true_dpi
        fig = plt.figure(figsize=(w_in, h_in))
        ax = fig.add_axes((0, 0, 1, 1))
        ax.imshow(sheet, cmap="gray", vmin=0, vmax=255, interpolation="nearest")
        ax.set_axis_off()
        fig.text(0.01, 0.002, f"StoryBeam {board.spec}  square {board.spec.square_m * 1000:g} mm", fontsize=5, color="0.5")
        fig.savefig(out, dpi=true_dpi)
        plt.close(fig)
    else:
        raise BoardSpecError(f"{out}: board output must be .png or .pdf")
    return out
