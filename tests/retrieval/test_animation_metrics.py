"""The animation measures (retrieval.animation.metrics): distance to a polyline, path
error and foot skate, checked on motions whose answer is known by construction."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ar.render.characters import build_character
from retrieval.animation import retarget, sole_points
from retrieval.animation.metrics import foot_skate, foot_skate_cm_per_m, path_error_cm, point_to_polyline
from retrieval.motion import Motion
from retrieval.motion.formats import load_motion

BVH = Path(__file__).resolve().parents[2] / "assets" / "motions" / "bvh"


def test_point_to_polyline_measures_to_segments_and_their_ends():
    line = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    pts = np.array([[0.5, 0.2], [1.3, 0.5], [-0.3, -0.4], [2.0, 2.0], [1.0, 0.0]])
    want = [0.2, 0.3, 0.5, np.hypot(1.0, 1.0), 0.0]
    np.testing.assert_allclose(point_to_polyline(pts, line), want, atol=1e-12)


@pytest.fixture(scope="module")
def robot():
    return build_character("robot")


def _standing(robot, frames: int = 60, fps: float = 30.0) -> Motion:
    """The robot in its rest pose, soles on the table (y = 0), standing still."""
    sk = robot.skeleton
    rot = np.broadcast_to(np.eye(3), (frames, sk.n_joints, 3, 3)).copy()
    m = Motion(sk, rot, np.zeros((frames, 3)), fps, "stand")
    lift = -sole_points(m)[:, :, 1].min() / sk.metres_per_unit
    m.root_translation[:, 1] = lift
    return m


def test_path_error_is_the_offset_of_a_root_walking_beside_the_path(robot):
    m = _standing(robot)
    mpu = m.skeleton.metres_per_unit
    m.root_translation[:, 0] = np.linspace(0.0, 0.5, m.n_frames) / mpu  # 50 cm along x ...
    m.root_translation[:, 2] = 0.02 / mpu  # ... 2 cm beside the path
    path = np.array([[0.0, 0.0], [0.5, 0.0]])
    assert path_error_cm(m, path) == pytest.approx(2.0)
    assert path_error_cm(m, path, frames=slice(0, 10)) == pytest.approx(2.0)


def test_a_character_sliding_on_planted_feet_skates_two_feet_per_metre(robot):
    m = _standing(robot)
    # slow enough that the soles count as standing, not swinging
    m.root_translation[:, 0] = np.linspace(0.0, 0.05, m.n_frames) / m.skeleton.metres_per_unit
    total, travelled = foot_skate(m)
    assert travelled == pytest.approx(0.05)
    assert total == pytest.approx(2 * 0.05)  # both feet slide the whole way
    assert foot_skate_cm_per_m(m) == pytest.approx(200.0)


def test_standing_still_or_gliding_in_the_air_is_no_skate(robot):
    still = _standing(robot)
    assert foot_skate(still)[0] == 0.0
    air = _standing(robot)
    air.root_translation[:, 1] += 0.5 * build_character("robot").height_m / air.skeleton.metres_per_unit
    air.root_translation[:, 0] = np.linspace(0.0, 0.05, air.n_frames) / air.skeleton.metres_per_unit
    assert foot_skate(air)[0] == 0.0


def test_foot_skate_reads_the_same_at_any_size(robot):
    walk = retarget(load_motion(BVH / "02_01.bvh"), robot.skeleton)
    big_skeleton = dataclasses.replace(walk.skeleton, metres_per_unit=walk.skeleton.metres_per_unit * 14.0)
    big = walk.copy(skeleton=big_skeleton)
    assert foot_skate_cm_per_m(walk) > 0.0
    assert foot_skate_cm_per_m(big) == pytest.approx(foot_skate_cm_per_m(walk), rel=1e-9)
