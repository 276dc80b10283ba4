"""BlazePose landmarks → canonical joints (:mod:`retrieval.motion.landmarks`): on
landmarks made from a known body filmed by a pinhole camera, the joints come back in
StoryBeam's axes with the root's height from the image (a jump rises although world
landmarks are hip-centred), the documented offsets are applied, frames the estimator
missed are interpolated, left and right swapped by the estimator in some frames are
swapped back, and bad input is refused with a clear error."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.motion import canonical_joint_map, positions
from retrieval.motion.landmarks import (
    COLLAPSE_FRACTION,
    DIRECT,
    L_EAR,
    L_HIP,
    L_SHOULDER,
    LR_PAIRS,
    R_EAR,
    R_HIP,
    R_SHOULDER,
    HEAD_ABOVE_NECK,
    UP_OFFSETS,
    LandmarkError,
    consistent_sides,
    fill_gaps,
    landmarks_to_positions,
    metres_per_pixel,
)
from tests.support.synthetic_motion import make_motion, make_skeleton

F, CX, CY, CAM_Y, CAM_Z = 600.0, 320.0, 240.0, 1.0, 4.0


def fake_landmarks(pos: np.ndarray, jm: dict[str, int]) -> tuple[np.ndarray, np.ndarray]:
    """BlazePose-like (world, image) landmarks of canonical positions (metres, Y up, the
    body facing +Z) filmed by a level pinhole camera on +Z, 1 m up: world is
    hip-centred in MediaPipe's axes (x right, y down, z away), image in pixels."""
    t = len(pos)
    lm = np.zeros((t, 33, 3))
    for name, i in DIRECT.items():
        lm[:, i] = pos[:, jm[name]]
    for i in range(33):  # landmarks this test does not model: at the head
        if not lm[:, i].any():
            lm[:, i] = pos[:, jm["head"]]
    lm[:, L_EAR] = pos[:, jm["head"]] + [0.07, 0.0, 0.0]
    lm[:, R_EAR] = pos[:, jm["head"]] - [0.07, 0.0, 0.0]
    mid = (lm[:, L_HIP] + lm[:, R_HIP]) / 2
    world = (lm - mid[:, None]) * np.array([1.0, -1.0, -1.0])
    depth = CAM_Z - lm[..., 2]
    image = np.stack([CX + F * lm[..., 0] / depth, CY - F * (lm[..., 1] - CAM_Y) / depth], axis=-1)
    return world, image


@pytest.fixture(scope="module")
def body():
    sk = make_skeleton()
    m = make_motion(sk, frames=60, arm_swing=40.0)
    jm = canonical_joint_map(sk)
    pos = positions(m)
    pos[..., [0, 2]] -= pos[:, [jm["hips"]]][..., [0, 2]]  # in place, as a performer in front of the tablet
    return pos, jm


def test_axes_and_scale(body):
    pos, jm = body
    world, image = fake_landmarks(pos, jm)
    out, out_jm, leg = landmarks_to_positions(world, image, np.ones(len(pos), bool), (640, 480), 30.0)
    assert out.shape == (len(pos), 18, 3) and set(out_jm) >= set(DIRECT)
    # the performer's left is on +X, the head above the hips: StoryBeam's axes
    assert np.all(out[:, out_jm["left_hip"], 0] > out[:, out_jm["right_hip"], 0])
    assert np.all(out[:, out_jm["head"], 1] > out[:, out_jm["hips"], 1])
    # metres: the hand-to-hand span matches the body's within a few percent
    want = np.linalg.norm(pos[:, jm["left_hand"], :2] - pos[:, jm["right_hand"], :2], axis=1)
    got = np.linalg.norm(out[:, out_jm["left_hand"], :2] - out[:, out_jm["right_hand"], :2], axis=1)
    np.testing.assert_allclose(got, want, rtol=0.08)  # perspective: hands swing in depth
    assert 0.6 < leg < 1.0


