"""Finding the body wherever it is in the frame, and choosing whom to follow (issue 27).

BlazePose's detector sees the whole frame letterboxed to 224×224, so on a 1920×1080
frame a body is shrunk 8.6 times: measured on pasted renders of the person figure
(docs/notebook/pose.md), the detector finds a standing body once it is about
:data:`DETECTABLE_FRACTION` (28 %) of its input's side tall — 540 px of a 1080p frame,
half its height. A child further away, or at the edge of a wide view, is smaller.

**Tiles.** :func:`tile_grid` covers the frame with square tiles at coarser-to-finer
levels, each tile cropped to the detector's 224×224 input at its own scale: level sides
shrink by :data:`LEVEL_STEP` from the frame's long side (a side within 10 % of the short
side is the short side) down to the side at which a body of ``min_body`` × the frame
height is detectable (``min_body · H / DETECTABLE_FRACTION``). Within a level, tiles are
spread evenly and overlap by at least half the tallest body that level must catch (the
previous level's smallest detectable body): the detector keys on the head and torso, so
that much overlap puts a whole upper body inside some tile. 1920×1080 with the default
``min_body`` = 1/6: 3 tiles of 1080 px and 8 of 643 px. A tile's detections are mapped
back to frame coordinates (:meth:`Tile.to_frame`) and merged with the others by
MediaPipe's weighted non-maximum suppression.

**Whom to follow.** Each detection gives a body region (:func:`ar.body.blazepose.roi_from_points`:
centre at the mid-hip, side from the hip-to-body keypoint distance). At acquisition the
candidates are ranked by :func:`priority`, the region's side over the frame's short side
times ``1 − ½·d`` (``d``: the region centre's distance from the frame centre over half
the diagonal): the most central and largest body first; an edge body (``d`` ≈ 0.9) must be
about 1.8 times the size of a central one to win. When the tracker lost a body it was
following, a candidate :func:`matches` the last followed region when its centre lies within
:data:`MATCH_DISTANCE` of that region's side and its size within a factor
:data:`MATCH_SCALE`; matching candidates come first, the nearest first (:func:`rank`), so a
neighbour who is bigger or more central does not take over after a lost frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ar.body import blazepose as bp

#: Smallest body (its height over the detector input's side) the detector finds, measured
#: on the person figure's walk (``storybeam bench find-body``, docs/notebook/pose.md):
#: found in 12 of 12 frames from 0.28 up, 10–11 of 12 at 0.24–0.26, at most 1 below.
DETECTABLE_FRACTION = 0.28
#: Default smallest body to look for, as a fraction of the frame height.
MIN_BODY = 1.0 / 6.0
#: Ratio between the sides of consecutive tile levels.
LEVEL_STEP = 0.6
#: A candidate continues the followed body when its centre is within this many of the last
#: followed region's sides from that region's centre, plus :data:`MATCH_SPEED` sides per
#: second since it was last seen (a body moves; neighbours stand about half a side apart) ...
MATCH_DISTANCE = 0.25
MATCH_SPEED = 1.5
#: ... and its side within this factor of that region's side.
MATCH_SCALE = 1.6


@dataclass(frozen=True)
class Tile:
    """A square of the frame, in pixels: top-left corner and side; ``level`` 1 is the
    coarsest tile level (level 0, the whole frame, is not a tile)."""

    x0: int
    y0: int
    side: int
    level: int = 1

    @property
    def centre(self) -> tuple[float, float]:
        return self.x0 + self.side / 2.0, self.y0 + self.side / 2.0

    def rect(self, image_size: tuple[int, int]) -> bp.Rect:
        """The tile as a normalised, unrotated :class:`~ar.body.blazepose.Rect`."""
        w, h = image_size
        cx, cy = self.centre
        return bp.Rect(cx / w, cy / h, self.side / w, self.side / h, 0.0)

    def to_frame(self, det: bp.Detection, image_size: tuple[int, int]) -> bp.Detection:
        """A detection normalised to this tile, normalised to the whole frame."""
        w, h = image_size
        scale = np.array([self.side / w, self.side / h], np.float32)
        origin = np.array([self.x0 / w, self.y0 / h], np.float32)
        box = np.asarray(det.box, np.float32)
        return bp.Detection(det.score, np.concatenate([box[:2] * scale + origin, box[2:] * scale]).astype(np.float32),
                            (det.keypoints * scale + origin).astype(np.float32))


def _spread(length: int, side: int, overlap: float) -> list[int]:
    """Starts of tiles of ``side`` covering ``[0, length)`` evenly, consecutive tiles
    overlapping by at least ``overlap``."""
    if side >= length:
        return [0]
    stride = max(1.0, side - overlap)
    n = int(math.ceil((length - side) / stride)) + 1
    return [int(round(i * (length - side) / (n - 1))) for i in range(n)]


def level_sides(image_size: tuple[int, int], min_body: float = MIN_BODY) -> list[int]:
    """The tile sides (pixels), coarse to fine (module docstring); empty when the whole
    frame already shows a ``min_body`` body large enough for the detector."""
    w, h = image_size
    short, long = min(w, h), max(w, h)
    finest = min_body * h / DETECTABLE_FRACTION
    sides: list[int] = []
    side = float(long)
    while side > finest * 1.02:
        side = max(finest, side * LEVEL_STEP)
        if side >= 0.9 * short:
            side = float(short)
        if sides and int(round(side)) >= sides[-1]:
            break
        sides.append(int(round(side)))
    return sides


def tile_grid(image_size: tuple[int, int], min_body: float = MIN_BODY) -> list[Tile]:
    """Every tile of every level (:func:`level_sides`), coarse level first, row by row."""
    w, h = image_size
    tiles: list[Tile] = []
    previous = float(max(w, h))  # level 0: the whole frame, letterboxed
    for level, side in enumerate(level_sides(image_size, min_body), start=1):
        overlap = 0.5 * DETECTABLE_FRACTION * previous
        tiles += [Tile(x, y, side, level) for y in _spread(h, side, overlap) for x in _spread(w, side, overlap)]
        previous = side
    return tiles


def order_tiles(tiles: list[Tile], focus: tuple[float, float]) -> list[Tile]:
    """``tiles`` in the order a sweep visits them: coarse level first, then the tile whose
    centre is nearest ``focus`` (pixels: the last followed body, else the frame centre)."""
    return sorted(tiles, key=lambda t: (t.level, math.hypot(t.centre[0] - focus[0], t.centre[1] - focus[1])))


def tile_around(roi: bp.Rect, image_size: tuple[int, int], min_side: int) -> Tile:
    """A square tile centred on ``roi`` (a lost body's last region), twice its side and at
    least ``min_side``, moved inside the frame (clamped to the frame's short side)."""
    w, h = image_size
    side = int(round(min(min(w, h), max(float(min_side), 2.0 * roi.width * w))))
    x0 = int(round(min(max(roi.x_center * w - side / 2.0, 0.0), w - side)))
    y0 = int(round(min(max(roi.y_center * h - side / 2.0, 0.0), h - side)))
    return Tile(x0, y0, side, 0)


def new_detections(extra: list[bp.Detection], found: list[bp.Detection],
                   threshold: float = bp.NMS_MIN_SUPPRESSION) -> list[bp.Detection]:
    """The detections of ``extra`` (a finer look) that overlap none of ``found`` (by IoU
    over MediaPipe's suppression threshold): what was found already stays as found."""
    return [d for d in extra if all(bp.iou(d.box, f.box) <= threshold for f in found)]


def body_region(det: bp.Detection, image_size: tuple[int, int]) -> bp.Rect:
    """The body region a detection gives (MediaPipe's PoseDetectionToRoi)."""
    kp = det.keypoints
    return bp.roi_from_points(kp[0], kp[1], image_size)


def priority(roi: bp.Rect, image_size: tuple[int, int]) -> float:
    """Acquisition rank of a body region: its side over the frame's short side, times
    ``1 − ½·d`` (``d`` = the centre's distance from the frame centre over half the diagonal)."""
    w, h = image_size
    side = roi.width * w
    d = math.hypot((roi.x_center - 0.5) * w, (roi.y_center - 0.5) * h) / (0.5 * math.hypot(w, h))
    return side / min(w, h) * (1.0 - 0.5 * min(d, 1.0))


def match_distance(roi: bp.Rect, last: bp.Rect, image_size: tuple[int, int], since_s: float = 0.0) -> float | None:
    """How far ``roi`` is from the last followed region ``last``, seen ``since_s`` seconds
    ago, in ``last``'s sides (centre to centre), or ``None`` when it does not continue it
    (further than :data:`MATCH_DISTANCE` + :data:`MATCH_SPEED` · ``since_s``, or a size
    outside a factor :data:`MATCH_SCALE`)."""
    w, h = image_size
    side_last, side = last.width * w, roi.width * w
    if not (side_last > 0 and side > 0) or not 1.0 / MATCH_SCALE <= side / side_last <= MATCH_SCALE:
        return None
    d = math.hypot((roi.x_center - last.x_center) * w, (roi.y_center - last.y_center) * h) / side_last
    return d if d <= MATCH_DISTANCE + MATCH_SPEED * max(0.0, since_s) else None


def rank(detections: list[bp.Detection], image_size: tuple[int, int], last: bp.Rect | None = None,
         since_s: float = 0.0) -> list[tuple[bp.Detection, bp.Rect]]:
    """The usable candidates (detection, region), best first: those continuing ``last``
    (seen ``since_s`` seconds ago; nearest first), then the rest by :func:`priority`."""
    out = []
    for det in detections:
        roi = body_region(det, image_size)
        if not roi.usable:
            continue
        m = match_distance(roi, last, image_size, since_s) if last is not None else None
        key = (0, m) if m is not None else (1, -priority(roi, image_size))
        out.append((key, det, roi))
    out.sort(key=lambda t: t[0])
    return [(det, roi) for _, det, roi in out]


__all__ = [
    "DETECTABLE_FRACTION", "MIN_BODY", "LEVEL_STEP", "MATCH_DISTANCE", "MATCH_SPEED", "MATCH_SCALE", "Tile", "level_sides",
    "tile_grid", "order_tiles", "tile_around", "new_detections", "body_region", "priority", "match_distance", "rank",
]
