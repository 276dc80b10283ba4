"""BVH (Biovision hierarchy) reading and writing for the :mod:`retrieval.motion.model` model.

Reading accepts the layouts found in the wild:

* any number of position and rotation channels per joint, in any order. Rotation
  channels compose in the order listed: ``Zrotation Xrotation Yrotation`` gives
  ``R = Rz @ Rx @ Ry``. A non-root joint's position channels *replace* its OFFSET
  component on that axis (``Motion.joint_translations``), which is how MotionBuilder /
  Vicon style 6-channel exports behave; a root without position channels stays at its
  OFFSET.
* The root's position channels are read either as the absolute position ("replace",
  Blender's and most exporters' convention) or as a displacement added to a non-zero
  root OFFSET ("add": Character Creator exports such as the shared ``CC_Base_Hip``
  files, OFFSET ``0 105 0`` with channel values near 0). ``root_offset="auto"``
  (default) picks, when the root OFFSET is non-zero, the reading that puts the lowest
  joint (median over frames) nearer the ground plane (height 0); with a zero OFFSET both
  agree. The result is stored as absolute ``root_translation`` either way.
* ``End Site`` blocks become channel-less joints named ``<parent>_end``.
* Y-up or Z-up, in metres, centimetres, millimetres, inches or Acclaim units — either
  given explicitly (``up_axis=``, ``units=``) or detected from the motion:

  - **Up axis**: the median of ``head - mean(ankles)`` (joints found by
    :func:`retrieval.motion.body.canonical_joint_map`) over up to 64 frames; whichever of Y
    and Z has the larger component is up. Frames are used, not the rest pose, because
    some converters (Character Creator's ``CC_Base`` rigs) have a rest pose that is not
    standing. Without a head or ankles the axis (Y or Z) of the largest extent is used.
    X-up files must be given ``up_axis`` explicitly (the model supports only Y and Z).
  - **Units**: the body's stature (90th percentile over frames of the joints' extent
    along the up axis) is compared with 1.7 m; the unit among metres, centimetres,
    millimetres, inches and Acclaim units (1/0.45 inch, used by CMU's own BVH
    conversions) whose stature is closest in ratio wins. Neighbouring candidates
    differ by at least 2.2x, so any real adult or child height (1.15–2.5 m) resolves.

* A leading T-pose frame added by converters: frame 0 is called a T-pose when its
  root-relative joint positions differ from frame 1 by more than 10x the median
  frame-to-frame change of the following frames *and* by more than 2 % of the stature
  (a real first frame moves like the rest). With ``drop_tpose=True`` (default) it is
  removed. ``detect_tpose`` exposes the test.
* ``Frame Time`` values like ``0.016667`` are snapped to the whole frame rate they
  round (60 fps) when within 0.01 %.

:func:`save_bvh` writes a motion back with its skeleton, channel layout and rotation
order, so ``load_bvh(save_bvh(m))`` reproduces the joint positions (to the printed
precision). Joints whose channels the file cannot express (Acclaim joints with a folded
axis matrix) are written with their BVH-equivalent layout, which acclaim.py already sets.
"""
from __future__ import annotations

import logging
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np

from retrieval.errors import MotionFormatError
from retrieval.motion.body import canonical_joint_map
from retrieval.motion.formats.textfile import (
    MAX_DEPTH,
    MAX_FRAMES,
    MAX_JOINTS,
    check_coordinates,
    check_motion_size,
    parse_float,
    parse_floats,
    read_lines,
)
from retrieval.motion.kinematics import global_transforms
from retrieval.motion.model import Joint, Motion, Skeleton
from retrieval.motion.rotations import axis_rotation, matrix_to_euler

log = logging.getLogger(__name__)

#: Metres per file unit for the unit names ``load_bvh(units=...)`` accepts.
UNIT_SCALES: dict[str, float] = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "inch": 0.0254,
    "acclaim": 0.0254 / 0.45,
}
_UNIT_ALIASES = {"metre": "m", "meter": "m", "metres": "m", "meters": "m", "in": "inch",
                 "inches": "inch", "centimetres": "cm", "millimetres": "mm"}
#: Typical adult stature used to guess units.
TYPICAL_STATURE_M = 1.7

#: Frame rates above this can only come from a corrupt ``Frame Time``.
MAX_FPS = 100_000.0

