"""DeepMimic motion files (read): reference motions of the DeepMimic simulator (Peng et
al. 2018, ``xbpeng/DeepMimic``), e.g. ``data/motions/humanoid3d_kick.txt``.

A motion is JSON: ``{"Loop": ..., "Frames": [[dt, root x y z, root w x y z, ...], ...]}``.
After the frame's duration ``dt`` (seconds until the next frame) and the root's position
(metres, Y up) and rotation, each non-root joint of the *character* file
(``data/characters/humanoid3d.txt``: ``Skeleton.Joints`` with ``ID``, ``Name``, ``Type``,
``Parent``, ``AttachX/Y/Z``) follows in ID order: a ``spherical``
joint as a quaternion ``w x y z``, a ``revolute`` one as one angle (radians) about its
joint frame's Z axis, a ``fixed`` one as nothing. So a frame of the 15-joint humanoid
holds 44 numbers.

The character has no head, hand or toe joints, which StoryBeam's canonical body needs
(:func:`retrieval.motion.body.canonical_joint_map`). They are added from the character's
own body shapes (``BodyDefs``): a ``head`` joint at the centre of the neck's sphere, the
wrist (``fixed``) kept as a joint that never turns with an end site at its sphere's rim,
and a toe end site at the front of the foot box, at its sole. Joint names are kept
(``right_knee``...), so the map finds every part by name.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from retrieval.errors import MotionFormatError
from retrieval.motion.formats.textfile import (
    check_coordinates,
    check_motion_size,
    read_lines,
)
from retrieval.motion.model import Joint, Motion, Skeleton
from retrieval.motion.rotations import axis_rotation

#: Values each joint type takes in a frame.
_WIDTH = {"none": 0, "spherical": 4, "revolute": 1, "fixed": 0}
_ROOT_CHANNELS = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
_CHANNELS = ["Zrotation", "Yrotation", "Xrotation"]


def _read_json(path: Path) -> dict:
    text = "\n".join(read_lines(path))
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise MotionFormatError(path, f"not JSON: {exc.msg}", exc.lineno) from None
    if not isinstance(data, dict):
        raise MotionFormatError(path, "expected a JSON object at the top")
    return data


def _number(value, path: Path, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise MotionFormatError(path, f"{what} must be a finite number, got {value!r}"[:160])
    return float(value)


def _quat_matrices(q: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions ``w x y z`` (normalised here) -> (N, 3, 3) rotation matrices."""
    n = np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = (q / np.where(n > 0, n, 1.0)).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def load_character(path: str | Path) -> tuple[list[dict], dict[str, dict]]:
    """The character file's joints (in ID order, checked) and body shapes by name."""
    path = Path(path)
    data = _read_json(path)
    joints = data.get("Skeleton", {}).get("Joints") if isinstance(data.get("Skeleton"), dict) else None
    if not isinstance(joints, list) or not joints:
        raise MotionFormatError(path, "no Skeleton.Joints list (is this a DeepMimic character file?)")
    out = []
    for k, j in enumerate(joints):
        if not isinstance(j, dict):
            raise MotionFormatError(path, f"joint {k}: expected an object")
        for key in ("ID", "Name", "Type", "Parent", "AttachX", "AttachY", "AttachZ"):
            if key not in j:
                raise MotionFormatError(path, f"joint {k}: missing {key}")
        if j["ID"] != k:
            raise MotionFormatError(path, f"joint {k}: ID {j['ID']!r}, expected joints in ID order 0, 1, 2...")
        if j["Type"] not in _WIDTH:
            raise MotionFormatError(path, f"joint {j['Name']!r}: unknown type {j['Type']!r} "
                                          f"(expected {', '.join(_WIDTH)})")
        parent = j["Parent"]
        if (k == 0) != (parent == -1) or not isinstance(parent, int) or parent >= k:
            raise MotionFormatError(path, f"joint {j['Name']!r}: parent {parent!r} must come before it "
                                          "(and only the first joint has none)")
        attach = [_number(j[f"Attach{a}"], path, f"joint {j['Name']!r} Attach{a}") for a in "XYZ"]
        if any(_number(j.get(f"AttachTheta{a}", 0.0), path, f"joint {j['Name']!r} AttachTheta{a}")
               for a in "XYZ"):
            # DeepMimic's own characters all have joint frames aligned with their parents'.
            raise MotionFormatError(path, f"joint {j['Name']!r}: a turned joint frame (AttachTheta) "
                                          "is not supported")
        check_coordinates(attach, path, None, "joint offset")
        out.append({"name": str(j["Name"]), "type": j["Type"], "parent": parent, "attach": np.array(attach)})
    bodies = {}
    for b in data.get("BodyDefs", []) or []:
        if isinstance(b, dict) and "Name" in b:
            try:
                bodies[str(b["Name"])] = {
                    "shape": b.get("Shape"),
                    "centre": np.array([float(b["AttachX"]), float(b["AttachY"]), float(b["AttachZ"])]),
                    "size": np.array([float(b["Param0"]), float(b["Param1"]), float(b["Param2"])]),
                }
            except (KeyError, TypeError, ValueError):
                raise MotionFormatError(path, f"body {b['Name']!r}: bad Attach or Param values") from None
    return out, bodies


