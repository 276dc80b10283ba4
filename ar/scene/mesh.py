"""Triangle meshes as plain numpy arrays, and the closed primitives characters are made of.

A :class:`MeshData` is what every renderer uploads once and then only moves: float32
vertex positions, float32 unit vertex normals and uint32 triangle indices (counter-
clockwise seen from outside). No trimesh, no GL: it runs on the tablet and feeds both the
Kivy GL renderer (:mod:`app.ui.gl`) and pyrender (:mod:`ar.render`).

Primitives and their normals (all exact, not estimated from the triangles):

* :func:`ellipsoid` -- a subdivided icosahedron (``subdivisions`` = 2: 320 triangles,
  3: 1280) scaled by the radii. A point ``p`` of the unit sphere maps to ``D p`` with
  ``D = diag(radii)``; the surface normal there is ``D^-1 p`` normalised (the inverse
  transpose of ``D`` applied to the sphere's normal ``p``).
* :func:`capsule` -- two hemispheres of ``count`` latitude rings each joined by a
  cylinder, around the axis from ``a`` to ``b``; a vertex at unit direction ``u`` from
  its hemisphere's centre has normal ``u`` (on the cylinder ``u`` is radial).
* :func:`box`, :func:`ribbon` -- flat faces with their face normals (vertices are not
  shared between faces, so the normals are exact).

:attr:`MeshData.is_watertight` checks that every edge is shared by exactly two
triangles that traverse it in opposite directions (a closed, consistently oriented
surface): the primitives above are closed except :func:`ribbon`, which is a flat strip.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

_ids = itertools.count(1)


@dataclass(frozen=True, eq=False)
class MeshData:
    """A triangle mesh: ``vertices`` (V, 3) float32 metres, ``normals`` (V, 3) float32 unit
    vectors, ``faces`` (F, 3) uint32 indices. ``uid`` names it for renderer caches (a
    renderer uploads a mesh once per uid, then only changes its pose)."""

    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    uid: int = field(default_factory=lambda: next(_ids))

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertices", np.ascontiguousarray(self.vertices, np.float32))
        object.__setattr__(self, "normals", np.ascontiguousarray(self.normals, np.float32))
        object.__setattr__(self, "faces", np.ascontiguousarray(self.faces, np.uint32))
        if self.vertices.shape != self.normals.shape or self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            raise ValueError(f"mesh: vertices {self.vertices.shape} and normals {self.normals.shape} must be (V, 3)")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise ValueError(f"mesh: faces {self.faces.shape} must be (F, 3)")
        if len(self.faces) and int(self.faces.max()) >= len(self.vertices):
            raise ValueError("mesh: a face indexes a vertex that does not exist")

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3): the lowest and highest corner of the axis-aligned bounding box."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)]).astype(np.float64)

    @property
    def extents(self) -> np.ndarray:
        """(3,): the bounding box's size."""
        lo, hi = self.bounds
        return hi - lo

    @property
    def is_watertight(self) -> bool:
        """Closed and consistently oriented: each directed edge appears once, and its
        reverse appears once too."""
        f = self.faces.astype(np.int64)
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        n = len(self.vertices)
        code = edges[:, 0] * n + edges[:, 1]
        if len(np.unique(code)) != len(code):
            return False
        return bool(np.all(np.isin(edges[:, 1] * n + edges[:, 0], code)))

    def transformed(self, T: np.ndarray) -> "MeshData":
        """A new mesh moved by the rigid 4x4 transform ``T`` (normals rotated)."""
        T = np.asarray(T, np.float64)
        v = self.vertices @ T[:3, :3].T + T[:3, 3]
        return MeshData(v, self.normals @ T[:3, :3].T, self.faces)


def concatenate(meshes: list[MeshData]) -> MeshData:
    """One mesh holding all of ``meshes`` (indices shifted)."""
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return MeshData(np.concatenate([m.vertices for m in meshes]), np.concatenate([m.normals for m in meshes]),
                    np.concatenate([m.faces.astype(np.int64) + o for m, o in zip(meshes, offsets)]))


# ------------------------------------------------------------------------- primitives
def _icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit sphere: vertices (on the sphere) and outward-wound faces."""
    t = (1.0 + 5.0 ** 0.5) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        cache: dict[tuple[int, int], int] = {}

        def mid(i: int, j: int) -> int:
            key = (min(i, j), max(i, j))
            if key not in cache:
                m = verts[i] + verts[j]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return np.array(verts), np.array(faces)


_SPHERES: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def ellipsoid(centre, radii, subdivisions: int = 2) -> MeshData:
    """An ellipsoid with semi-axes ``radii`` (x, y, z) around ``centre``."""
    if subdivisions not in _SPHERES:
        _SPHERES[subdivisions] = _icosphere(subdivisions)
    unit, faces = _SPHERES[subdivisions]
    r = np.asarray(radii, np.float64)
    normals = unit / r
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return MeshData(unit * r + np.asarray(centre, np.float64), normals, faces)


def sphere(centre, radius: float, subdivisions: int = 2) -> MeshData:
    """A sphere of ``radius`` around ``centre``."""
    return ellipsoid(centre, (radius, radius, radius), subdivisions)


def _frame_for(d: np.ndarray) -> np.ndarray:
    """A rotation whose third column is the unit vector ``d``."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, d)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(d, x), d], axis=1)


