"""The profile's last good copy: written while the profile is healthy, put back when it is
damaged, never treated as a fresh install.

Method. One copy, ``<profile>.db.backup`` beside the database, replaced ("rotated") as a
whole by :func:`write_backup`: the live database is checked (``PRAGMA quick_check``) and
only a database that passes is copied; the copy is SQLite's own image of the database
(:meth:`sqlite3.Connection.serialize`: every committed page, the WAL's included; marked
as a rollback-journal file, which a lone copy must be to open) written
through the durable write (:func:`~app.story.storage.database.atomic_write`: temporary
file, ``fsync``, ``os.replace``, folder ``fsync``), so a crash while it is written leaves
the previous copy whole. The store writes it when it opens, after every change of the
teacher PIN, and when it closes (skipped when the bytes are those already there).

:func:`read_backup` checks a copy without touching it (deserialised into memory: the
StoryBeam header, the schema version, ``quick_check``) and says what it holds (stories,
a PIN, when it was saved); :func:`restore_backup` moves the damaged database (with its
``-wal`` and ``-shm``) aside under a dated name -- it is kept, never deleted -- and puts
the copy in its place: the stories *and* the teacher PIN come back.
"""
from __future__ import annotations

import datetime as _dt
import os
import sqlite3
from dataclasses import dataclass
from pathlib import Path

from app.story.storage.database import (
    APPLICATION_ID,
    SCHEMA_VERSION,
    SQLITE_HEADER,
    ProfileDatabase,
    StorageError,
    as_storage_error,
    atomic_write,
    os_problem,
)
from retrieval.durable import fsync_dir

BACKUP_SUFFIX = ".backup"
#: The damaged file is kept as ``<profile>.db.damaged-YYYYmmdd-HHMMSS`` (and its -wal, -shm).
DAMAGED_INFIX = ".damaged-"


def backup_path(db_path: Path) -> Path:
    """Where the last good copy of the profile ``db_path`` is kept."""
    return db_path.with_name(db_path.name + BACKUP_SUFFIX)


def write_backup(db: ProfileDatabase) -> bool:
    """Copy the open profile to :func:`backup_path` if it passes ``quick_check``; returns
    whether a new copy was written (False: damaged now, or the copy is already this one)."""
    with as_storage_error(db.db_path, "no backup made"):
        if db.conn.execute("PRAGMA quick_check").fetchone()[0] != "ok":
            return False
        image = _rollback_image(db.conn.serialize())
    target = backup_path(db.db_path)
    try:
        if target.is_file() and target.stat().st_size == len(image) and target.read_bytes() == image:
            return False
    except OSError:
        pass  # unreadable: write it again
    atomic_write(target, image)
    return True


def _rollback_image(image: bytes) -> bytes:
    """The image with its header's file-format bytes (offsets 18, 19) set from 2 (WAL) to 1
    (rollback journal): the image already holds every committed page, and SQLite cannot
    read a WAL-mode image without its ``-wal`` file (deserialised or copied alone); the
    store switches a restored file back to WAL when it opens it."""
    if image[18:20] == b"\x02\x02":
        return image[:18] + b"\x01\x01" + image[20:]
    return image


@dataclass(frozen=True)
class BackupInfo:
    """A good copy: its file, when it was saved (seconds since the epoch, the file's time),
    how many stories it holds and whether it carries a teacher PIN."""

    path: Path
    saved: float
    stories: int
    has_pin: bool

    def saved_text(self) -> str:
        """When it was saved, as the teacher reads it (local time, to the minute)."""
        return _dt.datetime.fromtimestamp(self.saved).strftime("%Y-%m-%d %H:%M")


def backup_settings(db_path: Path, keys: tuple[str, ...]) -> dict[str, str]:
    """The settings ``keys`` as the good copy of ``db_path`` holds them (those it has; none
    when there is no good copy): how a profile opened in place of a damaged one keeps the
    teacher's PIN."""
    if read_backup(db_path) is None:
        return {}
    conn = sqlite3.connect(":memory:")
    try:
        conn.deserialize(backup_path(db_path).read_bytes())
        marks = ",".join("?" * len(keys))
        rows = conn.execute(f"SELECT key, value FROM settings WHERE key IN ({marks})", keys).fetchall()
    except (OSError, sqlite3.Error, UnicodeDecodeError):
        return {}
    finally:
        conn.close()
    return dict(rows)


def read_backup(db_path: Path) -> BackupInfo | None:
    """The good copy of profile ``db_path``, checked in memory; None when there is none or
    it is not a whole StoryBeam profile itself."""
    path = backup_path(db_path)
    try:
        image = path.read_bytes()
        saved = path.stat().st_mtime
    except OSError:
        return None
    if not image.startswith(SQLITE_HEADER):
        return None
    conn = sqlite3.connect(":memory:")
    try:
        conn.deserialize(image)
        app_id = conn.execute("PRAGMA application_id").fetchone()[0]
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        if app_id != APPLICATION_ID or not 1 <= version <= SCHEMA_VERSION:
            return None
        if conn.execute("PRAGMA quick_check").fetchone()[0] != "ok":
            return None
        stories = conn.execute("SELECT count(*) FROM stories").fetchone()[0]
        has_pin = version >= 2 and conn.execute(
            "SELECT count(*) FROM settings WHERE key = 'teacher_pin'").fetchone()[0] > 0
    except (sqlite3.Error, UnicodeDecodeError):
        return None
    finally:
        conn.close()
    return BackupInfo(path, saved, int(stories), bool(has_pin))


def restore_backup(db_path: Path, now: _dt.datetime | None = None) -> Path:
    """Put the good copy back in place of the damaged profile ``db_path``; returns where the
    damaged file was moved (kept, with its ``-wal``/``-shm``). A :class:`StorageError`
    when there is no good copy (nothing is moved then)."""
    info = read_backup(db_path)
    if info is None:
        raise StorageError(f"{backup_path(db_path)}: no good copy of the profile to put back")
    image = info.path.read_bytes()
    stamp = (now or _dt.datetime.now()).strftime("%Y%m%d-%H%M%S")
    kept = db_path.with_name(f"{db_path.name}{DAMAGED_INFIX}{stamp}")
    n = 1
    while kept.exists():
        n += 1
        kept = db_path.with_name(f"{db_path.name}{DAMAGED_INFIX}{stamp}-{n}")
    try:
        for suffix in ("", "-wal", "-shm"):  # the WAL belongs to the damaged file: it goes with it
            part = Path(str(db_path) + suffix)
            if part.exists():
                os.replace(part, Path(str(kept) + suffix))
        fsync_dir(db_path.parent)
    except OSError as exc:
        raise StorageError(f"{db_path}: the damaged profile could not be moved aside ({os_problem(exc)})") from None
    atomic_write(db_path, image)
    return kept


__all__ = ["BACKUP_SUFFIX", "DAMAGED_INFIX", "BackupInfo", "backup_path", "write_backup", "read_backup",
           "backup_settings", "restore_backup"]
