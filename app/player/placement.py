"""Where the story's table lies in the 3-D scene: the one table -> scene mapping.

The story is drawn in *table metres* (:mod:`app.story.model`: origin at the table's
front-left corner, x to the child's right, y away from the child, the table
``TABLE_WIDTH_M`` x ``TABLE_DEPTH_M``). Everything 3-D is authored in the *scene frame*
of :mod:`ar.render.projector_view`: Y up, metres, origin at the board centre on the
table, +X = board +x, +Z = board +y. A :class:`TablePlacement` says how one is laid in
the other -- centre the table on the scene origin, turn it, scale it -- and
:func:`table_to_scene` / :func:`scene_to_table` apply it. Two placements are used:

* :data:`PREVIEW_PLACEMENT` (the Play preview): the full-size table seen from the
  child's side (scene -Z, looking across the table): table +x is scene -X (to the
  viewer's right, as on the tablet's top-down view), table +y is scene +Z (away).
* :data:`STAGE_PLACEMENT` (the projector stage and its video): the table as a miniature
  on the marker board, scaled by :data:`STAGE_SCALE` and centred on the board: table +x
  runs along board -y (scene -Z, image right for the rig's camera), table +y along
  board -x (scene -X, away from the camera), so the child's edge of the table is the
  one nearest the rig.

Needs numpy only (no renderer), so the mapping can be tested and reused anywhere.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.story import TABLE_DEPTH_M, TABLE_WIDTH_M

#: table metres -> metres on the board (the story plays as a miniature on the board)
STAGE_SCALE = 0.28


@dataclass(frozen=True)
class TablePlacement:
    """The table laid in the scene: ``scene (X, Z) = scale * axes @ (table (x, y) - centre)``.

    ``axes`` rows are scene X and scene Z written in table (x, y); each must be a signed
    unit axis (a rotation or reflection), so the mapping is exactly invertible."""

    name: str
    scale: float
    axes: tuple[tuple[float, float], tuple[float, float]]

    @property
    def matrix(self) -> np.ndarray:
        """The 2x2 linear part (``scale * axes``)."""
        return self.scale * np.asarray(self.axes, np.float64)


TABLE_CENTRE_M = np.array([TABLE_WIDTH_M / 2, TABLE_DEPTH_M / 2])

PREVIEW_PLACEMENT = TablePlacement("preview", 1.0, ((-1.0, 0.0), (0.0, 1.0)))
STAGE_PLACEMENT = TablePlacement("stage", STAGE_SCALE, ((0.0, -1.0), (-1.0, 0.0)))


def table_to_scene(points: np.ndarray, placement: TablePlacement) -> np.ndarray:
    """``(N, >=2)`` table points (metres; a third column, time, is ignored) -> ``(N, 2)``
    scene ``(X, Z)`` under ``placement``."""
    p = np.asarray(points, np.float64)[:, :2] - TABLE_CENTRE_M
    return p @ placement.matrix.T


def scene_to_table(points_xz: np.ndarray, placement: TablePlacement) -> np.ndarray:
    """The inverse of :func:`table_to_scene`: ``(N, 2)`` scene ``(X, Z)`` -> table ``(x, y)``."""
    return np.asarray(points_xz, np.float64) @ np.linalg.inv(placement.matrix).T + TABLE_CENTRE_M


__all__ = ["STAGE_SCALE", "TABLE_CENTRE_M", "TablePlacement", "PREVIEW_PLACEMENT", "STAGE_PLACEMENT",
           "table_to_scene", "scene_to_table"]
