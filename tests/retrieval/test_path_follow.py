"""Walking and running along drawn paths: path error, foot skate, loops, one-shots and
transitions picked by the quantised code table. Runs on the bundled motions only."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ar.render.characters import build_character
from retrieval.animation import foot_skate_cm_per_m, path_error_cm, point_to_polyline
from retrieval.features import motion_features
from retrieval.motion.formats import load_motion
from retrieval.animation import OneShot, PathError, TablePath, follow_path, s_curve_path, straight_path
from retrieval.codes import Quantizer
from retrieval.animation import retarget
from retrieval.animation import code_transition_cost, find_loop, judge_transition, root_heading

BVH = Path(__file__).resolve().parents[2] / "assets" / "motions" / "bvh"


@pytest.fixture(scope="module")
def robot():
    return build_character("robot")


@pytest.fixture(scope="module")
def clips(robot):
    names = {"walk": "02_01", "run": "02_03", "jump": "16_01", "kick": "10_03", "dance": "05_11"}
    return {k: retarget(load_motion(BVH / f"{v}.bvh"), robot.skeleton) for k, v in names.items()}


@pytest.mark.parametrize("kind", ["walk", "run"])
@pytest.mark.parametrize("shape", ["straight", "s-curve"])
def test_follows_path_within_a_tenth_of_height_without_skating(clips, robot, kind, shape):
    path = straight_path(0.6) if shape == "straight" else s_curve_path(0.6, 0.08)
    res = follow_path(clips[kind], path)
    m = res.motion
    err = path_error_cm(m, path.points)
    assert err < 0.1 * robot.height_m * 100  # < 1.2 cm at 12 cm (measured about 0.1 cm)
    assert foot_skate_cm_per_m(m) < 2.0
    # reaches the end of the path, facing along it
    end = m.root_translation[-1, [0, 2]] * 0.01
    assert np.linalg.norm(end - path.points[-1]) < 0.05 * path.length
    yaw = root_heading(m)
    tangent = np.gradient(path.points, axis=0)
    want = np.arctan2(tangent[:, 0], tangent[:, 1])
    ground = m.root_translation[:, [0, 2]] * 0.01
    nearest = np.argmin(np.linalg.norm(ground[:, None] - path.points[None], axis=-1), axis=1)
    diff = np.angle(np.exp(1j * (yaw - want[nearest])))
    assert np.degrees(np.median(np.abs(diff))) < 15


def test_following_reduces_skate_compared_with_no_planting(clips):
    path = s_curve_path(0.6, 0.1)
    planted = follow_path(clips["walk"], path).motion
    loose = follow_path(clips["walk"], path, plant_feet=False).motion
    assert foot_skate_cm_per_m(planted) < 0.5 * foot_skate_cm_per_m(loose)


def test_duration_is_met_within_natural_rate_limits(clips):
    path = straight_path(0.3)
    natural = follow_path(clips["walk"], path)
    slow = follow_path(clips["walk"], path, duration_s=natural.motion.seconds * 1.2)
    assert slow.rate == pytest.approx(1 / 1.2, rel=0.02)
    assert slow.motion.seconds == pytest.approx(natural.motion.seconds * 1.2, rel=0.03)
    too_slow = follow_path(clips["walk"], path, duration_s=natural.motion.seconds * 5)
    assert too_slow.rate == pytest.approx(0.7)  # clamped, never a slow-motion crawl


def test_timestamps_steer_the_pace(clips):
    pts = straight_path(0.4, n=5).points
    natural = follow_path(clips["walk"], TablePath(pts)).motion.seconds  # at rate 1
    quick, slow = natural / 4 / 1.3, natural / 4 / 0.75  # per 10 cm: 1.3x then 0.75x
    fast_then_slow = TablePath(pts, times=np.cumsum([0.0, quick, quick, slow, slow]))
    res = follow_path(clips["walk"], fast_then_slow)
    x = res.motion.root_translation[:, 0] * 0.01
    t = np.arange(len(x)) / res.motion.fps
    at = lambda s: np.interp(s, t, x)
    assert at(2 * quick) == pytest.approx(0.2, abs=0.02)  # half way at the half-way time
    assert at(2 * quick + 2 * slow) == pytest.approx(0.4, abs=0.02)


def test_loop_points_resemble_each_other(clips):
    loop = find_loop(clips["walk"], blend_frames=9)
    assert loop.period >= 0.6 * clips["walk"].fps and loop.cost < 0.05


def test_one_shots_are_placed_on_the_path(clips):
    path = s_curve_path(0.6, 0.08)
    q = Quantizer.fit(np.concatenate([motion_features(clips[k]) for k in ("walk", "jump", "kick")]), 6)
    res = follow_path(clips["walk"], path, one_shots=[OneShot(clips["jump"], 0.2), OneShot(clips["kick"], 0.4)],
                      transition_cost=code_transition_cost(q))
    events = res.info["events"]
    assert [e["clip"] for e in events] == ["16_01", "10_03"]
    m = res.motion
    ground = m.root_translation[:, [0, 2]] * 0.01
    assert point_to_polyline(ground, path.points).mean() < 0.01
    step = np.linalg.norm(np.diff(ground, axis=0), axis=1)
    assert step.max() < 0.01  # no teleport at the joins: < 1 cm per frame at 12 cm


def test_code_table_transitions_beat_random_points(clips):
    q = Quantizer.fit(np.concatenate([motion_features(c) for c in clips.values()]), 6)
    cost = code_transition_cost(q)
    pairs = [("walk", "jump"), ("walk", "kick"), ("walk", "dance"), ("walk", "run"), ("run", "jump")]
    chosen, random = [], []
    for a, b in pairs:
        j = judge_transition(clips[a], clips[b], cost, window=9, refine=True)
        chosen.append(j.chosen_pose_cost)
        random.append(j.random_pose_cost_mean)
    chosen, random = np.array(chosen), np.array(random)
    assert (chosen < random).sum() >= 4
    assert chosen.mean() < 0.8 * random.mean()


def test_bad_paths_raise():
    with pytest.raises(PathError):
        TablePath(np.zeros((1, 2)))
    with pytest.raises(PathError):
        TablePath(np.zeros((3, 2)))
    with pytest.raises(PathError):
        TablePath(np.array([[0, 0], [1, np.nan]]))
    with pytest.raises(PathError):
        TablePath(np.array([[0, 0], [1, 0]]), times=[1.0, 0.5])


def test_choosing_a_clip_by_class_or_by_query():
    from retrieval.library import MotionIndex
    from retrieval.library import choose_clip, clip_path

    trials = {"02_01": "walk", "16_15": "walk", "16_31": "walk", "02_03": "run", "09_01": "run", "16_01": "jump"}
    motions = [load_motion(BVH / f"{t}.bvh").copy(name=t) for t in trials]
    index = MotionIndex.from_motions(motions, list(trials.values()))
    trial, label, _ = choose_clip(index, "walk")
    assert label == "walk" and trial in {"02_01", "16_15", "16_31"}
    # a query answers with the nearest clip of the wanted class, never an excluded one
    q = motions[1].slice(20, 80)
    t2, l2, d2 = choose_clip(index, "walk", q, exclude=("16_15",))
    assert l2 == "walk" and t2 != "16_15" and d2 >= 0
    assert choose_clip(index, query=q)[1] == "walk"  # any class allowed: still a walk
    assert clip_path(BVH.parent, "16_01").name == "16_01.bvh"
    with pytest.raises(Exception, match="dance"):
        choose_clip(index, "dance")