_CHANNEL_NAMES = {f"{a}{kind}".lower(): f"{a}{kind}" for a in "XYZ" for kind in ("position", "rotation")}


# ----------------------------------------------------------------------------- reading


def load_bvh(
    path: str | Path,
    up_axis: str | None = None,
    units: str | float | None = None,
    drop_tpose: bool = True,
    root_offset: str = "auto",
) -> Motion:
    """Read a BVH file.

    ``up_axis``: "y" or "z" (None: detect). ``units``: a name from :data:`UNIT_SCALES`
    or metres per unit as a number (None: detect). ``drop_tpose``: remove a leading
    T-pose frame when :func:`detect_tpose` finds one. ``root_offset``: "auto", "add" or
    "replace" (how root position channels relate to the root OFFSET, see the module
    docstring). Malformed files raise
    :class:`MotionFormatError` naming the file and line.
    """
    path = Path(path)
    if root_offset not in ("auto", "add", "replace"):
        raise MotionFormatError(path, f"root_offset must be 'auto', 'add' or 'replace', got {root_offset!r}")
    lines = read_lines(path)
    joints, motion_line = _parse_hierarchy(path, lines)
    fps, data = _parse_motion(path, lines, motion_line, sum(len(j.channels) for j in joints), len(joints))
    position_columns = [c for c, ch in enumerate(ch for j in joints for ch in j.channels) if ch.endswith("position")]
    check_coordinates(data[:, position_columns], path, None, "position channel value")
    skeleton = Skeleton(joints, metres_per_unit=0.01, up_axis="y", name=path.stem)
    motion = _channels_to_motion(skeleton, data, fps, path.stem)

    if up_axis is not None:
        if up_axis.lower() not in ("y", "z"):
            raise MotionFormatError(path, f"up_axis must be 'y' or 'z', got {up_axis!r}")
        skeleton.up_axis = up_axis.lower()
    root = skeleton.joints[0]
    root_has_position = any(c.endswith("position") for c in root.channels)
    needs_ground = root_offset == "auto" and root_has_position and np.abs(root.offset).max() > 0
    if up_axis is None or units is None or needs_ground:
        pos = global_transforms(_sample_frames(motion))[1]
        if up_axis is None:
            skeleton.up_axis = detect_up_axis(skeleton, pos)
        stature = _stature(pos, skeleton.up_axis)
        if needs_ground:
            k = 1 if skeleton.up_axis == "y" else 2
            floor = float(np.median(pos[..., k].min(axis=1)))
            root_offset = "add" if abs(floor + root.offset[k]) < abs(floor) else "replace"
    if root_offset == "add" and root_has_position:
        motion.root_translation += root.offset
    if units is None:
        skeleton.metres_per_unit = guess_metres_per_unit(stature)
    else:
        skeleton.metres_per_unit = _units_to_scale(path, units)
    if drop_tpose and motion.n_frames >= 3 and detect_tpose(motion):
        log.info("%s: dropping leading T-pose frame", path.name)
        motion = motion.slice(1, motion.n_frames)
    return motion


def _units_to_scale(path: Path, units: str | float) -> float:
    if isinstance(units, str):
        key = _UNIT_ALIASES.get(units.lower(), units.lower())
        if key not in UNIT_SCALES:
            raise MotionFormatError(path, f"unknown units {units!r} (use one of {', '.join(UNIT_SCALES)} or a number)")
        return UNIT_SCALES[key]
    scale = float(units)
    if not np.isfinite(scale) or scale <= 0:
        raise MotionFormatError(path, f"units must be a positive number of metres, got {units!r}")
    return scale


