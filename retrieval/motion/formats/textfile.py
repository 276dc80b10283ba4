"""Reading motion text files safely: one place for the size limit, decoding and number
parsing, so every parser reports bad input as :class:`MotionFormatError` with the file
and the line, never as a ``UnicodeDecodeError`` or ``ValueError`` from deep inside.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from retrieval.errors import MotionFormatError

#: Files larger than this are refused before reading. The biggest real mocap take is a
#: few MB (CMU's largest AMC: 3.7 MB); parsing costs about 13x the file size in peak
#: memory (measured: a 60 MB BVH peaks at 770 MB RSS), so 64 MB keeps a worst case
#: under 1 GB on a phone (docs/notebook/reliability.md).
MAX_FILE_BYTES = 64 * 1024 * 1024
#: More frames than this (about 46 hours at 60 fps) can only be a corrupt header.
MAX_FRAMES = 10_000_000
#: Deeper hierarchies than this are corrupt (real skeletons are < 30 deep).
MAX_DEPTH = 256
#: Largest coordinate (offset, bone length, translation) in file units. 1e9 is 1000 km
#: in millimetres; beyond it sums of offsets overflow to inf in forward kinematics
#: (found by fuzzing: OFFSET 1e308 loaded, then joint positions were inf).
MAX_COORDINATE = 1e9


def check_coordinates(values, path: str | Path, line: int | None, what: str) -> None:
    """Refuse coordinates beyond :data:`MAX_COORDINATE` (see there)."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.size and float(np.abs(arr).max()) > MAX_COORDINATE:
        raise MotionFormatError(path, f"{what} {float(np.abs(arr).max()):g} is implausibly large "
                                      f"(limit {MAX_COORDINATE:g} file units)", line)


#: More joints (BVH) or bones (ASF) than this are corrupt (real skeletons have < 200).
MAX_JOINTS = 4096
#: Frames x joints of a decoded motion (one 3x3 float64 rotation each, 72 bytes): 8
#: million is 576 MB, far above a real take (10 min at 120 fps x 38 joints = 2.7 M).
#: Without it a tiny file (thousands of channel-less joints, one value per frame)
#: asks for tens of GB.
MAX_FRAME_JOINTS = 8_000_000


def check_motion_size(path: str | Path, n_frames: int, n_joints: int, line: int | None = None) -> None:
    """Refuse a motion whose decoded arrays would exceed :data:`MAX_FRAME_JOINTS`."""
    if n_frames * n_joints > MAX_FRAME_JOINTS:
        raise MotionFormatError(
            path, f"{n_frames} frames x {n_joints} joints is more than the limit of {MAX_FRAME_JOINTS:,} "
                  "joint poses (file too large to load)", line)


def read_lines(path: str | Path) -> list[str]:
    """The file's lines (line endings stripped), refusing huge and non-UTF-8 files."""
    path = Path(path)
    try:
        size = os.path.getsize(path)
    except OSError as exc:
        raise MotionFormatError(path, f"cannot read file: {exc.strerror or exc}") from None
    if size > MAX_FILE_BYTES:
        raise MotionFormatError(
            path, f"file is {size / 2**20:.0f} MB, more than the {MAX_FILE_BYTES // 2**20} MB limit"
        )
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise MotionFormatError(path, f"cannot read file: {exc.strerror or exc}") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = _decode_by_line(data, path)
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise MotionFormatError(path, "not a text motion file (contains NUL bytes)", line)
    return text.splitlines()


def _decode_by_line(data: bytes, path: str | Path) -> str:
    """``data`` that is not all UTF-8, line by line: a comment line (``#`` first) that is not
    UTF-8 is read as Latin-1 (Vicon writes the capture folder's name there: HDM05's AMC files
    begin ``#!OML:ASF X:\\für Bonn\\...`` in Latin-1); any other line that is not UTF-8
    raises :class:`MotionFormatError` naming it and its first bad byte."""
    lines = data.removeprefix(b"\xef\xbb\xbf").split(b"\n")
    out = []
    for n, raw in enumerate(lines, start=1):
        try:
            out.append(raw.decode("utf-8"))
        except UnicodeDecodeError as exc:
            if not raw.lstrip().startswith(b"#"):
                raise MotionFormatError(
                    path, f"not a text motion file (byte 0x{raw[exc.start]:02x} is not UTF-8)", n
                ) from None
            out.append(raw.decode("latin-1"))
    return "\n".join(out)


def parse_float(token: str, path: str | Path, line: int, what: str = "number") -> float:
    """``float(token)``, requiring a finite value; errors name the file and line."""
    try:
        value = float(token)
    except ValueError:
        raise MotionFormatError(path, f"bad {what} {token[:40]!r}", line) from None
    if not math.isfinite(value):
        raise MotionFormatError(path, f"{what} is not finite ({token[:40]!r})", line)
    return value


def parse_floats(tokens: list[str], path: str | Path, line: int, what: str = "number") -> list[float]:
    """Every token as a finite float (see :func:`parse_float`)."""
    return [parse_float(t, path, line, what) for t in tokens]
