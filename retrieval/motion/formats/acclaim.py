"""Acclaim ASF (skeleton) and AMC (motion) files -> the :mod:`retrieval.motion.model` model.

The CMU database's native format. How an Acclaim skeleton maps onto :class:`Skeleton`
(see also motion.py's docstring):

* Each bone becomes a joint at the bone's *start*; the joints of its child bones sit at
  its tip, i.e. they are offset by ``direction * length`` (the ASF gives directions in
  the world frame of the rest pose, which is exactly the "parent frame" of our FK because
  every local rotation below is expressed in that same frame). Bones with no children get
  an end-site joint ``<bone>_end`` at their tip, so the hands, toes and head top exist.
* A bone's local rotation is ``R = C @ E @ C.T``: ``C`` is the bone's ``axis ax ay az
  XYZ`` line and ``E`` its AMC dof values. Both compose like CMU's own viewer and the
  common parsers: the order string lists the rotations in the order they are *applied*,
  so ``XYZ`` / ``dof rx ry rz`` give ``Rz @ Ry @ Rx``. Bones with fewer dofs (``dof rx``,
  ``dof ry rz``) simply lack the missing factors; bones without dofs never rotate.
  This is checked against an independent BVH conversion of the same take in
  tests/test_motion_io.py (joint positions agree to about a millimetre).
* The root uses ``:root order`` for its AMC values (translation in the ASF's length
  unit, rotation composed like a bone's dofs) and ``axis``/``orientation`` for its ``C``.
* Units: ``:units length L`` means one file unit is ``1/L`` inches (CMU's FAQ), so
  ``metres_per_unit = 0.0254 / L``; angles follow ``:units angle`` unless the AMC says
  ``:RADIANS``/``:DEGREES``. Acclaim files are Y up.

After folding ``C`` in, every rotation is a general 3-D rotation, so every bone joint is
given the BVH-equivalent channel layout ``Zrotation Yrotation Xrotation`` (the root also
``X/Y/Zposition``); that is the layout :func:`retrieval.motion.formats.bvh.save_bvh` writes. The
Acclaim dof lists are kept in :class:`AcclaimSkeleton`.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from retrieval.errors import MotionFormatError
from retrieval.motion.formats.textfile import (
    MAX_DEPTH,
    MAX_JOINTS,
    check_coordinates,
    check_motion_size,
    parse_float,
    parse_floats,
    read_lines,
)
from retrieval.motion.model import Joint, Motion, Skeleton
from retrieval.motion.rotations import axis_rotation

#: CMU's takes are captured at 120 frames per second; AMC files do not say so.
DEFAULT_AMC_FPS = 120.0

_ROTATION_DOFS = ("rx", "ry", "rz")
_TRANSLATION_DOFS = ("tx", "ty", "tz")
_BONE_CHANNELS = ["Zrotation", "Yrotation", "Xrotation"]
_ROOT_CHANNELS = ["Xposition", "Yposition", "Zposition"] + _BONE_CHANNELS


@dataclass
class _Bone:
    name: str
    line: int
    direction: np.ndarray = field(default_factory=lambda: np.zeros(3))
    length: float = 0.0
    axis: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis_order: str = "XYZ"
    dofs: list[str] = field(default_factory=list)


@dataclass
class AcclaimSkeleton:
    """A parsed ASF: the :class:`Skeleton` plus what is needed to read AMC files for it.

    ``dofs[name]`` is the bone's dof list in file order (the root's from ``:root order``,
    lower case); ``joint_of[name]`` its joint index; ``axis_matrix[name]`` its ``C``.
    """

    skeleton: Skeleton
    dofs: dict[str, list[str]]
    joint_of: dict[str, int]
    axis_matrix: dict[str, np.ndarray]
    degrees: bool
    path: str


def compose_in_application_order(axes: str | list[str], angles: np.ndarray) -> np.ndarray:
    """Rotation applying ``axes[0]`` first, then ``axes[1]``, ...: for axes ``XYZ`` this is
    ``Rz @ Ry @ Rx``. ``angles`` is (..., k) radians; returns (..., 3, 3)."""
    angles = np.asarray(angles, dtype=np.float64)
    out = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for k, axis in enumerate(axes):
        out = axis_rotation(axis, angles[..., k]) @ out
    return out


# ----------------------------------------------------------------------------- ASF


def load_asf(path: str | Path) -> AcclaimSkeleton:
    """Parse an ASF skeleton file (raises :class:`MotionFormatError` on bad input)."""
    path = Path(path)
    lines = read_lines(path)
    parser = _AsfParser(path, lines)
    return parser.parse()


class _AsfParser:
    def __init__(self, path: Path, lines: list[str]):
        self.path = path
        self.lines = lines
        self.length_scale = 1.0
        self.degrees = True
        self.root_order: list[str] = ["tx", "ty", "tz", "rx", "ry", "rz"]
        self.root_axis = "XYZ"
        self.root_position = np.zeros(3)
        self.root_orientation = np.zeros(3)
        self.bones: dict[str, _Bone] = {}
        self.children: dict[str, list[str]] = {}
        self.has_parent: set[str] = set()  # O(1) "two parents" check (a list scan was O(n^2))
        self.seen_sections: set[str] = set()

    def fail(self, problem: str, line: int | None = None) -> MotionFormatError:
        return MotionFormatError(self.path, problem, line)

    def parse(self) -> AcclaimSkeleton:
        section = None
        bone: _Bone | None = None
        in_hierarchy_block = False
        for ln, raw in enumerate(self.lines, 1):
            s = raw.split("#", 1)[0].strip()
            if not s:
                continue
            tokens = s.split()
            key = tokens[0].lower()
            if key.startswith(":"):
                if bone is not None:
                    raise self.fail(f"bone {bone.name!r} has no 'end'", bone.line)
                section = key
                self.seen_sections.add(section)
                if section in (":version", ":name"):
                    section = None
                elif section in (":units", ":root", ":bonedata", ":hierarchy", ":documentation", ":skin"):
                    pass
                # unknown sections are skipped (the format allows extensions)
                continue
            if section == ":units":
                self._units(tokens, ln)
            elif section == ":root":
                self._root(tokens, ln)
            elif section == ":bonedata":
                if key == "begin":
                    if bone is not None:
                        raise self.fail("'begin' inside a bone (missing 'end')", ln)
                    bone = _Bone(name="", line=ln)
                elif key == "end":
                    if bone is None:
                        raise self.fail("'end' without 'begin'", ln)
                    self._finish_bone(bone)
                    bone = None
                elif bone is None:
                    raise self.fail(f"unexpected {tokens[0]!r} outside begin/end", ln)
                else:
                    self._bone_line(bone, tokens, ln)
            elif section == ":hierarchy":
                if key == "begin":
                    in_hierarchy_block = True
                elif key == "end":
                    in_hierarchy_block = False
                elif in_hierarchy_block:
                    self._hierarchy(tokens, ln)
                else:
                    raise self.fail(f"unexpected {tokens[0]!r} outside hierarchy begin/end", ln)
        if bone is not None:
            raise self.fail(f"file ends inside bone {bone.name!r} (missing 'end')", bone.line)
        for required in (":root", ":bonedata", ":hierarchy"):
            if required not in self.seen_sections:
                raise self.fail(f"no {required} section (is this an ASF file?)")
        return self._build()

    def _units(self, tokens: list[str], ln: int) -> None:
        key = tokens[0].lower()
        if len(tokens) < 2:
            raise self.fail(f"units line {tokens[0]!r} has no value", ln)
        if key == "length":
            self.length_scale = parse_float(tokens[1], self.path, ln, "length unit")
            if self.length_scale <= 0:
                raise self.fail("length unit must be positive", ln)
            if not 1e-6 <= self.length_scale <= 1e6:  # 5e-324 made metres_per_unit inf (fuzzing)
                raise self.fail(f"length unit {self.length_scale:g} is implausible (expected 1e-6 to 1e6)", ln)
        elif key == "angle":
            unit = tokens[1].lower()
            if unit not in ("deg", "rad"):
                raise self.fail(f"unknown angle unit {tokens[1]!r} (expected deg or rad)", ln)
            self.degrees = unit == "deg"

    def _root(self, tokens: list[str], ln: int) -> None:
        key = tokens[0].lower()
        if key == "order":
            order = [t.lower() for t in tokens[1:]]
            bad = [t for t in order if t not in _ROTATION_DOFS + _TRANSLATION_DOFS]
            if bad or len(set(order)) != len(order):
                raise self.fail(f"bad root order {' '.join(tokens[1:])!r}", ln)
            self.root_order = order
        elif key == "axis":
            if len(tokens) != 2 or not _is_axis_order(tokens[1]):
                raise self.fail(f"bad root axis {' '.join(tokens[1:])!r}", ln)
            self.root_axis = tokens[1].upper()
        elif key in ("position", "orientation"):
            if len(tokens) != 4:
                raise self.fail(f"root {key} needs 3 numbers, found {len(tokens) - 1}", ln)
            vec = np.array(parse_floats(tokens[1:], self.path, ln, f"root {key}"))
            check_coordinates(vec, self.path, ln, f"root {key}")
            if key == "position":
                self.root_position = vec
            else:
                self.root_orientation = vec

    def _bone_line(self, bone: _Bone, tokens: list[str], ln: int) -> None:
        key = tokens[0].lower()
        if key == "name":
            if len(tokens) != 2:
                raise self.fail("bone name must be one word", ln)
            bone.name = tokens[1]
        elif key == "direction":
            if len(tokens) != 4:
                raise self.fail(f"direction needs 3 numbers, found {len(tokens) - 1}", ln)
            bone.direction = np.array(parse_floats(tokens[1:], self.path, ln, "direction"))
        elif key == "length":
            if len(tokens) != 2:
                raise self.fail("length needs 1 number", ln)
            bone.length = parse_float(tokens[1], self.path, ln, "length")
            if bone.length < 0:
                raise self.fail("bone length is negative", ln)
            check_coordinates(bone.length, self.path, ln, "bone length")
        elif key == "axis":
            if len(tokens) != 5 or not _is_axis_order(tokens[4]):
                raise self.fail("axis line must be 'axis ax ay az ORDER' (e.g. XYZ)", ln)
            bone.axis = np.array(parse_floats(tokens[1:4], self.path, ln, "axis angle"))
            bone.axis_order = tokens[4].upper()
        elif key == "dof":
            dofs = [t.lower() for t in tokens[1:]]
            for d in dofs:
                if d in _TRANSLATION_DOFS or d == "l":
                    raise self.fail(f"bone {bone.name!r}: dof {d!r} (translation/length) is not supported", ln)
                if d not in _ROTATION_DOFS:
                    raise self.fail(f"bone {bone.name!r}: unknown dof {d!r}", ln)
            if len(set(dofs)) != len(dofs):
                raise self.fail(f"bone {bone.name!r}: repeated dof", ln)
            bone.dofs = dofs
        # id, limits (and their continuation lines), bodymass, cofmass: not needed

    def _finish_bone(self, bone: _Bone) -> None:
        if not bone.name:
            raise self.fail("bone without a name", bone.line)
        if bone.name in self.bones or bone.name == "root":
            raise self.fail(f"bone {bone.name!r} defined twice", bone.line)
        norm = float(np.linalg.norm(bone.direction))
        if norm < 1e-9 and bone.length > 0:
            raise self.fail(f"bone {bone.name!r} has a zero direction", bone.line)
        if norm > 0:
            bone.direction = bone.direction / norm
        if len(self.bones) >= MAX_JOINTS:
            raise self.fail(f"more than {MAX_JOINTS} bones (not a real skeleton)", bone.line)
        self.bones[bone.name] = bone

    def _hierarchy(self, tokens: list[str], ln: int) -> None:
        parent, kids = tokens[0], tokens[1:]
        for name in [parent] + kids:
            if name != "root" and name not in self.bones:
                raise self.fail(f"hierarchy names unknown bone {name!r}", ln)
        for kid in kids:
            if kid == "root":
                raise self.fail("root cannot be a child", ln)
            if kid in self.has_parent:
                raise self.fail(f"bone {kid!r} has two parents", ln)
            self.has_parent.add(kid)
        self.children.setdefault(parent, []).extend(kids)

    def _build(self) -> AcclaimSkeleton:
        scale = np.pi / 180.0 if self.degrees else 1.0
        root_c = compose_in_application_order(self.root_axis, self.root_orientation * scale)
        joints = [
            Joint("root", -1, self.root_position.copy(), list(_ROOT_CHANNELS), "ZYX", root_c)
        ]
        joint_of = {"root": 0}
        axis_matrix = {"root": root_c}
        dofs = {"root": list(self.root_order)}
        # Depth-first from the root, parents before children.
        stack: list[tuple[str, int, np.ndarray, int]] = [
            (kid, 0, np.zeros(3), 1) for kid in reversed(self.children.get("root", []))
        ]
        while stack:
            name, parent, offset, depth = stack.pop()
            if depth > MAX_DEPTH:
                raise self.fail(f"hierarchy deeper than {MAX_DEPTH} bones")
            bone = self.bones[name]
            c = compose_in_application_order(bone.axis_order, bone.axis * scale)
            idx = len(joints)
            joints.append(Joint(name, parent, offset, list(_BONE_CHANNELS), "ZYX", c))
            joint_of[name], axis_matrix[name], dofs[name] = idx, c, list(bone.dofs)
            tip = bone.direction * bone.length
            kids = self.children.get(name, [])
            if not kids:
                joints.append(Joint(f"{name}_end", idx, tip.copy()))
            for kid in reversed(kids):
                stack.append((kid, idx, tip.copy(), depth + 1))
        unreachable = sorted(set(self.bones) - set(joint_of))
        if unreachable:
            raise self.fail(f"bones not connected to the root: {', '.join(unreachable[:10])}")
        skeleton = Skeleton(joints, metres_per_unit=0.0254 / self.length_scale, up_axis="y", name=self.path.stem)
        return AcclaimSkeleton(skeleton, dofs, joint_of, axis_matrix, self.degrees, str(self.path))


def _is_axis_order(s: str) -> bool:
    return len(s) == 3 and sorted(s.upper()) == ["X", "Y", "Z"]


# ----------------------------------------------------------------------------- AMC


def load_amc(path: str | Path, skeleton: AcclaimSkeleton | str | Path, fps: float = DEFAULT_AMC_FPS) -> Motion:
    """Read an AMC motion for ``skeleton`` (an :class:`AcclaimSkeleton` or an ASF path).

    Bones missing from a frame keep identity rotation (their dof values read as 0); a
    bone the skeleton does not know, a wrong number of values, a bad number or a file
    without frames raises :class:`MotionFormatError`.
    """
    path = Path(path)
    asf = skeleton if isinstance(skeleton, AcclaimSkeleton) else load_asf(skeleton)
    if fps <= 0:
        raise MotionFormatError(path, f"frame rate must be positive, got {fps}")
    lines = read_lines(path)
    degrees = asf.degrees
    first = None  # index of the first frame-number line
    for i, raw in enumerate(lines):
        s = raw.strip()
        if not s or s[0] == "#":
            continue
        if s[0] == ":":
            flag = s.split()[0].upper()
            if flag in (":RADIANS", ":DEGREES"):
                degrees = flag == ":DEGREES"
            continue
        if s.isdecimal():
            first = i
        break
    fast = _read_uniform_frames(lines[first:], asf) if first is not None else None
    n_frames, values = fast if fast is not None else _read_frames_line_by_line(path, lines, asf)
    check_motion_size(path, n_frames, asf.skeleton.n_joints)
    if "root" in values:
        translation = [k for k, d in enumerate(asf.dofs["root"]) if d in _TRANSLATION_DOFS]
        check_coordinates(values["root"][1][:, translation], path, None, "root translation")
    return _amc_to_motion(asf, values, n_frames, degrees, fps, path.stem)


#: The number of an AMC file's first frame (Acclaim's files count from 1, some tools from 0);
#: each next frame's number is one more.
FIRST_AMC_FRAMES = (1, 0)
#: A line of one integer (signed too, so "-3" is refused as a frame number, not read as a bone).
_FRAME_NUMBER = re.compile(r"^[+-]?[0-9]+$")

#: Per bone: (frame indices, (len(frames), n_dofs) values).
_BoneValues = dict[str, tuple[np.ndarray, np.ndarray]]


def _read_uniform_frames(body: list[str], asf: AcclaimSkeleton) -> tuple[int, _BoneValues] | None:
    """Fast path for the usual file: every frame lists the same bones in the same order.

    Each bone's lines are every ``period``-th line, so its values parse in one numpy call
    instead of a Python loop over lines. Returns None at the first irregularity (then the
    line-by-line reader runs and reports any problem with its line number).
    """
    body = [line for line in body if line and not line.isspace()]
    period = next((k for k in range(1, min(len(body), 1024)) if body[k].strip().isdecimal()), len(body))
    if not body or len(body) % period:
        return None
    n = len(body) // period
    if not all(line.strip().isdecimal() for line in body[::period]):
        return None
    numbers = [int(line) if len(line.strip()) <= 12 else -1 for line in body[::period]]
    if numbers[0] not in FIRST_AMC_FRAMES or numbers != list(range(numbers[0], numbers[0] + n)):
        return None
    out: _BoneValues = {}
    frames = np.arange(n)
    for k in range(1, period):
        tokens = " ".join(body[k::period]).split()
        name = tokens[0] if tokens else ""
        dofs = asf.dofs.get(name)
        if dofs is None or name in out or len(tokens) != n * (1 + len(dofs)):
            return None
        table = np.array(tokens).reshape(n, 1 + len(dofs))
        if not (table[:, 0] == name).all():
            return None
        try:
            values = table[:, 1:].astype(np.float64)
        except ValueError:
            return None
        if not np.isfinite(values).all():
            return None
        out[name] = (frames, values)
    return n, out


def _read_frames_line_by_line(path: Path, lines: list[str], asf: AcclaimSkeleton) -> tuple[int, _BoneValues]:
    """Any valid AMC layout (bones in any order, missing or commented lines); raises
    :class:`MotionFormatError` with the line of the first problem."""
    # Per bone: (frame index, line number, value tokens) for every line that names it.
    records: dict[str, list[tuple[int, int, list[str]]]] = {name: [] for name in asf.dofs}
    n_frames = 0
    first_number = 0
    last_seen: dict[str, int] = {}
    for ln, raw in enumerate(lines, 1):
        s = raw.strip()
        if not s or s[0] in "#:":
            continue
        tokens = s.split()
        if len(tokens) == 1 and _FRAME_NUMBER.match(tokens[0]):
            number = int(tokens[0]) if len(tokens[0]) <= 13 else -1  # a huge one is out of range anyway
            if n_frames == 0 and number not in FIRST_AMC_FRAMES:
                raise MotionFormatError(path, f"frame number {tokens[0][:24]} out of range: the first frame is "
                                              f"numbered {' or '.join(map(str, FIRST_AMC_FRAMES))}", ln)
            first_number = number if n_frames == 0 else first_number
            if number != first_number + n_frames:
                raise MotionFormatError(path, f"frame number {tokens[0][:24]} out of range: frame "
                                              f"{first_number + n_frames} comes next", ln)
            n_frames += 1
            continue
        name = tokens[0]
        if n_frames == 0:
            raise MotionFormatError(path, f"bone line {name!r} before the first frame number", ln)
        rec = records.get(name)
        if rec is None:
            raise MotionFormatError(path, f"bone {name!r} is not in skeleton {Path(asf.path).name}", ln)
        if last_seen.get(name) == n_frames:
            raise MotionFormatError(path, f"bone {name!r} appears twice in one frame", ln)
        last_seen[name] = n_frames
        want = len(asf.dofs[name])
        if len(tokens) - 1 != want:
            raise MotionFormatError(
                path, f"bone {name!r} needs {want} values, found {len(tokens) - 1}", ln
            )
        rec.append((n_frames - 1, ln, tokens[1:]))
    if n_frames == 0:
        raise MotionFormatError(path, "no frames (empty motion)")
    values: _BoneValues = {}
    for name, rec in records.items():
        if rec:
            frames = np.array([r[0] for r in rec], dtype=np.int64)
            values[name] = (frames, _values(path, rec, len(asf.dofs[name])))
    return n_frames, values


def _values(path: Path, rec: list[tuple[int, int, list[str]]], width: int) -> np.ndarray:
    """(len(rec), width) floats from the records' tokens, naming the line of a bad one."""
    try:
        arr = np.array([r[2] for r in rec], dtype=np.float64).reshape(len(rec), width)
        if np.isfinite(arr).all():
            return arr
    except ValueError:
        pass
    for _, ln, toks in rec:  # find and report the first bad line
        parse_floats(toks, path, ln, "value")
    raise AssertionError("unreachable")  # pragma: no cover