class _Tokens:
    """The hierarchy's tokens with their line numbers, consumed front to back."""

    def __init__(self, path: Path, lines: list[str]):
        self.path = path
        self.items: list[tuple[str, int]] = []
        self.motion_line = None
        for ln, raw in enumerate(lines, 1):
            toks = raw.replace("{", " { ").replace("}", " } ").split()
            if toks and toks[0].upper() == "MOTION":
                self.motion_line = ln
                break
            self.items.extend((t, ln) for t in toks)
        self.pos = 0

    def peek(self) -> tuple[str, int]:
        if self.pos >= len(self.items):
            last = self.items[-1][1] if self.items else 1
            raise MotionFormatError(self.path, "file ends inside the HIERARCHY section (truncated?)", last)
        return self.items[self.pos]

    def take(self) -> tuple[str, int]:
        item = self.peek()
        self.pos += 1
        return item

    def expect(self, word: str) -> int:
        tok, ln = self.take()
        if tok.upper() != word.upper():
            raise MotionFormatError(self.path, f"expected {word!r}, found {tok[:40]!r}", ln)
        return ln

    def rest_of_line(self, ln: int) -> list[str]:
        out = []
        while self.pos < len(self.items) and self.items[self.pos][1] == ln and self.items[self.pos][0] != "{":
            out.append(self.items[self.pos][0])
            self.pos += 1
        return out


def _parse_hierarchy(path: Path, lines: list[str]) -> tuple[list[Joint], int]:
    """Joints (parents first) and the line number of ``MOTION``."""
    toks = _Tokens(path, lines)
    if not toks.items:
        raise MotionFormatError(path, "empty file (no HIERARCHY)")
    toks.expect("HIERARCHY")
    tok, ln = toks.take()
    if tok.upper() != "ROOT":
        raise MotionFormatError(path, f"expected 'ROOT', found {tok[:40]!r}", ln)
    joints: list[Joint] = []
    # Stack of open blocks: (joint index, is end site).
    stack: list[tuple[int, bool]] = []

    def open_block(name: str, parent: int, end_site: bool, line: int) -> None:
        if len(stack) >= MAX_DEPTH:
            raise MotionFormatError(path, f"hierarchy deeper than {MAX_DEPTH} joints", line)
        if len(joints) >= MAX_JOINTS:
            raise MotionFormatError(path, f"more than {MAX_JOINTS} joints (not a real skeleton)", line)
        toks.expect("{")
        offset, channels = _joint_body(path, toks, end_site)
        joints.append(Joint(name, parent, offset, channels, _rotation_order(channels)))
        stack.append((len(joints) - 1, end_site))

    name = " ".join(toks.rest_of_line(ln))
    if not name:
        raise MotionFormatError(path, "ROOT has no name", ln)
    open_block(name, -1, False, ln)
    while stack:
        tok, ln = toks.take()
        word = tok.upper()
        parent, parent_is_end = stack[-1]
        if word == "}":
            stack.pop()
            continue
        if parent_is_end:
            raise MotionFormatError(path, f"End Site cannot contain {tok[:40]!r}", ln)
        if word == "JOINT":
            name = " ".join(toks.rest_of_line(ln))
            if not name:
                raise MotionFormatError(path, "JOINT has no name", ln)
            open_block(name, parent, False, ln)
        elif word == "END":
            site, sln = toks.take()
            if site.upper() != "SITE":
                raise MotionFormatError(path, f"expected 'End Site', found 'End {site[:40]}'", sln)
            base = f"{joints[parent].name}_end"
            taken = {j.name for j in joints}
            name, k = base, 2
            while name in taken:
                name, k = f"{base}{k}", k + 1
            open_block(name, parent, True, ln)
        elif word == "ROOT":
            raise MotionFormatError(path, "a second ROOT inside the hierarchy", ln)
        else:
            raise MotionFormatError(path, f"unexpected {tok[:40]!r} in the hierarchy", ln)
    if toks.pos < len(toks.items):
        tok, ln = toks.items[toks.pos]
        if tok.upper() == "ROOT":
            raise MotionFormatError(path, "files with more than one ROOT are not supported", ln)
        raise MotionFormatError(path, f"unexpected {tok[:40]!r} after the hierarchy", ln)
    if toks.motion_line is None:
        raise MotionFormatError(path, "no MOTION section (truncated?)", len(lines))
    names = [j.name for j in joints]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise MotionFormatError(path, f"joint name {dup!r} used twice")
    return joints, toks.motion_line


