"""Projector-view rendering (pyrender, headless EGL) and the closed-loop landing check."""
from __future__ import annotations

import os
import threading

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from ar.boards import DEFAULT_BOARD_SPEC, Board  # noqa: E402
from ar.closed_loop import LandingCheck  # noqa: E402
from ar.geometry import look_at  # noqa: E402
from ar.pose import estimate_board_pose  # noqa: E402
from ar.render.projector_view import (ProjectorRenderer, add_test_scene, board_from_scene, board_to_scene_points,  # noqa: E402
                               opencv_to_pyrender_pose, pyrender_to_opencv_pose, scene_to_board_points)
from ar.synthetic import SyntheticCamera, TrajectoryConfig, handheld_trajectory  # noqa: E402


@pytest.fixture(scope="module")
def rig():
    return SyntheticCamera(Board(DEFAULT_BOARD_SPEC))


@pytest.fixture(scope="module")
def renderer(rig):
    P = rig.projector
    r = ProjectorRenderer(P.width, P.height, P.K)
    yield r
    r.close()


def test_scene_frame_is_y_up_at_board_centre():
    board = Board(DEFAULT_BOARD_SPEC)
    T = board_from_scene(board)
    assert np.allclose(T[:3, 3], board.centre)
    assert np.allclose(T[:3, :3] @ [0, 1, 0], [0, 0, -1])  # scene up = off the table = board -z
    assert np.isclose(np.linalg.det(T[:3, :3]), 1.0)
    pts = np.random.default_rng(0).normal(size=(5, 3))
    assert np.allclose(board_to_scene_points(scene_to_board_points(pts, board), board), pts)


def test_pose_conversion_round_trip():
    T = look_at(np.array([0.3, -0.2, -0.5]), np.zeros(3), np.array([0, -1.0, 0]))
    node = opencv_to_pyrender_pose(T)
    assert np.allclose(pyrender_to_opencv_pose(node), T)
    # the GL camera looks down its -z: that axis must point from the eye to the target
    view_dir = -node[:3, 2]
    assert np.allclose(view_dir, -node[:3, 3] / np.linalg.norm(node[:3, 3]))


def test_render_not_blank_and_background_black(rig, renderer):
    add_test_scene(renderer, rig.board)
    try:
        T = handheld_trajectory(rig.board, 1)[0]
        renderer.set_board_pose(T, rig.proj_from_cam, rig.board)
        img = renderer.render()
        assert img.shape == (rig.projector.height, rig.projector.width, 3) and img.dtype == np.uint8
        lit = img.max(axis=2) > 20
        assert 0.01 < lit.mean() < 0.5
        assert img[0, 0].sum() == 0 and img[-1, -1].sum() == 0  # corners: no light
        # the red X axis is drawn where the board's +x direction projects
        assert (img[..., 0] > 150).sum() > 50
    finally:
        for name in ("axis_x", "axis_y", "axis_z", "cube", "grid"):
            renderer.remove(name)
    assert renderer.node_names == []


def test_render_from_another_thread_is_refused(renderer):
    renderer.render()  # binds to this thread
    errors = []

    def other():
        try:
            renderer.render()
        except RuntimeError as exc:
            errors.append(exc)

    th = threading.Thread(target=other)
    th.start()
    th.join()
    assert errors and "thread" in str(errors[0])


def test_closed_loop_landing_error(rig, renderer):
    check = LandingCheck(renderer, rig.board)
    P = rig.projector
    try:
        # exact pose: only the render and blob detection remain
        T = handheld_trajectory(rig.board, 1)[0]
        exact = check.measure(T, rig.proj_from_cam, P.K, P.dist, rig.proj_from_cam @ T)
        assert np.all(np.isfinite(exact.errors_mm)) and np.max(exact.errors_mm) < 0.2
        # pose estimated from synthetic camera frames
        errs = []
        for T in handheld_trajectory(rig.board, 4, TrajectoryConfig(seed=11)):
            est = estimate_board_pose(rig.render(T), rig.board, rig.camera.K, rig.camera.dist)
            res = check.measure(est.T_cam_from_board, rig.proj_from_cam, P.K, P.dist, rig.proj_from_cam @ T)
            errs.extend(res.errors_mm)
        assert np.median(errs) <= 2.0
        # a deliberately wrong projector pose must show up as a landing error
        T_wrong = rig.proj_from_cam.copy()
        T_wrong[0, 3] += 0.01
        res = check.measure(T, T_wrong, P.K, P.dist, rig.proj_from_cam @ T)
        assert np.nanmedian(res.errors_mm) > 5.0
    finally:
        renderer.remove("landing_dots")


def test_parts_at_one_distance_are_drawn_in_name_order_in_every_process(rig, renderer):
    """Coplanar quads at one node pose: pyrender alone draws them in its node set's
    order (object addresses: a different winner per process); ours by name, so the
    first name's colour wins everywhere (GL_LESS keeps the first fragment at equal depth)."""
    import pyrender
    import trimesh

    P, r = rig.projector, renderer
    rng = np.random.default_rng(3)
    names = [f"part{k:02d}" for k in range(24)]
    colours = {n: rng.uniform(0.2, 1.0, 3) for n in names}
    quad = trimesh.Trimesh(vertices=[[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], faces=[[0, 1, 2], [0, 2, 3]])
    try:
        for n in rng.permutation(names):
            mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[*colours[n], 1.0])
            r.add(n, pyrender.Mesh.from_trimesh(quad, material=mat, smooth=False))
        r.set_view(look_at(np.array([0.0, 0.0, 3.0]), np.zeros(3), np.array([0.0, -1.0, 0.0])))
        img = r.render(flat=True)
        order = [node.name for node in r._renderer._renderer._sorted_mesh_nodes(r.scene)]
        assert order == names
        centre = img[P.height // 2, P.width // 2].astype(float) / 255
        np.testing.assert_allclose(centre, colours["part00"], atol=2 / 255)
    finally:
        for n in names:
            r.remove(n)