def _skeleton(joints: list[dict], bodies: dict[str, dict], name: str) -> tuple[Skeleton, list[int]]:
    """The StoryBeam skeleton and, per character joint, its index in it (added head, hand
    and toe joints go right after their parent's subtree root, so parents still come first)."""
    sk_joints: list[Joint] = []
    index: list[int] = []

    def add(name: str, parent: int, offset, channels: list[str]) -> int:
        sk_joints.append(Joint(name=name, parent=parent, offset=np.asarray(offset, dtype=float),
                               channels=list(channels), rotation_order="ZYX"))
        return len(sk_joints) - 1

    for k, j in enumerate(joints):
        parent = -1 if k == 0 else index[j["parent"]]
        me = add(j["name"], parent, j["attach"], _ROOT_CHANNELS if k == 0 else _CHANNELS)
        index.append(me)
        body = bodies.get(j["name"])
        base = j["name"].lower()
        if base.endswith("neck"):
            centre = body["centre"] if body is not None else np.array([0.0, 0.175, 0.0])
            radius = body["size"][0] / 2 if body is not None else 0.1
            head = add(j["name"].lower().replace("neck", "head"), me, centre, _CHANNELS)
            add(f"{sk_joints[head].name}_end", head, [0.0, radius, 0.0], [])
        elif j["type"] == "fixed" or base.endswith("wrist"):
            radius = body["size"][0] / 2 if body is not None else 0.04
            add(f"{j['name']}_end", me, [0.0, -radius, 0.0], [])
        elif base.endswith("ankle") and body is not None and body["shape"] == "box":
            c, s = body["centre"], body["size"]
            add(f"{j['name'].lower().replace('ankle', 'toe')}", me,
                [c[0] + s[0] / 2, c[1] - s[1] / 2, c[2]], [])
    return Skeleton(sk_joints, metres_per_unit=1.0, up_axis="y", name=name), index


def load_deepmimic(path: str | Path, character_path: str | Path) -> Motion:
    """Read the DeepMimic motion ``path`` on the character ``character_path`` (see the
    module's docstring). The frame rate is 1 / the first frame's duration (DeepMimic's
    clips keep it constant; the last frame's duration is 0 and unused). Any problem
    raises :class:`MotionFormatError` naming the file."""
    path = Path(path)
    joints, bodies = load_character(character_path)
    data = _read_json(path)
    frames = data.get("Frames")
    if not isinstance(frames, list) or not frames:
        raise MotionFormatError(path, "no Frames list (is this a DeepMimic motion file?)")
    width = 1 + 3 + 4 + sum(_WIDTH[j["type"]] for j in joints[1:])
    for t, row in enumerate(frames):
        if not isinstance(row, list) or len(row) != width:
            got = len(row) if isinstance(row, list) else type(row).__name__
            raise MotionFormatError(path, f"frame {t}: expected {width} values for the character "
                                          f"{Path(character_path).name}, found {got}")
    check_motion_size(path, len(frames), len(joints) + 5)
    for t, row in enumerate(frames):
        for v in row:
            _number(v, path, f"frame {t}: value")
    values = np.array(frames, dtype=np.float64)
    dt = float(values[0, 0])
    if not 1e-4 <= dt <= 1.0:
        raise MotionFormatError(path, f"frame 0: duration {dt:g} s is not a frame time (1e-4 to 1 s)")
    check_coordinates(values[:, 1:4], path, None, "root position")
    skeleton, index = _skeleton(joints, bodies, path.stem)
    n = len(frames)
    rotations = np.tile(np.eye(3), (n, skeleton.n_joints, 1, 1))
    rotations[:, index[0]] = _quat_matrices(values[:, 4:8])
    col = 8
    for k, j in enumerate(joints[1:], start=1):
        if j["type"] == "spherical":
            rotations[:, index[k]] = _quat_matrices(values[:, col:col + 4])
        elif j["type"] == "revolute":
            rotations[:, index[k]] = axis_rotation("z", values[:, col])
        col += _WIDTH[j["type"]]
    return Motion(skeleton=skeleton, rotations=rotations, root_translation=values[:, 1:4].copy(),
                  fps=1.0 / dt, name=path.stem)