def _joint_body(path: Path, toks: _Tokens, end_site: bool) -> tuple[np.ndarray, list[str]]:
    """OFFSET and CHANNELS of the block just opened (children are left in the stream)."""
    offset = None
    channels: list[str] = []
    while True:
        tok, ln = toks.peek()
        word = tok.upper()
        if word == "OFFSET":
            toks.take()
            vals = [toks.take() for _ in range(3)]
            offset = np.array([parse_float(t, path, l, "OFFSET value") for t, l in vals])
            check_coordinates(offset, path, vals[0][1], "OFFSET value")
        elif word == "CHANNELS":
            toks.take()
            if end_site:
                raise MotionFormatError(path, "End Site cannot have CHANNELS", ln)
            count_tok, cln = toks.take()
            if not count_tok.isdecimal():
                raise MotionFormatError(path, f"bad channel count {count_tok[:40]!r}", cln)
            count = int(count_tok)
            if count > 64:
                raise MotionFormatError(path, f"implausible channel count {count}", cln)
            for _ in range(count):
                name, nl = toks.take()
                canon = _CHANNEL_NAMES.get(name.lower())
                if canon is None:
                    raise MotionFormatError(
                        path, f"unknown channel {name[:40]!r} (CHANNELS says {count}, check the count)", nl
                    )
                if canon in channels:
                    raise MotionFormatError(path, f"channel {canon} listed twice", nl)
                channels.append(canon)
        else:
            break
    if offset is None:
        raise MotionFormatError(path, "joint has no OFFSET", ln)
    return offset, channels


def _rotation_order(channels: list[str]) -> str:
    order = "".join(c[0] for c in channels if c.endswith("rotation"))
    return order or "ZYX"


def _parse_motion(path: Path, lines: list[str], motion_line: int, n_channels: int,
                  n_joints: int = 1) -> tuple[float, np.ndarray]:
    """Frame rate and the (T, n_channels) channel values."""
    i = motion_line  # index of the line after MOTION
    header: dict[str, tuple[str, int]] = {}
    while i < len(lines) and len(header) < 2:
        s = lines[i].strip()
        i += 1
        if not s:
            continue
        key, _, value = s.partition(":")
        key = " ".join(key.lower().split())
        if key not in ("frames", "frame time"):
            raise MotionFormatError(path, f"expected 'Frames:' and 'Frame Time:', found {s[:40]!r}", i)
        header[key] = (value.strip(), i)
    for key in ("frames", "frame time"):
        if key not in header:
            raise MotionFormatError(path, f"MOTION section has no '{key.title()}:' line (truncated?)", len(lines))
    frames_text, fln = header["frames"]
    if not frames_text.isdecimal():
        raise MotionFormatError(path, f"bad frame count {frames_text[:40]!r}", fln)
    n_frames = int(frames_text)
    if n_frames == 0:
        raise MotionFormatError(path, "no frames (empty motion)", fln)
    if n_frames > MAX_FRAMES:
        raise MotionFormatError(path, f"declared frame count {n_frames} exceeds the limit of {MAX_FRAMES}", fln)
    check_motion_size(path, n_frames, n_joints, fln)
    dt_text, tln = header["frame time"]
    dt = parse_float(dt_text, path, tln, "frame time")
    if dt <= 0:
        raise MotionFormatError(path, f"frame time must be positive, got {dt_text[:40]!r}", tln)
    fps = 1.0 / dt
    if not fps <= MAX_FPS:  # also catches inf from a subnormal frame time (round(inf) raises)
        raise MotionFormatError(path, f"frame time {dt_text[:40]!r} is implausibly small (over {MAX_FPS:.0f} fps)", tln)
    if abs(fps - round(fps)) < 1e-4 * fps:
        fps = float(round(fps))

    rows: list[list[str]] = []
    row_lines: list[int] = []
    for ln in range(i + 1, len(lines) + 1):
        toks = lines[ln - 1].split()
        if not toks:
            continue
        if len(rows) == n_frames:
            log.warning("%s: ignoring data after the %d declared frames (line %d)", path.name, n_frames, ln)
            break
        if len(toks) != n_channels:
            raise MotionFormatError(path, f"expected {n_channels} channel values, found {len(toks)}", ln)
        rows.append(toks)
        row_lines.append(ln)
    if len(rows) < n_frames:
        raise MotionFormatError(
            path, f"declared {n_frames} frames but found {len(rows)} (truncated?)", len(lines)
        )
    if n_channels == 0:
        return fps, np.zeros((n_frames, 0))
    try:
        data = np.array(rows, dtype=np.float64)
    except ValueError:
        data = None
    if data is None or not np.isfinite(data).all():
        for toks, ln in zip(rows, row_lines):
            parse_floats(toks, path, ln, "channel value")
    return fps, data


