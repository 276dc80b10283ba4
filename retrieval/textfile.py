"""Reading motion text files safely: one place for the size limit, decoding and number
parsing, so every parser reports bad input as :class:`MotionFormatError` with the file
and the line, never as a ``UnicodeDecodeError`` or ``ValueError`` from deep inside.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

from .errors import MotionFormatError

#: Files larger than this are refused before reading: the biggest real mocap take is a
#: few tens of MB, and a multi-GB file would exhaust a phone's memory.
MAX_FILE_BYTES = 512 * 1024 * 1024
#: More frames than this (about 46 hours at 60 fps) can only be a corrupt header.
MAX_FRAMES = 10_000_000
#: Deeper hierarchies than this are corrupt (real skeletons are < 30 deep).
MAX_DEPTH = 256


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
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise MotionFormatError(
            path, f"not a text motion file (byte 0x{data[exc.start]:02x} is not UTF-8)", line
        ) from None
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise MotionFormatError(path, "not a text motion file (contains NUL bytes)", line)
    return text.splitlines()


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