def _amc_to_motion(
    asf: AcclaimSkeleton, bone_values: _BoneValues, n_frames: int, degrees: bool, fps: float, name: str
) -> Motion:
    sk = asf.skeleton
    rotations = np.broadcast_to(np.eye(3), (n_frames, sk.n_joints, 3, 3)).copy()
    root_translation = np.broadcast_to(sk.joints[0].offset, (n_frames, 3)).copy()
    to_rad = np.pi / 180.0 if degrees else 1.0
    for bone, (frames, present) in bone_values.items():
        dofs = asf.dofs[bone]
        if not dofs:
            continue
        values = np.zeros((n_frames, len(dofs)))
        values[frames] = present
        rot_cols = [k for k, d in enumerate(dofs) if d in _ROTATION_DOFS]
        if bone == "root":
            for k, d in enumerate(dofs):
                if d in _TRANSLATION_DOFS:
                    root_translation[frames, "xyz".index(d[1])] = present[:, k]
        if not rot_cols:
            continue
        axes = [dofs[k][1].upper() for k in rot_cols]
        e = compose_in_application_order(axes, values[:, rot_cols] * to_rad)
        c = asf.axis_matrix[bone]
        rotations[:, asf.joint_of[bone]] = c @ e @ c.T
    return Motion(sk, rotations, root_translation, float(fps), name=name)
