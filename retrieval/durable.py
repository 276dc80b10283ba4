"""Durable file writes: after a call returns, the file survives a power cut.

The one way StoryBeam writes a file outside SQLite (calibration, story assets, story
packages, the activity CSV). Method, for a file ``dir/name``:

1. create a temporary file in the *same* folder (``dir/.name.XXXX.tmp``: same file
   system, so the rename below is atomic), write the bytes, ``flush``, ``fsync``;
2. ``os.replace`` it over ``dir/name``;
3. ``fsync`` the folder, so the rename itself (a directory entry) is on disk.

Why each step: without the temporary file a crash during the write truncates the old
file in place (an empty ``camera.json``); without the file ``fsync`` the rename can reach
the disk before the data (a file of the right name full of zeros); without the folder
``fsync`` the rename can be lost (POSIX leaves directory entries unordered), so the file
the app reported as saved is missing after the cut. Folders are made with
:func:`make_dirs`, which fsyncs the parent of every folder it creates, for the same
reason. On any error the temporary file is removed and the old file is untouched.

A crash between steps 1 and 2 can leave a temporary file behind; :func:`clean_temporaries`
removes them (the profile store calls it when it opens; a durable write removes the
stale temporaries of its own target first). ``tests/robust/test_power_loss.py`` and
``storybeam stress power-loss`` check all of this by replaying the real process's
recorded system calls onto simulated post-crash disks.

Standard library only, no StoryBeam imports: the lowest layer, so both the rig's
calibration (:mod:`ar.calibration`) and the story store (:mod:`app.story.storage`) use it.
"""
from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import BinaryIO, Iterator

#: Suffix of every temporary file made here (``.<name>.<random>.tmp``).
TEMP_SUFFIX = ".tmp"


def fsync_dir(folder: str | Path) -> None:
    """``fsync`` a folder, making the directory entries in it (creates, renames,
    deletes) durable. A no-op where folders cannot be opened (Windows)."""
    if os.name == "nt":  # Windows has no directory fsync (tested by faking os.name)
        return
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_file(path: str | Path) -> None:
    """``fsync`` a file written by someone else (an encoder, a library): its data reach
    the disk before it is renamed into place with :func:`durable_move`."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def make_dirs(folder: str | Path) -> Path:
    """``mkdir -p`` that fsyncs the parent of every folder it creates (the new entry
    lives in the parent); returns the folder."""
    folder = Path(folder)
    missing = []
    probe = folder
    while not probe.is_dir():  # stops at the latest at "/" or "."
        missing.append(probe)
        probe = probe.parent
    for path in reversed(missing):
        path.mkdir(exist_ok=True)  # FileExistsError when a file is in the way
        fsync_dir(path.parent)
    return folder


def _temp_prefix(path: Path) -> str:
    return f".{path.name}."


def clean_temporaries(folder: str | Path, recursive: bool = False) -> list[Path]:
    """Remove the temporary files a crash left in ``folder`` (and below it with
    ``recursive``); returns what was removed. Removal is not fsynced: a leftover that
    comes back after another cut is removed the next time."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    removed = []
    pattern = "**/.*" + TEMP_SUFFIX if recursive else ".*" + TEMP_SUFFIX
    for path in sorted(folder.glob(pattern)):
        if path.is_file() and not path.is_symlink():
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
                removed.append(path)
    return removed


@contextlib.contextmanager
def durable_file(path: str | Path) -> Iterator[BinaryIO]:
    """Open a temporary file beside ``path`` for writing (binary); when the ``with``
    block ends without an exception, make it durable and put it in place atomically
    (steps 1-3 of the module docstring). On any exception the temporary file is removed,
    ``path`` is left as it was, and the exception propagates."""
    path = Path(path)
    make_dirs(path.parent)
    own = re.compile(re.escape(_temp_prefix(path)) + r"[A-Za-z0-9_]{8}" + re.escape(TEMP_SUFFIX))
    for stale in path.parent.iterdir():
        if own.fullmatch(stale.name):  # left by a crash during an earlier write
            with contextlib.suppress(OSError):  # (a folder of that name stays)
                stale.unlink()
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=_temp_prefix(path), suffix=TEMP_SUFFIX)
    try:
        with os.fdopen(fd, "wb") as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    fsync_dir(path.parent)


def durable_write(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` durably and atomically (a crash leaves the old file or
    the new one, and after return the new one survives a power cut); returns the path."""
    path = Path(path)
    with durable_file(path) as fh:
        fh.write(data)
    return path


def durable_move(src: str | Path, dst: str | Path) -> Path:
    """``os.replace(src, dst)`` (a file or a folder, same file system), then fsync the
    destination's folder and, if different, the source's; returns ``dst``."""
    src, dst = Path(src), Path(dst)
    os.replace(src, dst)
    fsync_dir(dst.parent)
    if src.parent.resolve() != dst.parent.resolve():
        fsync_dir(src.parent)
    return dst


def durable_tree(folder: str | Path) -> Path:
    """fsync every file and folder under ``folder`` (and ``folder`` itself): written
    with plain writes, after this the whole tree survives a power cut once it is linked
    into a durable folder (e.g. by :func:`durable_move`)."""
    folder = Path(folder)
    for root, _dirs, files in os.walk(folder, topdown=False):
        for name in files:
            fsync_file(os.path.join(root, name))
        fsync_dir(root)
    return folder


def remove_tree(folder: str | Path) -> None:
    """Remove a folder and everything in it (missing is fine), then fsync its parent."""
    folder = Path(folder)
    if not folder.exists():
        return
    shutil.rmtree(folder, ignore_errors=True)
    with contextlib.suppress(OSError):
        fsync_dir(folder.parent)


__all__ = ["TEMP_SUFFIX", "fsync_dir", "fsync_file", "make_dirs", "clean_temporaries", "durable_file", "durable_write",
           "durable_move", "durable_tree", "remove_tree"]
