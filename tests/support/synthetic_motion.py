"""Hand-made skeletons and motions for retrieval tests (no files, no loaders needed).

A small BVH-style body (Hips, Spine, Neck, Head, arms, legs) whose joint names resolve
through :func:`retrieval.motion.body.canonical_joint_map`, and a family of periodic motions
whose style (arm swing, knee bend, bounce) is set by a few numbers, so tests can make
clips that belong to distinct classes.
"""
from __future__ import annotations

import numpy as np

from retrieval.motion import Joint, Motion, Skeleton
from retrieval.motion import euler_to_matrix

ROT = ["Zrotation", "Yrotation", "Xrotation"]

# name, parent name, offset in centimetres (Y up)
_BODY = [
    ("Hips", None, (0, 95, 0)),
    ("Spine", "Hips", (0, 10, 0)),
    ("Neck", "Spine", (0, 40, 0)),
    ("Head", "Neck", (0, 10, 0)),
    ("LeftArm", "Neck", (18, -5, 0)),
    ("LeftForeArm", "LeftArm", (0, -28, 0)),
    ("LeftHand", "LeftForeArm", (0, -25, 0)),
    ("RightArm", "Neck", (-18, -5, 0)),
    ("RightForeArm", "RightArm", (0, -28, 0)),
    ("RightHand", "RightForeArm", (0, -25, 0)),
    ("LeftUpLeg", "Hips", (9, -5, 0)),
    ("LeftLeg", "LeftUpLeg", (0, -42, 0)),
    ("LeftFoot", "LeftLeg", (0, -40, 0)),
    ("LeftToeBase", "LeftFoot", (0, -6, 12)),
    ("RightUpLeg", "Hips", (-9, -5, 0)),
    ("RightLeg", "RightUpLeg", (0, -42, 0)),
    ("RightFoot", "RightLeg", (0, -40, 0)),
    ("RightToeBase", "RightFoot", (0, -6, 12)),
]


def make_skeleton(scale: float = 1.0, up_axis: str = "y", name: str = "synthetic") -> Skeleton:
    """The test body; ``scale`` multiplies every bone (a child vs an adult)."""
    names = [b[0] for b in _BODY]
    joints = []
    for jname, parent, off in _BODY:
        o = np.array(off, dtype=float) * scale
        if up_axis == "z":  # same body, native axes Z up: (x, y, z)_yup -> (x, -z, y)_zup
            o = np.array([o[0], -o[2], o[1]])
        chans = (["Xposition", "Yposition", "Zposition"] if parent is None else []) + ROT
        joints.append(Joint(jname, -1 if parent is None else names.index(parent), o, chans, "ZYX"))
    return Skeleton(joints, metres_per_unit=0.01, up_axis=up_axis, name=name)


def make_motion(
    skeleton: Skeleton,
    frames: int = 60,
    fps: float = 30.0,
    arm_swing: float = 30.0,
    knee_bend: float = 20.0,
    bounce: float = 0.0,
    period: float = 1.0,
    phase: float = 0.0,
    heading_deg: float = 0.0,
) -> Motion:
    """A periodic gait-like motion: hips swing ±``knee_bend``/2, knees bend, arms swing
    ``arm_swing`` degrees, the root bounces ``bounce`` metres; turned by ``heading_deg``."""
    t = np.arange(frames) / fps
    w = 2 * np.pi * t / period + phase
    nj = skeleton.n_joints
    angles = np.zeros((frames, nj, 3))  # Z, Y, X degrees
    idx = skeleton.index
    angles[:, idx("LeftUpLeg"), 2] = knee_bend * np.sin(w)
    angles[:, idx("RightUpLeg"), 2] = -knee_bend * np.sin(w)
    angles[:, idx("LeftLeg"), 2] = knee_bend * (1 + np.sin(w))
    angles[:, idx("RightLeg"), 2] = knee_bend * (1 - np.sin(w))
    angles[:, idx("LeftArm"), 2] = -arm_swing * np.sin(w)
    angles[:, idx("RightArm"), 2] = arm_swing * np.sin(w)
    angles[:, idx("LeftForeArm"), 2] = -arm_swing / 2 * (1 + np.sin(w))
    angles[:, idx("RightForeArm"), 2] = -arm_swing / 2 * (1 - np.sin(w))
    angles[:, 0, 1] = heading_deg
    rot = euler_to_matrix(angles, "ZYX")
    if skeleton.up_axis == "z":
        a = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # y-up -> z-up native
        rot = a @ rot @ a.T
    unit = 1.0 / skeleton.metres_per_unit
    root = np.zeros((frames, 3))
    root[:, 2] = t * 1.2 * unit
    root[:, 1] = (skeleton.joints[0].offset[1 if skeleton.up_axis == "y" else 2]
                  + bounce * unit * np.abs(np.sin(w)))
    if skeleton.up_axis == "z":
        root = np.stack([root[:, 0], -root[:, 2], root[:, 1]], axis=1)
    return Motion(skeleton, rot, root, fps, name="synthetic")


def write_bvh(motion: Motion, path) -> None:
    """A minimal BVH writer for the test body (ZYX rotations, root position channels)."""
    from retrieval.motion import matrix_to_euler

    sk = motion.skeleton
    lines = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        joint = sk.joints[j]
        pad = "  " * depth
        kw = "ROOT" if joint.parent < 0 else "JOINT"
        lines.append(f"{pad}{kw} {joint.name}")
        lines.append(pad + "{")
        lines.append(pad + "  OFFSET " + " ".join(f"{v:.6f}" for v in joint.offset))
        lines.append(pad + f"  CHANNELS {len(joint.channels)} " + " ".join(joint.channels))
        kids = sk.children(j)
        for k in kids:
            emit(k, depth + 1)
        if not kids:
            lines.append(pad + "  End Site")
            lines.append(pad + "  {")
            lines.append(pad + "    OFFSET 0.0 1.0 0.0")
            lines.append(pad + "  }")
        lines.append(pad + "}")

    emit(0, 0)
    lines.append("MOTION")
    lines.append(f"Frames: {motion.n_frames}")
    lines.append(f"Frame Time: {1.0 / motion.fps:.8f}")
    eul = matrix_to_euler(motion.rotations, "ZYX")  # (T, J, 3)
    order = []

    def walk(j: int) -> None:
        order.append(j)
        for k in sk.children(j):
            walk(k)

    walk(0)
    for t in range(motion.n_frames):
        vals = list(motion.root_translation[t])
        for j in order:
            vals.extend(eul[t, j])
        lines.append(" ".join(f"{v:.6f}" for v in vals))
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


#: A two-bone Acclaim skeleton written by hand (bones ``a``: dof rx, ``b``: dof rx ry rz),
#: for tests of the ASF/AMC readers and of what reads through them.
TINY_ASF = """\
# a tiny test skeleton
:version 1.10
:name tiny
:units
  mass 1.0
  length 0.45
  angle deg
:documentation
  two bones
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name a
     direction 1 0 0
     length 2
     axis 0 0 90  XYZ
    dof rx
    limits (-180.0 180.0)
  end
  begin
     id 2
     name b
     direction 1 0 0
     length 1
     axis 0 0 0 XYZ
    dof rx ry rz
    limits (-180.0 180.0)
           (-180.0 180.0)
           (-180.0 180.0)
  end
:hierarchy
  begin
    root a
    a b
  end
"""
