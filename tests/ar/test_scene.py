"""The renderer-agnostic scene: numpy meshes, characters without trimesh, views."""
from __future__ import annotations

import numpy as np
import pytest

from ar import look_at, project_points
from ar.scene.characters import CHARACTER_NAMES, build_character, rest_motion
from ar.scene.content import add_character, add_mesh, table_mesh
from ar.scene.description import Lighting, SceneDescription, View, overhead_view
from ar.scene.mesh import MeshData, box, capsule, concatenate, ellipsoid, ribbon, sphere


def _volume(m: MeshData) -> float:
    """Signed volume by the divergence theorem (positive for outward-wound closed meshes)."""
    v = m.vertices.astype(np.float64)[m.faces]
    return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)


def _face_normals(m: MeshData) -> np.ndarray:
    v = m.vertices.astype(np.float64)[m.faces]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


@pytest.mark.parametrize("mesh, volume", [
    (sphere((0.1, 0.2, 0.3), 0.05, 3), 4 / 3 * np.pi * 0.05 ** 3),
    (ellipsoid((0, 0, 0), (0.03, 0.05, 0.02), 3), 4 / 3 * np.pi * 0.03 * 0.05 * 0.02),
    (capsule((0, 0, 0), (0.02, 0.08, -0.01), 0.01, 24), np.pi * 0.01 ** 2 * (4 / 3 * 0.01 + np.linalg.norm([0.02, 0.08, 0.01]))),
])
def test_primitives_are_closed_outward_and_have_the_right_volume(mesh, volume):
    assert mesh.is_watertight
    assert _volume(mesh) == pytest.approx(volume, rel=0.03)  # polygonal: a little under the true volume
    assert _volume(mesh) < volume
    # vertex normals are unit and agree with the faces they belong to (outward)
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-5)
    fn = _face_normals(mesh)
    vn = mesh.normals[mesh.faces].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, vn) > 0.8)


def test_primitives_match_trimesh_references():
    trimesh = pytest.importorskip("trimesh")
    ref = trimesh.creation.capsule(height=0.06, radius=0.01, count=[12, 12])
    ours = capsule((0, 0, -0.03), (0, 0, 0.03), 0.01, 12)
    assert _volume(ours) == pytest.approx(ref.volume, rel=0.02)
    ref_s = trimesh.creation.icosphere(subdivisions=2, radius=0.04)
    ours_s = sphere((0, 0, 0), 0.04, 2)
    assert len(ours_s.faces) == len(ref_s.faces)
    assert _volume(ours_s) == pytest.approx(ref_s.volume, rel=1e-6)


def test_watertight_check_can_fail_and_meshes_validate():
    s = sphere((0, 0, 0), 1.0, 1)
    assert not MeshData(s.vertices, s.normals, s.faces[1:]).is_watertight  # a hole
    assert not ribbon(np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.05]])).is_watertight  # a flat strip
    with pytest.raises(ValueError):
        MeshData(s.vertices, s.normals, s.faces + len(s.vertices))
    b = box((0.2, 0.1, 0.4), (1.0, 2.0, 3.0))
    assert np.allclose(b.bounds, [[0.9, 1.95, 2.8], [1.1, 2.05, 3.2]])
    assert _volume(b) == pytest.approx(0.2 * 0.1 * 0.4)
    both = concatenate([s, b])
    assert len(both.vertices) == len(s.vertices) + len(b.vertices) and both.faces.max() == len(both.vertices) - 1


@pytest.mark.parametrize("name", CHARACTER_NAMES)
def test_characters_are_numpy_and_stand_on_the_table(name):
    ch = build_character(name)
    assert all(isinstance(p.mesh, MeshData) and p.mesh.is_watertight for p in ch.parts)
    lo, hi = ch.posed_mesh().bounds
    assert lo[1] == pytest.approx(0.0, abs=0.002) and 0.115 <= hi[1] <= 0.14
    desc = SceneDescription(overhead_view())
    add_character(desc, ch, ch.all_part_poses(rest_motion(ch))[0])
    assert len(desc.items) == len(ch.parts) and {i.mesh.uid for i in desc.items} == {p.mesh.uid for p in ch.parts}


def test_view_projection_matches_opencv_and_pyrender():
    K = np.array([[700.0, 0, 319.5], [0, 690.0, 241.0], [0, 0, 1]])
    T = look_at(np.array([0.1, 0.4, -0.3]), np.zeros(3), np.array([0.0, 1.0, 0.0]))
    view = View(640, 480, K, T)
    pts = np.random.default_rng(0).uniform(-0.05, 0.05, (20, 3))
    ref = project_points(pts, T, K, np.zeros(5))
    assert np.allclose(view.project(pts), ref, atol=1e-9)
    # the GL matrices put the point at the same pixel: NDC -> window with rows from the top
    h = np.c_[pts, np.ones(len(pts))] @ (view.gl_projection() @ view.gl_view()).T
    ndc = h[:, :3] / h[:, 3:]
    px = np.c_[(ndc[:, 0] + 1) / 2 * 640 - 0.5, (1 - ndc[:, 1]) / 2 * 480 - 0.5]
    assert np.allclose(px, ref, atol=1e-6)
    assert np.all(np.abs(ndc[:, 2]) < 1)
    pyrender = pytest.importorskip("pyrender")
    cam = pyrender.IntrinsicsCamera(700.0, 690.0, 320.0, 241.5, znear=view.znear, zfar=view.zfar)
    assert np.allclose(cam.get_projection_matrix(640, 480), view.gl_projection())
    assert np.allclose(view.eye, [0.1, 0.4, -0.3]) and view.forward @ (-view.eye) > 0
    half = view.scaled(320, 240)
    assert np.allclose((half.project(pts) + 0.5) * 2, view.project(pts) + 0.5)  # pixel-edge coordinates scale


def test_static_content_and_lighting():
    desc = SceneDescription(overhead_view(), lighting=Lighting(0.45, 3.5))
    add_mesh(desc, table_mesh(1.2, 0.8), (150, 150, 160))
    (item,) = desc.items
    assert item.colour == (150, 150, 160) and np.allclose(item.pose, np.eye(4))
    assert item.mesh.bounds[1, 1] == pytest.approx(-0.0001, abs=1e-6)  # the top just under y = 0
