"""The table's shape as a height map over the board plane (issue 28, "Scan the table").

A :class:`HeightMap` is a regular grid in the *board frame* (:mod:`ar.boards`: metres,
the board plane is ``z = 0`` and ``+z`` points *into* the table, so "up" is ``-z`` and a
point's height is ``-z``): cell ``(i, j)`` covers
``x0 + j*cell_m <= x < x0 + (j+1)*cell_m`` and ``y0 + i*cell_m <= y < y0 + (i+1)*cell_m``,
its centre is at ``(x0 + (j + 0.5)*cell_m, y0 + (i + 0.5)*cell_m)``. ``heights[i, j]`` is
the surface's height above the board plane there (float32 metres) and ``known[i, j]`` says
whether the scan saw it.

Method
    Rasterisation (:meth:`HeightMap.from_points`): triangulated points (board frame) are
    binned into cells; a cell's height is the **median** height ``-z`` of its points (robust to the
    odd mis-decoded Gray-code pixel, which lands far above or below the surface), and the
    cell is known when it holds at least ``min_points`` points. Unknown cells form holes
    (specular spots, decoding failures, the projector's and camera's shadows beside a box).
    A hole is filled only when it is **bounded** -- a connected component of unknown cells
    (4-neighbourhood) that touches no border of the grid -- and **small** (at most
    ``max_hole_cells`` cells); each of its cells takes the height of the nearest known
    cell (Euclidean distance transform), which keeps a box's edge sharp where averaging
    would ramp it. Larger or open holes stay unknown: a shadow is not guessed.

    Sampling (:meth:`HeightMap.height_at`): bilinear between the four cell centres around
    a point, over the known ones only (weights renormalised); a point with no known
    neighbour, or outside the grid, gets ``default`` (the board plane, 0) and is flagged
    unknown. :meth:`HeightMap.normal_at` is the surface normal from the central-difference
    slope of the same samples.

Files (:meth:`HeightMap.save` / :meth:`HeightMap.load`)
    One ``.npz`` (``numpy.savez_compressed``: ``heights`` float32, ``known`` bool,
    ``origin`` ``[x0, y0, cell_m]`` float64, ``version``), written through
    :func:`retrieval.durable.durable_write`, so a power cut leaves the old map or the new
    one. A 0.6 m x 0.45 m table at 2 mm is 300 x 225 cells, a few hundred kB. Loading
    never unpickles and checks every array's key, dtype, shape and values; a malformed
    file raises :class:`HeightMapError` naming it.
"""
from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ar.errors import CalibrationError
from retrieval.durable import durable_write

#: Default cell size: 2 mm, finer than a child's finger and than the scan's point spacing
#: at a typical 40 cm working distance (a camera pixel covers ~0.6 mm there).
DEFAULT_CELL_M = 0.002
#: A cell needs this many points to be known (a median of one point is not robust).
DEFAULT_MIN_POINTS = 3
#: Largest bounded hole that is filled: 25 cells, 1 cm^2 at 2 mm cells.
DEFAULT_MAX_HOLE_CELLS = 25
#: A grid larger than this (cells per side) is refused: 4096 cells of 2 mm is 8 m.
MAX_SIDE_CELLS = 4096
#: Largest height-map file read (a full 4096^2 grid compresses to far less).
MAX_FILE_BYTES = 64 * 1024 * 1024
FORMAT_VERSION = 1
#: The scanned table's file, beside ``camera.json`` and ``projector.json`` in the
#: calibration folder (the teacher's profile folder): written by the calibration wizard's
#: *Scan the table* step, read by the projector stage.
HEIGHT_MAP_FILE = "table.npz"


class HeightMapError(CalibrationError):
    """A height map cannot be built, or a height-map file is unusable (names the file)."""


def _grid_index(size_m: float, cell_m: float) -> int:
    return max(1, int(np.ceil(size_m / cell_m - 1e-9)))


