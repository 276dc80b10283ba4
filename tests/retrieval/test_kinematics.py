"""Forward kinematics, resampling, Euler conversions and the canonical joint map."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.motion import canonical_joint_map
from retrieval.motion import positions, resample, rest_positions
from retrieval.motion import Joint, Motion, Skeleton
from retrieval.motion import axis_rotation, euler_to_matrix, matrix_to_euler

ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


def _arm(up_axis: str = "y", metres_per_unit: float = 0.01) -> Skeleton:
    """root -> shoulder (10 up) -> elbow (30 along x) -> hand end site (20 along x)."""
    return Skeleton(
        [
            Joint("root", -1, np.zeros(3), ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]),
            Joint("shoulder", 0, np.array([0.0, 10.0, 0.0]), ["Zrotation", "Yrotation", "Xrotation"]),
            Joint("elbow", 1, np.array([30.0, 0.0, 0.0]), ["Zrotation", "Yrotation", "Xrotation"]),
            Joint("hand_end", 2, np.array([20.0, 0.0, 0.0])),
        ],
        metres_per_unit=metres_per_unit,
        up_axis=up_axis,
    )


def _one_frame(sk: Skeleton, local: dict[int, np.ndarray], root=(0.0, 0.0, 0.0)) -> Motion:
    rot = np.broadcast_to(np.eye(3), (1, sk.n_joints, 3, 3)).copy()
    for j, r in local.items():
        rot[0, j] = r
    return Motion(sk, rot, np.array([root], dtype=float), 30.0)


def test_fk_matches_hand_computed_positions():
    sk = _arm()
    rz90 = axis_rotation("Z", np.pi / 2)  # x -> y
    ry90 = axis_rotation("Y", np.pi / 2)  # x -> -z
    m = _one_frame(sk, {1: rz90, 2: ry90}, root=(100.0, 0.0, 0.0))
    got = positions(m, metres_yup=False)[0]
    # shoulder: root + (0,10,0); elbow: shoulder + Rz90 (30,0,0) = + (0,30,0);
    # hand: elbow + Rz90 Ry90 (20,0,0) = + Rz90 (0,0,-20) = + (0,0,-20).
    expected = np.array([[100, 0, 0], [100, 10, 0], [100, 40, 0], [100, 40, -20]], dtype=float)
    np.testing.assert_allclose(got, expected, atol=1e-12)
    np.testing.assert_allclose(positions(m)[0], expected * 0.01, atol=1e-12)


def test_root_rotation_moves_whole_body():
    sk = _arm()
    m = _one_frame(sk, {0: axis_rotation("X", np.pi / 2)})  # y -> z
    got = positions(m, metres_yup=False)[0]
    np.testing.assert_allclose(got[1], [0, 0, 10], atol=1e-12)
    np.testing.assert_allclose(got[3], [50, 0, 10], atol=1e-12)


def test_z_up_positions_are_converted_to_y_up():
    sk = _arm(up_axis="z", metres_per_unit=0.0254)
    sk.joints[1].offset = np.array([0.0, 0.0, 10.0])  # "up" in a Z-up file
    got = positions(_one_frame(sk, {}))[0]
    np.testing.assert_allclose(got[1], [0, 10 * 0.0254, 0], atol=1e-12)
    np.testing.assert_allclose(rest_positions(sk)[3], [50 * 0.0254, 10 * 0.0254, 0], atol=1e-12)


def test_joint_translations_replace_offsets():
    sk = _arm()
    m = _one_frame(sk, {})
    jt = np.broadcast_to(sk.offsets, (1, 4, 3)).copy()
    jt[0, 2] = [0.0, 0.0, 5.0]
    m.joint_translations = jt
    np.testing.assert_allclose(positions(m, metres_yup=False)[0, 2], [0, 10, 5], atol=1e-12)


def test_resample_keeps_duration_and_coincident_frames():
    rng = np.random.default_rng(0)
    sk = _arm()
    n = 121
    angles = np.cumsum(rng.normal(0, 2, size=(n, sk.n_joints, 3)), axis=0)
    rot = euler_to_matrix(angles, "ZYX")
    root = np.cumsum(rng.normal(0, 1, size=(n, 3)), axis=0)
    m = Motion(sk, rot, root, 120.0)
    r = resample(m, 30.0)
    assert r.n_frames == 31
    assert (r.n_frames - 1) / r.fps == pytest.approx((m.n_frames - 1) / m.fps)
    # 30 fps frame k is 120 fps frame 4k exactly.
    np.testing.assert_allclose(r.rotations, m.rotations[::4], atol=1e-9)
    np.testing.assert_allclose(r.root_translation, m.root_translation[::4], atol=1e-9)
    up = resample(m, 240.0)
    assert (up.n_frames - 1) / up.fps == pytest.approx((m.n_frames - 1) / m.fps)
    # Midpoints of translations are linear interpolations.
    np.testing.assert_allclose(up.root_translation[1], (root[0] + root[1]) / 2, atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
def test_euler_round_trip(order):
    rng = np.random.default_rng(hash(order) % 2**32)
    angles = rng.uniform(-170, 170, size=(200, 3))
    angles[:, 1] = rng.uniform(-85, 85, size=200)  # stay away from gimbal lock
    m = euler_to_matrix(angles, order)
    back = matrix_to_euler(m, order)
    np.testing.assert_allclose(back, angles, atol=1e-9)
    # The order string is the multiplication order: "ZYX" is Rz @ Ry @ Rx.
    a, b, c = np.deg2rad(angles[0])
    manual = axis_rotation(order[0], a) @ axis_rotation(order[1], b) @ axis_rotation(order[2], c)
    np.testing.assert_allclose(m[0], manual, atol=1e-12)


def _names_skeleton(names_parents: list[tuple[str, int]]) -> Skeleton:
    return Skeleton([Joint(n, p, np.zeros(3), ["Zrotation", "Yrotation", "Xrotation"]) for n, p in names_parents])


def test_canonical_map_uses_pelvis_joint_below_a_floor_root():
    # Character Creator: RL_BoneRoot sits on the floor, CC_Base_Hip is the pelvis.
    names = ["RL_BoneRoot", "CC_Base_Hip", "CC_Base_Pelvis", "CC_Base_L_Thigh", "CC_Base_L_Calf",
             "CC_Base_L_Foot", "CC_Base_L_ToeBase", "CC_Base_R_Thigh", "CC_Base_R_Calf", "CC_Base_R_Foot",
             "CC_Base_R_ToeBase", "CC_Base_Waist", "CC_Base_Spine01", "CC_Base_Spine02",
             "CC_Base_NeckTwist01", "CC_Base_Head", "CC_Base_L_Clavicle", "CC_Base_L_Upperarm",
             "CC_Base_L_Forearm", "CC_Base_L_Hand", "CC_Base_R_Clavicle", "CC_Base_R_Upperarm",
             "CC_Base_R_Forearm", "CC_Base_R_Hand"]
    sk = _names_skeleton([(n, i - 1) for i, n in enumerate(names)])
    got = {k: sk.names[v] for k, v in canonical_joint_map(sk).items()}
    assert got["hips"] == "CC_Base_Hip"
    assert got["spine"] == "CC_Base_Spine02"
    assert got["left_shoulder"] == "CC_Base_L_Upperarm"
    assert got["right_knee"] == "CC_Base_R_Calf"
    assert got["left_toe"] == "CC_Base_L_ToeBase"


def test_canonical_map_on_real_skeletons(cmu_dir):
    from retrieval.motion.formats import load_motion, load_skeleton

    acclaim = load_skeleton(cmu_dir / "asf" / "01.asf").skeleton
    got = {k: acclaim.names[v] for k, v in canonical_joint_map(acclaim).items()}
    assert got == {
        "hips": "root", "spine": "thorax", "neck": "lowerneck", "head": "head",
        "left_shoulder": "lhumerus", "left_elbow": "lradius", "left_hand": "lwrist",
        "right_shoulder": "rhumerus", "right_elbow": "rradius", "right_hand": "rwrist",
        "left_hip": "lfemur", "left_knee": "ltibia", "left_ankle": "lfoot", "left_toe": "ltoes",
        "right_hip": "rfemur", "right_knee": "rtibia", "right_ankle": "rfoot", "right_toe": "rtoes",
    }
    cgspeed = load_motion(cmu_dir / "extra" / "01_01.bvh").skeleton
    got = {k: cgspeed.names[v] for k, v in canonical_joint_map(cgspeed).items()}
    assert (got["hips"], got["spine"], got["left_shoulder"], got["left_hand"], got["right_knee"]) == (
        "Hips", "Spine1", "LeftArm", "LeftHand", "RightLeg")
    cc = load_motion(cmu_dir / "bvh" / "07_01.bvh").skeleton
    assert cc.names[0] == "RL_BoneRoot"
    assert cc.names[canonical_joint_map(cc)["hips"]] == "CC_Base_Hip"
