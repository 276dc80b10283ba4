"""The Gray-code sequence a projector shows for calibration and scanning.

Method: OpenCV-contrib's ``cv2.structured_light.GrayCodePattern`` for a projector of
``width x height`` pixels, step 1 (one code per projector column and row). Its
``generate()`` gives ``2 * (ceil(log2 width) + ceil(log2 height))`` images: for each bit of
the column code, most significant first, the pattern then its inverse; then the same for
the row code. We append a full-white and a full-black image (for the shadow masks and for
finding the board under full light), so a pose's captures are ``generate()`` order, white,
black -- the order :mod:`ar.structured_light.decode` expects and the file names must sort in.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ar.errors import CalibrationError


@dataclass(frozen=True)
class GrayCodeLayout:
    """How many images a projector size needs, and where each kind sits in the sequence."""

    width: int
    height: int

    @property
    def col_bits(self) -> int:
        return int(math.ceil(math.log2(self.width)))

    @property
    def row_bits(self) -> int:
        return int(math.ceil(math.log2(self.height)))

    @property
    def n_patterns(self) -> int:
        """Images ``generate()`` returns (pattern + inverse per bit)."""
        return 2 * (self.col_bits + self.row_bits)

    @property
    def n_images(self) -> int:
        """Images per pose: the patterns, then white, then black."""
        return self.n_patterns + 2

    @property
    def white_index(self) -> int:
        return self.n_patterns

    @property
    def black_index(self) -> int:
        return self.n_patterns + 1


def parse_projector_size(text: str) -> tuple[int, int]:
    """``"1024x768"`` -> ``(1024, 768)``; raises :class:`CalibrationError` on anything else."""
    try:
        w_s, h_s = text.lower().split("x")
        w, h = int(w_s), int(h_s)
    except ValueError:
        raise CalibrationError(f"projector size {text!r} must look like 1024x768") from None
    if not (2 <= w <= 16384 and 2 <= h <= 16384):
        raise CalibrationError(f"projector size {w}x{h} is out of range (2..16384 per side)")
    return w, h


def graycode_sequence(projector_size: tuple[int, int]) -> list[np.ndarray]:
    """The grey uint8 images (projector resolution) to show, in capture order: OpenCV's
    ``GrayCodePattern.generate()`` patterns, then white, then black."""
    w, h = (int(v) for v in projector_size)
    pattern = cv2.structured_light.GrayCodePattern.create(w, h)
    ok, images = pattern.generate()
    if not ok:  # pragma: no cover - OpenCV only fails for sizes parse_projector_size refuses
        raise CalibrationError(f"OpenCV could not generate Gray-code patterns for {w}x{h}")
    layout = GrayCodeLayout(w, h)
    assert len(images) == layout.n_patterns, (len(images), layout)
    return [np.asarray(im, np.uint8) for im in images] + [np.full((h, w), 255, np.uint8), np.zeros((h, w), np.uint8)]