@dataclass(frozen=True)
class HeightMap:
    """Heights (metres above the board plane) on a grid in the board frame; see the module."""

    x0: float
    y0: float
    cell_m: float
    heights: np.ndarray  # (H, W) float32, metres above the board plane
    known: np.ndarray  # (H, W) bool

    def __post_init__(self) -> None:
        heights = np.asarray(self.heights, np.float32)
        known = np.asarray(self.known, bool)
        if heights.ndim != 2 or heights.shape != known.shape or 0 in heights.shape:
            raise HeightMapError(f"heights {heights.shape} and known {known.shape} must be the same non-empty 2-D shape")
        if max(heights.shape) > MAX_SIDE_CELLS:
            raise HeightMapError(f"a {heights.shape[1]}x{heights.shape[0]} grid is larger than {MAX_SIDE_CELLS} cells a side")
        if not (np.isfinite(self.cell_m) and self.cell_m > 0 and np.isfinite(self.x0) and np.isfinite(self.y0)):
            raise HeightMapError(f"origin ({self.x0}, {self.y0}) and cell size {self.cell_m} must be finite, cell > 0")
        if not np.all(np.isfinite(heights[known])):
            raise HeightMapError("known heights must be finite")
        heights = np.where(known, heights, 0.0).astype(np.float32)  # unknown cells hold the board plane
        object.__setattr__(self, "heights", heights)
        object.__setattr__(self, "known", known)
        object.__setattr__(self, "x0", float(self.x0))
        object.__setattr__(self, "y0", float(self.y0))
        object.__setattr__(self, "cell_m", float(self.cell_m))

    # ------------------------------------------------------------------ shape
    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)``: rows along board y, columns along board x."""
        return self.heights.shape  # type: ignore[return-value]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the grid, metres in the board frame."""
        h, w = self.shape
        return (self.x0, self.x0 + w * self.cell_m, self.y0, self.y0 + h * self.cell_m)

    @property
    def known_fraction(self) -> float:
        return float(self.known.mean())

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Board-frame ``(x, y)`` of the cell centres, each ``(H, W)``."""
        h, w = self.shape
        xs = self.x0 + (np.arange(w) + 0.5) * self.cell_m
        ys = self.y0 + (np.arange(h) + 0.5) * self.cell_m
        return np.meshgrid(xs, ys)

    # ------------------------------------------------------------------ building
    @classmethod
    def flat(cls, extent: tuple[float, float, float, float] = (-0.1, 0.5, -0.1, 0.4), cell_m: float = DEFAULT_CELL_M,
             height: float = 0.0) -> "HeightMap":
        """A fully known level surface ``height`` metres above the board over ``extent``
        ``(x_min, x_max, y_min, y_max)``: the table without a scan, and tests' baseline."""
        x_min, x_max, y_min, y_max = (float(v) for v in extent)
        if not (x_max > x_min and y_max > y_min):
            raise HeightMapError(f"extent {extent} must have x_max > x_min and y_max > y_min")
        w, h = _grid_index(x_max - x_min, cell_m), _grid_index(y_max - y_min, cell_m)
        return cls(x_min, y_min, cell_m, np.full((h, w), height, np.float32), np.ones((h, w), bool))

    @classmethod
    def from_points(cls, points_board: np.ndarray, cell_m: float = DEFAULT_CELL_M,
                    extent: tuple[float, float, float, float] | None = None, min_points: int = DEFAULT_MIN_POINTS,
                    max_hole_cells: int = DEFAULT_MAX_HOLE_CELLS) -> "HeightMap":
        """Rasterise ``points_board`` ((N, 3) metres, board frame: a point's height above
        the board is ``-z``) into a height map.

        ``extent`` ``(x_min, x_max, y_min, y_max)`` fixes the grid (points outside are
        dropped); by default it is the points' bounding box. Per cell the median height of
        at least ``min_points`` points; bounded holes of at most ``max_hole_cells`` cells
        filled from the nearest known cell (see the module docstring)."""
        pts = np.asarray(points_board, np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise HeightMapError(f"points must be an (N, 3) array, got shape {pts.shape}")
        if not (np.isfinite(cell_m) and cell_m > 0):
            raise HeightMapError(f"cell size must be a positive number of metres, got {cell_m}")
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if extent is None:
            if len(pts) == 0:
                raise HeightMapError("no finite points to build a height map from")
            lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
            extent = (lo[0], max(hi[0], lo[0] + cell_m), lo[1], max(hi[1], lo[1] + cell_m))
        x_min, x_max, y_min, y_max = (float(v) for v in extent)
        if not (x_max > x_min and y_max > y_min):
            raise HeightMapError(f"extent {extent} must have x_max > x_min and y_max > y_min")
        w, h = _grid_index(x_max - x_min, cell_m), _grid_index(y_max - y_min, cell_m)
        if max(w, h) > MAX_SIDE_CELLS:
            raise HeightMapError(f"a {w}x{h} grid of {cell_m * 1000:g} mm cells is larger than {MAX_SIDE_CELLS} a side")
        col = np.floor((pts[:, 0] - x_min) / cell_m).astype(np.int64)
        row = np.floor((pts[:, 1] - y_min) / cell_m).astype(np.int64)
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        cell = row[inside] * w + col[inside]
        z = -pts[inside, 2]  # height: board +z points into the table
        heights = np.zeros(h * w, np.float32)
        counts = np.bincount(cell, minlength=h * w)
        if len(cell):
            order = np.lexsort((z, cell))  # by cell, then by height within a cell
            z_sorted = z[order]
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            occupied = np.flatnonzero(counts)
            lo_i = starts[occupied] + (counts[occupied] - 1) // 2
            hi_i = starts[occupied] + counts[occupied] // 2
            heights[occupied] = 0.5 * (z_sorted[lo_i] + z_sorted[hi_i])
        known = (counts >= max(1, int(min_points))).reshape(h, w)
        heights = heights.reshape(h, w)
        heights, known = fill_bounded_holes(heights, known, max_hole_cells)
        return cls(x_min, y_min, cell_m, heights, known)

    # ------------------------------------------------------------------ sampling
    def _corners(self, x: np.ndarray, y: np.ndarray):
        h, w = self.shape
        u = (x - self.x0) / self.cell_m - 0.5  # continuous column of the cell centres
        v = (y - self.y0) / self.cell_m - 0.5
        j0, i0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
        fu, fv = u - j0, v - i0
        inside = (x >= self.x0) & (x < self.x0 + w * self.cell_m) & (y >= self.y0) & (y < self.y0 + h * self.cell_m)
        corners = []
        for di, dj, wt in ((0, 0, (1 - fu) * (1 - fv)), (0, 1, fu * (1 - fv)), (1, 0, (1 - fu) * fv), (1, 1, fu * fv)):
            ii = np.clip(i0 + di, 0, h - 1)
            jj = np.clip(j0 + dj, 0, w - 1)
            corners.append((ii, jj, wt))
        return corners, inside

    def height_at(self, x, y, default: float = 0.0, return_known: bool = False):
        """Height (metres above the board) at board-frame ``(x, y)`` (scalars or arrays):
        bilinear over the known cell centres around each point; ``default`` where none is
        known or the point is off the grid. With ``return_known`` also a bool array saying
        where the height came from the scan."""
        x = np.asarray(x, np.float64)
        y = np.asarray(y, np.float64)
        x, y = np.broadcast_arrays(x, y)
        corners, inside = self._corners(x, y)
        num = np.zeros(x.shape)
        den = np.zeros(x.shape)
        for ii, jj, wt in corners:
            k = self.known[ii, jj]
            num += np.where(k, wt * self.heights[ii, jj], 0.0)
            den += np.where(k, wt, 0.0)
        ok = inside & (den > 1e-9)
        out = np.where(ok, num / np.where(den > 1e-9, den, 1.0), default)
        if out.ndim == 0:
            out, ok = float(out), bool(ok)
        return (out, ok) if return_known else out

    def normal_at(self, x, y) -> np.ndarray:
        """Unit surface normal(s) ``(..., 3)`` in the board frame at ``(x, y)``, from the
        central-difference slope of :meth:`height_at` over one cell."""
        x = np.asarray(x, np.float64)
        y = np.asarray(y, np.float64)
        d = self.cell_m
        dzdx = (self.height_at(x + d, y) - self.height_at(x - d, y)) / (2 * d)
        dzdy = (self.height_at(x, y + d) - self.height_at(x, y - d)) / (2 * d)
        n = np.stack(np.broadcast_arrays(-np.asarray(dzdx), -np.asarray(dzdy), np.ones(np.shape(dzdx))), axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    # ------------------------------------------------------------------ files
    def to_bytes(self) -> bytes:
        """The map as compressed ``.npz`` bytes (the file format of :meth:`save`)."""
        buf = io.BytesIO()
        np.savez_compressed(buf, heights=self.heights.astype(np.float32), known=self.known.astype(bool),
                            origin=np.array([self.x0, self.y0, self.cell_m], np.float64),
                            version=np.array(FORMAT_VERSION, np.int64))
        return buf.getvalue()

    def save(self, path: str | Path) -> Path:
        """Write the map durably (atomic replace, fsynced); returns the path."""
        return durable_write(path, self.to_bytes())

    @classmethod
    def from_bytes(cls, data: bytes, path: str | Path | None = None) -> "HeightMap":
        """Parse :meth:`to_bytes` output; anything malformed raises :class:`HeightMapError`
        naming ``path``."""
        where = str(path) if path is not None else None
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as npz:
                missing = {"heights", "known", "origin", "version"} - set(npz.files)
                if missing:
                    raise HeightMapError(f"not a height map: missing {', '.join(sorted(missing))}", where)
                arrays = {key: npz[key] for key in ("heights", "known", "origin", "version")}
        except HeightMapError:
            raise
        except (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError) as exc:
            raise HeightMapError(f"not a height map file ({type(exc).__name__}: {exc})", where) from None
        version = arrays["version"]
        if version.shape != () or version.dtype.kind not in "iu" or int(version) != FORMAT_VERSION:
            raise HeightMapError(f"unsupported height map version {version!r} (this StoryBeam reads {FORMAT_VERSION})",
                                 where)
        heights, known, origin = arrays["heights"], arrays["known"], arrays["origin"]
        if heights.dtype.kind != "f" or known.dtype != np.bool_ or origin.dtype.kind != "f" or origin.shape != (3,):
            raise HeightMapError(f"wrong array types: heights {heights.dtype}, known {known.dtype}, "
                                 f"origin {origin.dtype}{list(origin.shape)}", where)
        try:
            return cls(float(origin[0]), float(origin[1]), float(origin[2]), heights, known)
        except HeightMapError as exc:
            raise HeightMapError(exc.problem, where) from None

    @classmethod
    def load(cls, path: str | Path) -> "HeightMap":
        """Read a map written by :meth:`save`; a missing, oversized or malformed file
        raises :class:`HeightMapError` naming it."""
        path = Path(path)
        try:
            size = path.stat().st_size
            if size > MAX_FILE_BYTES:
                raise HeightMapError(f"file is {size / 2**20:.1f} MB, more than the {MAX_FILE_BYTES // 2**20} MB "
                                     "a height map can be", path)
            data = path.read_bytes()
        except FileNotFoundError:
            raise HeightMapError("file not found", path) from None
        except IsADirectoryError:
            raise HeightMapError("is a folder, not a height map file", path) from None
        except OSError as exc:
            raise HeightMapError(f"cannot read: {exc}", path) from None
        return cls.from_bytes(data, path)


def fill_bounded_holes(heights: np.ndarray, known: np.ndarray,
                       max_hole_cells: int = DEFAULT_MAX_HOLE_CELLS) -> tuple[np.ndarray, np.ndarray]:
    """Fill the unknown components (4-neighbourhood) that touch no grid border and have at
    most ``max_hole_cells`` cells, each cell from its nearest known cell; returns new
    ``(heights, known)``. Nothing is filled when nothing is known."""
    heights = np.asarray(heights, np.float32).copy()
    known = np.asarray(known, bool).copy()
    if max_hole_cells <= 0 or known.all() or not known.any():
        return heights, known
    from scipy import ndimage  # deferred: scipy.ndimage costs ~200 ms to import (-X importtime), needed only for scans

    labels, n = ndimage.label(~known)  # default structure: 4-neighbourhood
    if n == 0:
        return heights, known
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    fill = (sizes <= max_hole_cells)
    fill[0] = False
    fill[border] = False
    to_fill = fill[labels]
    if not to_fill.any():
        return heights, known
    _, (ii, jj) = ndimage.distance_transform_edt(~known, return_indices=True)
    heights[to_fill] = heights[ii[to_fill], jj[to_fill]]
    known[to_fill] = True
    return heights, known


__all__ = ["HEIGHT_MAP_FILE", "DEFAULT_CELL_M", "DEFAULT_MAX_HOLE_CELLS", "DEFAULT_MIN_POINTS", "HeightMap", "HeightMapError",
           "fill_bounded_holes"]
