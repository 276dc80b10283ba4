"""BlazePose's pre- and post-processing, as MediaPipe's ``pose_landmark_cpu`` graph does it.

Every constant below was read from the graphs inside the ``mediapipe==0.10.21`` wheel
(``pose_landmark_cpu.binarypb`` and the subgraphs registered in its
``_framework_bindings`` library: PoseDetectionCpu, PoseDetectionToRoi,
PoseLandmarkByRoiCpu, TensorsToPoseLandmarksAndSegmentation,
PoseLandmarksAndSegmentationInverseProjection, PoseLandmarksToRoi); the methods follow
the calculators named in each docstring. Pure numpy plus OpenCV's warps; no interpreter.

Precision: MediaPipe computes in float32 (C++ ``float``) and the landmark model is
sensitive to single grey levels of its crop, so the arithmetic is replayed in float32, in
MediaPipe's order, down to OpenCV 4's corner points, perspective solve and fixed-point
warp (:func:`rect_transform`, :func:`warp_maps`): on the stored reference renders the
crops are bit-identical to MediaPipe's.

Conventions: a *rect* is MediaPipe's ``NormalizedRect`` -- centre, width and height as
fractions of the image width/height, rotation in radians (clockwise on screen, image y
down); *normalised* points are (x / W, y / H).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import math
import threading
from dataclasses import dataclass

import cv2
import numpy as np

# ---- PoseDetectionCpu ----------------------------------------------------------------
DETECTOR_SIZE = 224
#: SsdAnchorsCalculatorOptions
ANCHOR_STRIDES = (8, 16, 32, 32, 32)
ANCHOR_MIN_SCALE, ANCHOR_MAX_SCALE = 0.1484375, 0.75
ANCHOR_OFFSET = 0.5
#: TensorsToDetectionsCalculatorOptions (num_boxes 2254, 12 coords: box then 4 keypoints)
NUM_ANCHORS = 2254
NUM_KEYPOINTS = 4
SCORE_CLIP = 100.0
MIN_DETECTION_SCORE = 0.5
#: NonMaxSuppressionCalculatorOptions (IoU, WEIGHTED)
NMS_MIN_SUPPRESSION = 0.3
# ---- PoseDetectionToRoi / PoseLandmarksToRoi -----------------------------------------
ROI_SCALE = 1.25
ROI_TARGET_ANGLE = np.pi / 2  # rotation_vector_target_angle_degrees: 90
# ---- PoseLandmarkByRoiCpu ------------------------------------------------------------
LANDMARK_SIZE = 256
NUM_MODEL_LANDMARKS = 39  # 33 body + 2 auxiliary (ROI) + 4 unused
NUM_LANDMARKS = 33
AUX_SLICE = slice(33, 35)
#: The graph asks RefineLandmarksFromHeatmapCalculator for kernel_size 7, but mediapipe's
#: Python solution (``mp.solutions.pose``) loses that option when it expands the graph
#: (its canonical config holds an empty options block for that node), so the calculator
#: runs with its default, 9. StoryBeam follows what MediaPipe actually runs: with 7, feet
#: and hands differ from the reference by up to 2 px; with 9 they agree (docs/notebook/pose.md).
HEATMAP_KERNEL = 9
HEATMAP_MIN_CONFIDENCE = 0.5  # RefineLandmarksFromHeatmapCalculatorOptions default
POSE_PRESENCE_THRESHOLD = 0.5  # ThresholdingCalculator: present when flag > 0.5


def _libm_float_functions() -> tuple:
    """The C library's float ``atan2f``, ``cosf``, ``sinf`` (what MediaPipe's
    ``std::atan2(float, float)`` etc. call), or numpy float32 stand-ins where there is no
    loadable libm; they differ in the last bit now and then."""
    for candidate in (ctypes.util.find_library("m"), "libm.so.6", "libm.so"):
        if not candidate:
            continue
        try:
            libm = ctypes.CDLL(candidate)
            fns = []
            for name, nargs in (("atan2f", 2), ("cosf", 1), ("sinf", 1)):
                fn = getattr(libm, name)
                fn.restype, fn.argtypes = ctypes.c_float, [ctypes.c_float] * nargs
                fns.append(fn)
            return tuple(fns)
        except (OSError, AttributeError):
            continue
    return (lambda y, x: np.arctan2(np.float32(y), np.float32(x)),
            lambda a: np.cos(np.float32(a)), lambda a: np.sin(np.float32(a)))


_ATAN2F, _COSF, _SINF = _libm_float_functions()


@dataclass(frozen=True)
class Rect:
    """MediaPipe's ``NormalizedRect``: centre and size as fractions of the image, rotation
    in radians."""

    x_center: float
    y_center: float
    width: float
    height: float
    rotation: float = 0.0

    @property
    def usable(self) -> bool:
        """A region with a finite centre and a positive finite size (a crop can be taken)."""
        v = (self.x_center, self.y_center, self.width, self.height, self.rotation)
        return all(math.isfinite(x) for x in v) and self.width > 0 and self.height > 0


@dataclass(frozen=True)
class Detection:
    """One detector hit, normalised to the input image (letterbox removed): ``box`` =
    (xmin, ymin, width, height), ``keypoints`` (4, 2): mid-hip, full-body size/rotation
    point, mid-shoulder, upper-body point."""

    score: float
    box: np.ndarray
    keypoints: np.ndarray


def ssd_anchors(input_size: int = DETECTOR_SIZE, strides: tuple[int, ...] = ANCHOR_STRIDES,
                offset: float = ANCHOR_OFFSET) -> np.ndarray:
    """Anchor centres (N, 2), normalised, in the detector's output order
    (SsdAnchorsCalculator with one aspect ratio 1.0, the default interpolated-scale anchor,
    ``fixed_anchor_size``: every anchor is 1x1, so only centres matter). Consecutive layers
    of one stride share a feature map: per cell, 2 anchors per layer."""
    out = []
    layer = 0
    while layer < len(strides):
        last = layer
        while last < len(strides) and strides[last] == strides[layer]:
            last += 1
        per_cell = 2 * (last - layer)  # aspect 1.0 + the interpolated scale, per layer
        n = int(np.ceil(input_size / strides[layer]))
        ys, xs = np.meshgrid((np.arange(n) + offset) / n, (np.arange(n) + offset) / n, indexing="ij")
        centres = np.stack([xs.ravel(), ys.ravel()], axis=1)
        out.append(np.repeat(centres, per_cell, axis=0))
        layer = last
    return np.concatenate(out).astype(np.float32)


def letterbox_transform(image_size: tuple[int, int], out_size: int = DETECTOR_SIZE) -> tuple[np.ndarray, tuple[float, float]]:
    """The 3x3 transform image -> the detector's square input (ImageToTensorCalculator,
    ``keep_aspect_ratio``: the whole image centred, the short side padded), and the
    padding (horizontal, vertical) as fractions of the square on each side."""
    return rect_transform(Rect(0.5, 0.5, 1.0, 1.0), image_size, out_size)


def box_points(cx: float, cy: float, width: float, height: float, degrees: float) -> np.ndarray:
    """The corners (4, 2) float32 of a rotated rectangle, in ``cv::RotatedRect::points``'
    order and float32 arithmetic (OpenCV 4, as linked into MediaPipe; OpenCV 5 rounds
    the last bit differently)."""
    f32 = np.float32
    angle = float(np.float32(degrees)) * math.pi / 180.0
    b = f32(math.cos(angle)) * f32(0.5)
    a = f32(math.sin(angle)) * f32(0.5)
    cx, cy, w, h = f32(cx), f32(cy), f32(width), f32(height)
    p0 = (cx - a * h - b * w, cy + b * h - a * w)
    p1 = (cx + a * h - b * w, cy - b * h - a * w)
    two = f32(2.0)
    return np.array([p0, p1, (two * cx - p0[0], two * cy - p0[1]), (two * cx - p1[0], two * cy - p1[1])], np.float32)


def _lu_solve(a: list[list[float]], b: list[float]) -> list[float]:
    """OpenCV 4's ``LUImpl`` (Gaussian elimination, partial pivoting, in this order of
    operations), for bit-identical results; ``ValueError`` for a singular system."""
    m = len(b)
    for i in range(m):
        k = max(range(i, m), key=lambda j: (abs(a[j][i]), -j))
        if abs(a[k][i]) < 2.2e-16:
            raise ValueError("degenerate region: singular perspective system")
        if k != i:
            a[i], a[k] = a[k], a[i]
            b[i], b[k] = b[k], b[i]
        d = -1.0 / a[i][i]
        for j in range(i + 1, m):
            alpha = a[j][i] * d
            for c in range(i + 1, m):
                a[j][c] += alpha * a[i][c]
            b[j] += alpha * b[i]
    for i in range(m - 1, -1, -1):
        s = b[i]
        for c in range(i + 1, m):
            s -= a[i][c] * b[c]
        b[i] = s / a[i][i]
    return b


def perspective_transform(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """``cv::getPerspectiveTransform`` as in OpenCV 4 (its 8x8 system with float32
    products, solved by :func:`_lu_solve`)."""
    src, dst = np.asarray(src, np.float32), np.asarray(dst, np.float32)
    a = [[0.0] * 8 for _ in range(8)]
    b = [0.0] * 8
    for i in range(4):
        sx, sy, dx, dy = src[i, 0], src[i, 1], dst[i, 0], dst[i, 1]
        a[i][0] = a[i + 4][3] = float(sx)
        a[i][1] = a[i + 4][4] = float(sy)
        a[i][2] = a[i + 4][5] = 1.0
        a[i][6], a[i][7] = float(-sx * dx), float(-sy * dx)
        a[i + 4][6], a[i + 4][7] = float(-sx * dy), float(-sy * dy)
        b[i], b[i + 4] = float(dx), float(dy)
    return np.array(_lu_solve(a, b) + [1.0], np.float64).reshape(3, 3)


def invert_3x3(m: np.ndarray) -> np.ndarray:
    """``cv::invert`` of a 3x3 double matrix (OpenCV's cofactor formula, same order)."""
    s = [[float(v) for v in row] for row in np.asarray(m, np.float64)]
    det = (s[0][0] * (s[1][1] * s[2][2] - s[1][2] * s[2][1]) - s[0][1] * (s[1][0] * s[2][2] - s[1][2] * s[2][0])
           + s[0][2] * (s[1][0] * s[2][1] - s[1][1] * s[2][0]))
    if det == 0.0:
        return np.zeros((3, 3))
    d = 1.0 / det
    return np.array([
        [(s[1][1] * s[2][2] - s[1][2] * s[2][1]) * d, (s[0][2] * s[2][1] - s[0][1] * s[2][2]) * d,
         (s[0][1] * s[1][2] - s[0][2] * s[1][1]) * d],
        [(s[1][2] * s[2][0] - s[1][0] * s[2][2]) * d, (s[0][0] * s[2][2] - s[0][2] * s[2][0]) * d,
         (s[0][2] * s[1][0] - s[0][0] * s[1][2]) * d],
        [(s[1][0] * s[2][1] - s[1][1] * s[2][0]) * d, (s[0][1] * s[2][0] - s[0][0] * s[2][1]) * d,
         (s[0][0] * s[1][1] - s[0][1] * s[1][0]) * d],
    ])


def pad_roi(width: np.float32, height: np.float32) -> tuple[np.float32, np.float32, tuple[np.float32, np.float32]]:
    """ImageToTensorCalculator's PadRoi for a square tensor (``keep_aspect_ratio``): the
    region grown to the tensor's aspect, and the padding (horizontal, vertical) it adds,
    as fractions of each side (float32, as there)."""
    f32 = np.float32
    one, two = f32(1.0), f32(2.0)
    roi_aspect = height / width
    if one > roi_aspect:
        return width, width * one, (f32(0.0), (one - roi_aspect / one) / two)
    return height / one, height, ((one - one / roi_aspect) / two, f32(0.0))


def rect_transform(rect: Rect, image_size: tuple[int, int], out_size: int) -> tuple[np.ndarray, tuple[float, float]]:
    """The 3x3 perspective matrix mapping the rotated ``rect`` onto an ``out_size`` square,
    and the letterbox padding (horizontal, vertical) of the crop, as MediaPipe's
    ImageToTensorCalculator and OpenCV converter compute them: the rect in pixels and its
    angle in degrees in float32, padded to a square (:func:`pad_roi`), its corners
    (:func:`box_points`) -> (0, S), (0, 0), (S, 0), (S, S), :func:`perspective_transform`."""
    if not rect.usable:
        raise ValueError(f"degenerate region {rect}")
    f32 = np.float32
    w, h = f32(image_size[0]), f32(image_size[1])
    cx, cy = f32(rect.x_center) * w, f32(rect.y_center) * h
    rw, rh, padding = pad_roi(f32(rect.width) * w, f32(rect.height) * h)
    degrees = f32(np.float64(f32(rect.rotation) * f32(180.0)) / np.pi)
    s = float(out_size)
    dst = np.array([[0.0, s], [0.0, 0.0], [s, 0.0], [s, s]], np.float32)
    return perspective_transform(box_points(cx, cy, rw, rh, degrees), dst), padding


#: OpenCV's fixed-point warp: 5 fractional bits per coordinate (INTER_BITS)
_INTER_BITS = 5
_INTER_TAB = 1 << _INTER_BITS
#: OpenCV 4's warpPerspective works in blocks of 64 columns x 16 rows (BLOCK_SZ 32)
_BLOCK_W = 64


def warp_maps(matrix: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """The fixed-point maps with which OpenCV 4's ``warpPerspective(src, matrix, (size,
    size), INTER_LINEAR)`` samples (the version inside MediaPipe; OpenCV 5 differs in the
    last bits, and the landmark model is sensitive to single grey levels of its input):
    the matrix inverted (:func:`invert_3x3`), each output pixel's source point computed
    in double in the same order (per 64-column block: ``(M0·xb + M1·y + M2) + M0·x1``, over
    ``W0 + M6·x1``), times 32, rounded half to even; returned as the integer part (int16
    pairs) and the 5+5-bit fraction (bilinear table index) for ``cv2.remap``, which then
    samples exactly as OpenCV 4 does."""
    mi = invert_3x3(matrix).ravel()
    buf = _warp_buffers(size)
    blocks, bw = buf["blocks"], buf["bw"]
    xb, x1, y = buf["xb"], buf["x1"], buf["y"]

    def line(m0: float, m1: float, m2: float, out: np.ndarray) -> np.ndarray:
        # (M0·xb + M1·y + M2) per row and block, then + M0·x1 per column: OpenCV's order
        np.add(((m0 * xb + m1 * y) + m2)[:, :, None], m0 * x1, out=out.reshape(size, blocks, bw))
        return out

    wd, fx, fy = line(mi[6], mi[7], mi[8], buf["w"]), line(mi[0], mi[1], mi[2], buf["x"]), line(mi[3], mi[4], mi[5], buf["y2"])
    if np.all(wd != 0.0):
        np.divide(_INTER_TAB, wd, out=wd)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            np.copyto(wd, np.where(wd != 0.0, _INTER_TAB / wd, 0.0))
    fx *= wd
    fy *= wd
    lim = 2.0 ** 31 - 1
    np.clip(fx, -lim - 1, lim, out=fx)
    np.clip(fy, -lim - 1, lim, out=fy)
    ix, iy = buf["ix"], buf["iy"]
    np.rint(fx, out=fx)
    np.rint(fy, out=fy)
    ix[...] = fx
    iy[...] = fy
    xy = np.empty((size, size, 2), np.int16)
    np.clip(ix[:, :size] >> _INTER_BITS, -32768, 32767, out=xy[..., 0], casting="unsafe")
    np.clip(iy[:, :size] >> _INTER_BITS, -32768, 32767, out=xy[..., 1], casting="unsafe")
    ix &= _INTER_TAB - 1
    iy &= _INTER_TAB - 1
    iy <<= _INTER_BITS
    iy |= ix
    return xy, iy[:, :size].astype(np.uint16)


_BUFFERS = threading.local()


def _warp_buffers(size: int) -> dict:
    """Per-thread scratch arrays for :func:`warp_maps` (fresh 0.5 MB arrays every frame
    cost more in page faults than the arithmetic)."""
    cache = getattr(_BUFFERS, "by_size", None)
    if cache is None:
        cache = _BUFFERS.by_size = {}
    if size not in cache:
        blocks, bw = -(-size // _BLOCK_W), min(_BLOCK_W, size)
        shape = (size, blocks * bw)
        cache[size] = {
            "blocks": blocks, "bw": bw,
            "xb": (np.arange(blocks) * bw).astype(np.float64)[None, :],  # block starts
            "x1": np.arange(bw, dtype=np.float64)[None, None, :],  # columns within a block
            "y": np.arange(size, dtype=np.float64)[:, None],
            "w": np.empty(shape), "x": np.empty(shape), "y2": np.empty(shape),
            "ix": np.empty(shape, np.int32), "iy": np.empty(shape, np.int32),
        }
    return cache[size]


def warp_to_tensor(frame_bgr: np.ndarray, matrix: np.ndarray, size: int, value_range: tuple[float, float],
                   border: int) -> np.ndarray:
    """Crop through ``matrix`` (bilinear, OpenCV 4's fixed-point sampling (:func:`warp_maps`),
    ``border`` = cv2.BORDER_CONSTANT (zero) or cv2.BORDER_REPLICATE), BGR -> RGB, and scale
    to ``value_range``: a (1, S, S, 3) float32 -- a per-thread buffer, overwritten by the
    next call of the same size."""
    xy, frac = warp_maps(matrix, size)
    crop = cv2.remap(frame_bgr, xy, frac, cv2.INTER_LINEAR, borderMode=border, borderValue=(0, 0, 0))
    crop = cv2.cvtColor(crop, cv2.COLOR_BGR2RGB)
    out = _tensor_buffer(size)
    np.take(_value_table(*value_range), crop, out=out[0])
    return out


def _tensor_buffer(size: int) -> np.ndarray:
    """A per-thread (1, S, S, 3) float32 input buffer (reused: valid until the next
    :func:`warp_to_tensor` of that size in the thread)."""
    cache = getattr(_BUFFERS, "tensors", None)
    if cache is None:
        cache = _BUFFERS.tensors = {}
    if size not in cache:
        cache[size] = np.empty((1, size, size, 3), np.float32)
    return cache[size]


def _value_table(lo: float, hi: float) -> np.ndarray:
    """Byte -> float32 as OpenCV's ``convertTo(scale, offset)`` gives it (one rounding: the
    float32 scale times a byte is exact in double, so double then float32 matches)."""
    key = (float(lo), float(hi))
    table = _VALUE_TABLES.get(key)
    if table is None:
        scale = float(np.float32(hi - lo) / np.float32(255.0))
        table = _VALUE_TABLES[key] = (np.arange(256, dtype=np.float64) * scale + float(np.float32(lo))).astype(np.float32)
    return table


_VALUE_TABLES: dict[tuple[float, float], np.ndarray] = {}


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """1 / (1 + exp(-x)) in float32, as MediaPipe's ``1.0f / (1.0f + std::exp(-x))``."""
    x = np.asarray(x, np.float32)
    with np.errstate(over="ignore"):  # exp(-x) -> inf for very negative x: sigmoid 0, as intended
        e = np.exp(-x.astype(np.float64)).astype(np.float32)  # expf, correctly rounded
        return np.float32(1.0) / (np.float32(1.0) + e)


def decode_detections(raw_boxes: np.ndarray, raw_scores: np.ndarray, anchors: np.ndarray,
                      min_score: float = MIN_DETECTION_SCORE, scale: float = DETECTOR_SIZE) -> list[Detection]:
    """Scored boxes and keypoints of every anchor at or above ``min_score``
    (TensorsToDetectionsCalculator: ``reverse_output_order`` (x before y), offsets divided
    by ``scale`` and added to the anchor centre, anchor size 1; scores clipped at
    +-:data:`SCORE_CLIP` then sigmoid; float32). Coordinates are on the detector's
    letterboxed square; ``box`` = (xmin, ymin, width, height)."""
    raw_boxes = np.asarray(raw_boxes, np.float32).reshape(-1, 4 + 2 * NUM_KEYPOINTS)
    scores = _sigmoid(np.clip(np.asarray(raw_scores, np.float32).reshape(-1), -SCORE_CLIP, SCORE_CLIP))
    keep = np.flatnonzero(scores >= np.float32(min_score))
    f32 = np.float32
    sc, half = f32(scale), f32(2.0)
    out = []
    for i in keep:
        r, ax, ay = raw_boxes[i], anchors[i, 0], anchors[i, 1]
        xc, yc = r[0] / sc + ax, r[1] / sc + ay
        w, h = r[2] / sc, r[3] / sc
        xmin, ymin, xmax, ymax = xc - w / half, yc - h / half, xc + w / half, yc + h / half
        kp = (r[4:].reshape(NUM_KEYPOINTS, 2) / sc + anchors[i]).astype(np.float32)
        out.append(Detection(float(scores[i]), np.array([xmin, ymin, xmax - xmin, ymax - ymin], np.float32), kp))
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two (xmin, ymin, width, height) boxes (0 when apart;
    float32, as MediaPipe's OverlapSimilarity)."""
    a, b = np.asarray(a, np.float32), np.asarray(b, np.float32)
    x0, y0 = max(a[0], b[0]), max(a[1], b[1])
    x1, y1 = min(a[0] + a[2], b[0] + b[2]), min(a[1] + a[3], b[1] + b[3])
    if x1 < x0 or y1 < y0:
        return 0.0
    inter = (x1 - x0) * (y1 - y0)
    union = a[2] * a[3] + b[2] * b[3] - inter
    return float(inter / union) if union > 0 else 0.0


def weighted_nms(detections: list[Detection], threshold: float = NMS_MIN_SUPPRESSION) -> list[Detection]:
    """NonMaxSuppressionCalculator, WEIGHTED: take the best remaining detection; every
    remaining one overlapping it by IoU > ``threshold`` (itself included) is merged into a
    score-weighted mean box and keypoints (the best one's score kept; float32 sums in
    order) and removed. Output in descending score."""
    f32 = np.float32
    remaining = sorted(detections, key=lambda d: -d.score)
    out = []
    while remaining:
        best = remaining[0]
        group = [d for d in remaining if iou(d.box, best.box) > threshold]
        rest = [d for d in remaining if not iou(d.box, best.box) > threshold]
        total, corners, kp = f32(0.0), np.zeros(4, np.float32), np.zeros((NUM_KEYPOINTS, 2), np.float32)
        for d in group:
            w = f32(d.score)
            total = total + w
            corners += np.array([d.box[0], d.box[1], d.box[0] + d.box[2], d.box[1] + d.box[3]], np.float32) * w
            kp += d.keypoints * w
        xmin, ymin = corners[0] / total, corners[1] / total
        box = np.array([xmin, ymin, corners[2] / total - xmin, corners[3] / total - ymin], np.float32)
        out.append(Detection(best.score, box, (kp / total).astype(np.float32)))
        if len(rest) == len(remaining):
            break
        remaining = rest
    return out


def remove_letterbox(det: Detection, padding: tuple[float, float]) -> Detection:
    """DetectionLetterboxRemovalCalculator: from the padded square back to the image."""
    f32 = np.float32
    px, py = f32(padding[0]), f32(padding[1])
    sx, sy = f32(1.0) - (px + px), f32(1.0) - (py + py)
    b = det.box
    box = np.array([(b[0] - px) / sx, (b[1] - py) / sy, b[2] / sx, b[3] / sy], np.float32)
    kp = ((det.keypoints - np.array([px, py], np.float32)) / np.array([sx, sy], np.float32)).astype(np.float32)
    return Detection(det.score, box, kp)


def normalize_radians(angle: float) -> float:
    """Into [-pi, pi) (MediaPipe's NormalizeRadians, in double, stored as float32)."""
    a = float(np.float32(angle))
    return float(np.float32(a - 2 * np.pi * np.floor((a - (-np.pi)) / (2 * np.pi))))


_TARGET_ANGLE_F32 = np.float32(np.pi * 90.0 / 180.0)


def alignment_rect(p0: np.ndarray, p1: np.ndarray, image_size: tuple[int, int]) -> Rect:
    """AlignmentPointsRectsCalculator on normalised points: centre ``p0``, a square of side
    2·|p1 − p0| (pixels), rotation 90° − atan2(−(y1 − y0), x1 − x0), normalised (float32)."""
    f32 = np.float32
    w, h = f32(image_size[0]), f32(image_size[1])
    x0, y0 = f32(p0[0]) * w, f32(p0[1]) * h
    x1, y1 = f32(p1[0]) * w, f32(p1[1]) * h
    size = f32(np.sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0), dtype=np.float32) * f32(2.0))
    rotation = normalize_radians(_TARGET_ANGLE_F32 - np.float32(_ATAN2F(float(-(y1 - y0)), float(x1 - x0))))
    return Rect(float(x0 / w), float(y0 / h), float(size / w), float(size / h), rotation)


def roi_from_points(p0: np.ndarray, p1: np.ndarray, image_size: tuple[int, int], scale: float = ROI_SCALE) -> Rect:
    """PoseDetectionToRoi / PoseLandmarksToRoi: :func:`alignment_rect`, then
    RectTransformationCalculator (``square_long``, both sides × ``scale``; float32)."""
    f32 = np.float32
    r = alignment_rect(p0, p1, image_size)
    w, h = f32(image_size[0]), f32(image_size[1])
    long_side = max(f32(r.width) * w, f32(r.height) * h)
    return Rect(r.x_center, r.y_center, float(long_side / w * f32(scale)), float(long_side / h * f32(scale)),
                r.rotation)


def decode_landmarks(raw: np.ndarray, size: int = LANDMARK_SIZE) -> np.ndarray:
    """TensorsToLandmarksCalculator: (39, 5) float32 = x, y, z divided by the input size
    (normalised to the crop), sigmoid visibility and presence."""
    lm = np.asarray(raw, np.float32).reshape(NUM_MODEL_LANDMARKS, 5).copy()
    lm[:, :3] /= np.float32(size)
    lm[:, 3:] = _sigmoid(lm[:, 3:])
    return lm


def refine_from_heatmap(landmarks: np.ndarray, heatmap: np.ndarray, kernel: int = HEATMAP_KERNEL,
                        min_confidence: float = HEATMAP_MIN_CONFIDENCE) -> np.ndarray:
    """RefineLandmarksFromHeatmapCalculator: each landmark's x, y replaced by the
    confidence-weighted mean cell of a ``kernel``-wide window of its heatmap channel
    (sigmoid of the raw map) around its cell, when the window's highest confidence is at
    least ``min_confidence``. Cells are ``int(x · 64)`` (truncated toward zero, as in C++);
    the calculator's out-of-map test compares the column with the map height (a quirk
    kept: equal sizes here). Sums in float32, row by row, as there."""
    hm = np.asarray(heatmap, np.float32).reshape(heatmap.shape[-3:])
    rows, cols, n = hm.shape
    out = np.asarray(landmarks, np.float32).copy()
    off = (kernel - 1) // 2
    col = np.trunc(out[:n, 0] * np.float32(cols)).astype(np.int64)  # C++ float -> int: toward zero
    row = np.trunc(out[:n, 1] * np.float32(rows)).astype(np.int64)
    inside = (col >= 0) & (col < cols) & (row >= 0) & (col < rows)
    k = np.arange(-off, off + 1)
    rr = np.broadcast_to(row[:, None, None] + k[None, :, None], (n, kernel, kernel))
    cc = np.broadcast_to(col[:, None, None] + k[None, None, :], (n, kernel, kernel))
    ok = (rr >= 0) & (rr < rows) & (cc >= 0) & (cc < cols) & inside[:, None, None]
    vals = hm[np.clip(rr, 0, rows - 1), np.clip(cc, 0, cols - 1), np.arange(n)[:, None, None]]
    conf = np.where(ok, _sigmoid(vals), np.float32(0.0)).reshape(n, -1)
    # sequential float32 sums in the calculator's loop order (cumsum is sequential)
    total = np.cumsum(conf, axis=1, dtype=np.float32)[:, -1]
    wcol = np.cumsum(cc.reshape(n, -1).astype(np.float32) * conf, axis=1, dtype=np.float32)[:, -1]
    wrow = np.cumsum(rr.reshape(n, -1).astype(np.float32) * conf, axis=1, dtype=np.float32)[:, -1]
    refine = inside & (total > 0) & (conf.max(axis=1) >= np.float32(min_confidence))
    safe = np.where(total > 0, total, np.float32(1.0))
    out[:n, 0] = np.where(refine, wcol / np.float32(cols) / safe, out[:n, 0])
    out[:n, 1] = np.where(refine, wrow / np.float32(rows) / safe, out[:n, 1])
    return out


def remove_crop_letterbox(landmarks: np.ndarray, padding: tuple[float, float]) -> np.ndarray:
    """LandmarkLetterboxRemovalCalculator (the crop's padding is ~0: the region is square)."""
    f32 = np.float32
    px, py = f32(padding[0]), f32(padding[1])
    sx, sy = f32(1.0) - (px + px), f32(1.0) - (py + py)
    out = np.asarray(landmarks, np.float32).copy()
    out[:, 0] = (out[:, 0] - px) / sx
    out[:, 1] = (out[:, 1] - py) / sy
    out[:, 2] = out[:, 2] / sx
    return out


def project_landmarks(landmarks: np.ndarray, rect: Rect) -> np.ndarray:
    """LandmarkProjectionCalculator: crop-normalised (x, y, z, ...) -> image-normalised,
    rotating about the crop centre by ``rect.rotation`` and scaling by its size (z by its
    width, as x); float32."""
    f32 = np.float32
    lm = np.asarray(landmarks, np.float32)
    out = lm.copy()
    x, y = lm[:, 0] - f32(0.5), lm[:, 1] - f32(0.5)
    c, s = f32(_COSF(rect.rotation)), f32(_SINF(rect.rotation))
    out[:, 0] = (c * x - s * y) * f32(rect.width) + f32(rect.x_center)
    out[:, 1] = (s * x + c * y) * f32(rect.height) + f32(rect.y_center)
    out[:, 2] = lm[:, 2] * f32(rect.width)
    return out


def rotate_world(world: np.ndarray, rotation: float) -> np.ndarray:
    """WorldLandmarkProjectionCalculator: x, y rotated by the ROI's rotation, z kept (float32)."""
    w = np.asarray(world, np.float32)
    out = w.copy()
    c, s = np.float32(_COSF(rotation)), np.float32(_SINF(rotation))
    out[:, 0] = c * w[:, 0] - s * w[:, 1]
    out[:, 1] = s * w[:, 0] + c * w[:, 1]
    return out


__all__ = [
    "DETECTOR_SIZE", "ANCHOR_STRIDES", "ANCHOR_MIN_SCALE", "ANCHOR_MAX_SCALE", "ANCHOR_OFFSET", "NUM_ANCHORS",
    "NUM_KEYPOINTS", "SCORE_CLIP", "MIN_DETECTION_SCORE", "NMS_MIN_SUPPRESSION", "ROI_SCALE", "ROI_TARGET_ANGLE",
    "LANDMARK_SIZE", "NUM_MODEL_LANDMARKS", "NUM_LANDMARKS", "AUX_SLICE", "HEATMAP_KERNEL", "HEATMAP_MIN_CONFIDENCE",
    "POSE_PRESENCE_THRESHOLD", "Rect", "Detection", "ssd_anchors", "letterbox_transform", "box_points",
    "perspective_transform", "invert_3x3", "pad_roi", "rect_transform", "warp_maps", "warp_to_tensor",
    "decode_detections", "iou", "weighted_nms", "remove_letterbox", "normalize_radians", "alignment_rect",
    "roi_from_points", "decode_landmarks", "refine_from_heatmap", "remove_crop_letterbox", "project_landmarks",
    "rotate_world",
]