def _channels_to_motion(skeleton: Skeleton, data: np.ndarray, fps: float, name: str) -> Motion:
    t = data.shape[0]
    nj = skeleton.n_joints
    rotations = np.broadcast_to(np.eye(3), (t, nj, 3, 3)).copy()
    root_translation = np.broadcast_to(skeleton.joints[0].offset, (t, 3)).copy()
    joint_translations = None
    col = 0
    for j, joint in enumerate(skeleton.joints):
        rot = None
        for ch in joint.channels:
            axis = "XYZ".index(ch[0])
            values = data[:, col]
            col += 1
            if ch.endswith("position"):
                if j == 0:
                    root_translation[:, axis] = values
                else:
                    if joint_translations is None:
                        joint_translations = np.broadcast_to(skeleton.offsets, (t, nj, 3)).copy()
                    joint_translations[:, j, axis] = values
            else:
                r = axis_rotation(ch[0], np.deg2rad(values))
                rot = r if rot is None else rot @ r
        if rot is not None:
            rotations[:, j] = rot
    return Motion(skeleton, rotations, root_translation, fps, name, joint_translations)


# ----------------------------------------------------------------------------- heuristics


def _sample_frames(motion: Motion, count: int = 64) -> Motion:
    """Up to ``count`` evenly spaced frames, skipping frame 0 (maybe a T-pose) if possible."""
    n = motion.n_frames
    start = 1 if n > 1 else 0
    idx = np.unique(np.linspace(start, n - 1, min(count, n - start)).round().astype(int))
    jt = None if motion.joint_translations is None else motion.joint_translations[idx]
    return Motion(motion.skeleton, motion.rotations[idx], motion.root_translation[idx], motion.fps, motion.name, jt)


def detect_up_axis(skeleton: Skeleton, native_positions: np.ndarray) -> str:
    """"y" or "z": the axis pointing from the ankles to the head (see module docstring).

    ``native_positions`` is (T, J, 3) in the file's axes."""
    cmap = canonical_joint_map(skeleton, required=False)
    feet = [cmap[k] for k in ("left_ankle", "right_ankle") if k in cmap]
    if "head" in cmap and feet:
        up = np.median(native_positions[:, cmap["head"]] - native_positions[:, feet].mean(axis=1), axis=0)
    else:
        up = np.median(native_positions.max(axis=1) - native_positions.min(axis=1), axis=0)
    return "y" if abs(up[1]) >= abs(up[2]) else "z"


def _stature(native_positions: np.ndarray, up_axis: str) -> float:
    k = 1 if up_axis == "y" else 2
    extent = native_positions[..., k].max(axis=1) - native_positions[..., k].min(axis=1)
    return float(np.percentile(extent, 90))


def guess_metres_per_unit(stature_native: float) -> float:
    """The :data:`UNIT_SCALES` value making ``stature_native`` closest (in ratio) to 1.7 m."""
    if not np.isfinite(stature_native) or stature_native <= 0:
        return UNIT_SCALES["cm"]
    scales = np.array(list(UNIT_SCALES.values()))
    err = np.abs(np.log(stature_native * scales / TYPICAL_STATURE_M))
    return float(scales[int(np.argmin(err))])


def detect_tpose(motion: Motion, ratio: float = 10.0, min_fraction: float = 0.02) -> bool:
    """Whether frame 0 is an inserted pose unlike the motion that follows (see module
    docstring): its change to frame 1 exceeds ``ratio`` x the median frame-to-frame change
    of frames 1..120 and ``min_fraction`` x the stature."""
    n = min(motion.n_frames, 121)
    if n < 3:
        return False
    head = motion.slice(0, n)
    pos = global_transforms(head)[1]
    rel = pos - pos[:, :1]
    step = np.linalg.norm(np.diff(rel, axis=0), axis=-1).mean(axis=1)
    stature = _stature(pos[1:], motion.skeleton.up_axis)
    typical = float(np.median(step[1:]))
    return bool(step[0] > ratio * typical and step[0] > min_fraction * stature)


# ----------------------------------------------------------------------------- writing