def test_root_height_comes_from_the_image(body):
    pos, jm = body
    lifted = pos.copy()
    lifted[20:30] += [0.0, 0.3, 0.0]  # a jump: the whole body 30 cm up for ten frames
    world, image = fake_landmarks(lifted, jm)
    world_still, _ = fake_landmarks(pos, jm)
    np.testing.assert_allclose(world, world_still, atol=1e-12)  # world landmarks cannot see it
    out, out_jm, _ = landmarks_to_positions(world, image, np.ones(len(pos), bool))
    ref, _, _ = landmarks_to_positions(world_still, fake_landmarks(pos, jm)[1], np.ones(len(pos), bool))
    rise = out[:, out_jm["hips"], 1] - ref[:, out_jm["hips"], 1]
    assert np.all(np.abs(rise[20:30] - 0.3) < 0.02), rise[20:30]
    assert np.all(np.abs(np.delete(rise, np.s_[20:30])) < 0.01)


def test_documented_offsets(body):
    pos, jm = body
    world, image = fake_landmarks(pos, jm)
    ok = np.ones(len(pos), bool)
    out, out_jm, leg = landmarks_to_positions(world, image, ok)
    s = metres_per_pixel(world, image, ok)
    mid_px = (image[:, L_HIP] + image[:, R_HIP]) / 2
    ears_px = (image[:, L_EAR] + image[:, R_EAR]) / 2
    # the head sits HEAD_ABOVE_NECK trunk lengths above the neck, on the trunk's line,
    # below the ears (Acclaim's head joint is the top of the neck)
    trunk = out[:, out_jm["neck"]] - out[:, out_jm["hips"]]
    np.testing.assert_allclose(out[:, out_jm["head"]] - out[:, out_jm["neck"]], HEAD_ABOVE_NECK * trunk, atol=1e-12)
    # heights are measured from the take's floor line: find that datum from a joint with no offset (a knee)
    knee_px = image[:, DIRECT["left_knee"], 1]
    datum = out[:, out_jm["left_knee"], 1] - (-(knee_px - np.median(mid_px[:, 1])) * s)
    head_minus_ears_y = out[:, out_jm["head"], 1] - datum - (-(ears_px[:, 1] - np.median(mid_px[:, 1])) * s)
    assert "head" not in UP_OFFSETS and np.all(head_minus_ears_y < 0)
    assert np.all(trunk[:, 1] > 0)
    # the root above the (corrected) hip joints by hips − hip offset
    root_up = out[:, out_jm["hips"], 1] - (out[:, out_jm["left_hip"], 1] + out[:, out_jm["right_hip"], 1]) / 2
    raw = (UP_OFFSETS["hips"] - UP_OFFSETS["left_hip"])
    assert np.all(root_up > 0.8 * raw * leg * 0.9) and np.all(root_up < 1.2 * raw * leg * 1.3)


def test_a_bigger_head_leaves_the_head_joint_where_it_is(body):
    """A child's head is larger for its body than an adult's: ears higher above the
    shoulders must not move the head joint (the top of the neck), nor any other joint."""
    pos, jm = body
    world, image = fake_landmarks(pos, jm)
    ok = np.ones(len(pos), bool)
    ref, rjm, ref_leg = landmarks_to_positions(world, image, ok)
    big = image.copy()
    big[:, [L_EAR, R_EAR], 1] -= 25.0  # ears 25 px (about 17 cm) higher in the image
    out, _, leg = landmarks_to_positions(world, big, ok)
    np.testing.assert_allclose(out, ref, atol=1e-12)
    assert leg == ref_leg