def capsule(a, b, radius: float, count: int = 12) -> MeshData:
    """A capsule of ``radius`` whose axis runs from point ``a`` to point ``b``.

    ``count`` segments around the axis and ``count // 2`` latitude steps per hemisphere
    (a single vertex at each pole)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    axis = b - a
    length = float(np.linalg.norm(axis))
    d = axis / length if length > 1e-9 else np.array([0.0, 0.0, 1.0])
    R = _frame_for(d)
    n_lat = max(2, count // 2)
    theta = np.arange(count) * 2 * np.pi / count
    rings_u, rings_c = [], []  # unit directions (local frame, z = axis) and their centres
    for k in range(1, n_lat + 1):  # lower hemisphere: from near the bottom pole up to the equator
        phi = -np.pi / 2 + k * (np.pi / 2) / n_lat
        rings_u.append(np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta),
                                 np.full(count, np.sin(phi))], axis=1))
        rings_c.append(0.0)
    for k in range(0, n_lat):  # upper hemisphere: from the equator up to near the top pole
        phi = k * (np.pi / 2) / n_lat
        rings_u.append(np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta),
                                 np.full(count, np.sin(phi))], axis=1))
        rings_c.append(length)
    u = np.concatenate([[[0.0, 0.0, -1.0]], *rings_u, [[0.0, 0.0, 1.0]]])
    c = np.concatenate([[0.0], *[np.full(count, z) for z in rings_c], [length]])
    local = u * radius
    local[:, 2] += c
    n_rings = len(rings_u)
    top = 1 + n_rings * count
    faces = []
    for j in range(count):  # bottom cap fan (outward = -axis)
        faces.append((0, 1 + (j + 1) % count, 1 + j))
    for r in range(n_rings - 1):
        s0, s1 = 1 + r * count, 1 + (r + 1) * count
        for j in range(count):
            j1 = (j + 1) % count
            faces += [(s0 + j, s0 + j1, s1 + j), (s0 + j1, s1 + j1, s1 + j)]
    last = 1 + (n_rings - 1) * count
    for j in range(count):
        faces.append((last + j, last + (j + 1) % count, top))
    verts = local @ R.T + a
    return MeshData(verts, u @ R.T, np.array(faces))


def box(extents, centre=(0.0, 0.0, 0.0)) -> MeshData:
    """An axis-aligned box of size ``extents`` around ``centre`` (4 vertices per face)."""
    e = np.asarray(extents, np.float64) / 2
    verts, normals, faces = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u_ax, v_ax = [k for k in range(3) if k != axis]
            corners = []
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = np.zeros(3)
                p[axis], p[u_ax], p[v_ax] = sign * e[axis], su * e[u_ax], sv * e[v_ax]
                corners.append(p)
            base = len(verts)
            verts += corners
            normals += [n] * 4
            quad = [(base, base + 1, base + 2), (base, base + 2, base + 3)]
            # orient each triangle outward
            for tri in quad:
                p0, p1, p2 = (verts[i] for i in tri)
                faces.append(tri if np.dot(np.cross(p1 - p0, p2 - p0), n) > 0 else (tri[0], tri[2], tri[1]))
    # corners are not shared between faces (exact face normals), so is_watertight is False: closed by position only
    return MeshData(np.array(verts) + np.asarray(centre, np.float64), np.array(normals), np.array(faces))


def ribbon(points_xz: np.ndarray, width: float = 0.006, lift: float = 0.0005) -> MeshData:
    """A flat strip on the table (normal +Y) of ``width`` along the (N, 2) scene-frame
    x-z polyline ``points_xz``, ``lift`` above the table top."""
    p = np.asarray(points_xz, np.float64)
    d = np.gradient(p, axis=0)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    n = np.stack([-d[:, 1], d[:, 0]], axis=1) * width / 2
    verts = np.zeros((2 * len(p), 3))
    verts[0::2, [0, 2]] = p + n
    verts[1::2, [0, 2]] = p - n
    verts[:, 1] = lift
    faces = []
    for i in range(len(p) - 1):
        a, b, c, e = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
        for tri in ((a, c, b), (b, c, e)):
            p0, p1, p2 = verts[list(tri)]
            faces.append(tri if np.cross(p1 - p0, p2 - p0)[1] >= 0 else (tri[0], tri[2], tri[1]))
    normals = np.tile([0.0, 1.0, 0.0], (len(verts), 1))
    return MeshData(verts, normals, np.array(faces).reshape(-1, 3))


__all__ = ["MeshData", "concatenate", "ellipsoid", "sphere", "capsule", "box", "ribbon"]