def save_bvh(motion: Motion, path: str | Path, decimals: int = 6) -> Path:
    """Write ``motion`` as BVH (skeleton, channel layout and rotation orders kept).

    Values are printed with ``decimals`` digits after the point (trailing zeros
    trimmed). Rotations are converted to Euler angles in each joint's channel order; a
    joint with fewer than three rotation channels is written assuming its rotation is
    expressible in them (true for anything read from such a file). The file is written
    to a temporary name and renamed, so a crash never leaves half a file.
    """
    path = Path(path)
    sk = motion.skeleton
    text = [_hierarchy_text(sk, decimals), "MOTION", f"Frames: {motion.n_frames}",
            f"Frame Time: {1.0 / motion.fps:.8f}"]
    columns = _channel_columns(motion)
    fmt = _formatter(decimals)
    body = "\n".join(" ".join(fmt(v) for v in row) for row in columns)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name, suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write("\n".join(text) + "\n" + body + "\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _formatter(decimals: int):
    def fmt(v: float) -> str:
        s = f"{v:.{decimals}f}"
        if "." in s:
            s = s.rstrip("0").rstrip(".")
        return "0" if s in ("-0", "") else s
    return fmt


def _written_channels(joint: Joint, has_children: bool) -> list[str]:
    if joint.channels or not has_children:
        return joint.channels
    return ["Zrotation", "Yrotation", "Xrotation"]  # a channel-less joint with children


def _children(sk: Skeleton) -> dict[int, list[int]]:
    kids: dict[int, list[int]] = {i: [] for i in range(sk.n_joints)}
    for i, j in enumerate(sk.joints):
        if j.parent >= 0:
            kids[j.parent].append(i)
    return kids


def _file_order(sk: Skeleton) -> list[int]:
    """The joints in the order the hierarchy is written (depth first), which is the order
    of the motion's columns. A skeleton need not be stored in it: a parent only has to come
    before its children, so a converted rig may list a hip before a shoulder."""
    kids, order = _children(sk), []
    stack = [0]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(kids[i]))
    return order


def _hierarchy_text(sk: Skeleton, decimals: int) -> str:
    fmt = _formatter(decimals)
    kids = _children(sk)
    out = ["HIERARCHY"]

    def emit(i: int, depth: int) -> None:
        j = sk.joints[i]
        pad = "\t" * depth
        chans = _written_channels(j, bool(kids[i]))
        if not chans and not kids[i] and i != 0:
            out.append(f"{pad}End Site")
        else:
            out.append(f"{pad}{'ROOT' if i == 0 else 'JOINT'} {j.name}")
        out.append(pad + "{")
        out.append(f"{pad}\tOFFSET " + " ".join(fmt(v) for v in j.offset))
        if chans or kids[i]:
            out.append(f"{pad}\tCHANNELS {len(chans)} " + " ".join(chans))
        for k in kids[i]:
            emit(k, depth + 1)
        out.append(pad + "}")

    emit(0, 0)
    return "\n".join(out)


def _channel_columns(motion: Motion) -> np.ndarray:
    sk = motion.skeleton
    has_kids = {j.parent for j in sk.joints}
    cols: list[np.ndarray] = []
    for j in _file_order(sk):
        joint = sk.joints[j]
        chans = _written_channels(joint, j in has_kids)
        rot_axes = "".join(c[0] for c in chans if c.endswith("rotation"))
        angles = {}
        if rot_axes:
            full = rot_axes + "".join(a for a in "XYZ" if a not in rot_axes)
            with warnings.catch_warnings():
                # At gimbal lock scipy sets the third angle to 0; the angles still
                # reproduce the matrix, which is all a writer needs.
                warnings.simplefilter("ignore", UserWarning)
                eul = matrix_to_euler(motion.rotations[:, j], full, degrees=True)
            angles = {a: eul[:, k] for k, a in enumerate(rot_axes)}
        for c in chans:
            axis = "XYZ".index(c[0])
            if c.endswith("rotation"):
                cols.append(angles[c[0]])
            elif j == 0:
                cols.append(motion.root_translation[:, axis])
            elif motion.joint_translations is not None:
                cols.append(motion.joint_translations[:, j, axis])
            else:
                cols.append(np.full(motion.n_frames, joint.offset[axis]))
    if not cols:
        return np.zeros((motion.n_frames, 0))
    return np.stack(cols, axis=1)
