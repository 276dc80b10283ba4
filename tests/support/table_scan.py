"""A scanned table with boxes of known size, for the height-map and surface tests.

:func:`scan_points` stands in for a structured-light scan's triangulated points (board
frame, ``+z`` into the table): a jittered grid of surface samples at about a camera
pixel's footprint, Gaussian depth noise and a share of wild outliers (mis-decoded pixels).
The boxes are ``(x0, x1, y0, y1, height)`` in board metres.
"""
from __future__ import annotations

import numpy as np

Box = tuple[float, float, float, float, float]


def box_height(boxes: list[Box], x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """True height of the surface at board ``(x, y)``: the tallest box there, else 0."""
    z = np.zeros(np.broadcast(x, y).shape)
    for x0, x1, y0, y1, h in boxes:
        z = np.where((x >= x0) & (x < x1) & (y >= y0) & (y < y1), np.maximum(z, h), z)
    return z


def scan_points(boxes: list[Box], extent: tuple[float, float, float, float], step: float = 0.0007,
                noise: float = 0.0003, outliers: float = 0.01, seed: int = 28) -> np.ndarray:
    """(N, 3) board-frame points of the table and ``boxes`` over ``extent``
    ``(x_min, x_max, y_min, y_max)``, as a scan sees them (see the module docstring)."""
    rng = np.random.default_rng(seed)
    xs = np.arange(extent[0] + step / 2, extent[1], step)
    ys = np.arange(extent[2] + step / 2, extent[3], step)
    gx, gy = np.meshgrid(xs, ys)
    x = gx.ravel() + rng.uniform(-step / 3, step / 3, gx.size)
    y = gy.ravel() + rng.uniform(-step / 3, step / 3, gx.size)
    z = box_height(boxes, x, y) + rng.normal(0, noise, x.size)
    wild = rng.random(z.size) < outliers
    z[wild] += rng.uniform(-0.05, 0.05, wild.sum())
    return np.column_stack([x, y, -z])  # board frame: +z points into the table