def test_missed_frames_are_interpolated(body):
    pos, jm = body
    world, image = fake_landmarks(pos, jm)
    ok = np.ones(len(pos), bool)
    full, fjm, _ = landmarks_to_positions(world, image, ok)
    ok[10:14] = False
    world[10:14] = np.nan
    image[10:14] = np.nan
    gap, _, _ = landmarks_to_positions(world, image, ok)
    assert np.all(np.isfinite(gap))
    root = fjm["hips"]
    # the clip's image origin and scale are medians over the seen frames: compare shapes
    np.testing.assert_allclose((gap - gap[:, [root]])[:10], (full - full[:, [root]])[:10], atol=5e-3)
    lin = fill_gaps(full, ok)
    np.testing.assert_allclose((gap - gap[:, [root]])[10:14], (lin - lin[:, [root]])[10:14], atol=5e-3)
    assert not np.allclose(gap[10:14], full[10:14], atol=1e-3)  # the gap really was filled, not seen


def test_bad_input_is_refused(body):
    pos, jm = body
    world, image = fake_landmarks(pos, jm)
    with pytest.raises(LandmarkError, match="no frame"):
        landmarks_to_positions(world, image, np.zeros(len(pos), bool))
    with pytest.raises(LandmarkError, match=r"world \(T, 33, 3\)"):
        landmarks_to_positions(world[:, :17], image, np.ones(len(pos), bool))
    with pytest.raises(LandmarkError, match="fps"):
        landmarks_to_positions(world, image, np.ones(len(pos), bool), fps=0.0)


def _swap_sides(a: np.ndarray, frames: np.ndarray) -> np.ndarray:
    out = a.copy()
    left, right = [i for i, _ in LR_PAIRS], [j for _, j in LR_PAIRS]
    out[np.ix_(frames, left + right)] = a[np.ix_(frames, right + left)]
    return out


def test_sides_swapped_by_the_estimator_are_swapped_back(body):
    """BlazePose took the body for one seen from behind in some frames (its left and
    right exchanged): those frames are put back the way the rest of the take is."""
    pos, jm = body
    world, image = fake_landmarks(pos, jm)
    ok = np.ones(len(pos), bool)
    ref, rjm, _ = landmarks_to_positions(world, image, ok)
    swapped = np.zeros(len(pos), bool)
    swapped[[3, 4, 5, 20, 21, 22, 23, 40, 41, 50]] = True
    out, _, _ = landmarks_to_positions(_swap_sides(world, swapped), _swap_sides(image, swapped), ok)
    np.testing.assert_allclose(out, ref, atol=1e-9)
    assert np.all(out[:, rjm["left_hip"], 0] > out[:, rjm["right_hip"], 0])
    # swapped in most frames: the take is made consistent the other way (a mirror image)
    w2, i2, ok2 = consistent_sides(_swap_sides(world, ~swapped), _swap_sides(image, ~swapped), ok)
    assert ok2.all()
    np.testing.assert_allclose(w2, _swap_sides(world, np.ones(len(pos), bool)), atol=1e-12)
    np.testing.assert_allclose(i2, _swap_sides(image, np.ones(len(pos), bool)), atol=1e-12)


def test_frames_caught_half_way_through_a_swap_are_missed(body):
    pos, jm = body
    world, image = fake_landmarks(pos, jm)
    ok = np.ones(len(pos), bool)
    collapsed = image.copy()
    for a, b in ((L_SHOULDER, R_SHOULDER), (L_HIP, R_HIP)):  # both sides onto the middle in frame 30
        collapsed[30, [a, b], 0] = collapsed[30, [a, b], 0].mean() + np.array([0.1, -0.1])
    _, _, kept = consistent_sides(world, collapsed, ok)
    assert not kept[30] and kept.sum() == len(pos) - 1
    _, _, kept = consistent_sides(world, collapsed, ok, collapse=0.0)
    assert kept.all()
    assert 0 < COLLAPSE_FRACTION < 1
    gap, gjm, _ = landmarks_to_positions(world, collapsed, ok)
    w_nan, i_nan = world.copy(), image.copy()
    ok_gap = ok.copy()
    ok_gap[30] = False
    w_nan[30] = np.nan
    i_nan[30] = np.nan
    want, _, _ = landmarks_to_positions(w_nan, i_nan, ok_gap)
    np.testing.assert_allclose(gap, want, atol=1e-9)  # filled like a frame without a body
