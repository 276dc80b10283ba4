"""The profile's SQLite database: opening, checking, migrating, transactions, durable files.

One SQLite database per device profile (stdlib :mod:`sqlite3`). Why these settings:

* **WAL journal + ``synchronous=FULL``.** The app saves after *every* edit (a child may
  pull the battery at any moment). In WAL mode a commit is one append to the ``-wal``
  file, so a crash or power cut leaves either the old or the new story, never a mix.
  ``NORMAL`` would also never corrupt the database under WAL, but could lose the last
  few commits on power loss; our writes are tiny (a story is a few kB), so the extra
  fsync per commit of ``FULL`` is cheap and we keep the child's last stroke.
* **Explicit transactions** (``BEGIN IMMEDIATE`` ... ``COMMIT``) around every write, so a
  multi-row change (a package import, a migration) is all-or-nothing.
* **Schema versioning** with ``PRAGMA user_version`` and a list of migrations applied in
  one transaction each; ``PRAGMA application_id`` marks the file as ours so a foreign
  SQLite file is refused instead of being "migrated".

Files beside the database (assets, the activity CSV) are written with
:func:`atomic_write` (:func:`retrieval.durable.durable_write`). Every problem a user can
cause raises :class:`StorageError` with the file name and the problem.
"""
from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path
from typing import Iterator

from retrieval.durable import durable_write, make_dirs
from retrieval.errors import StoryBeamError

#: 'SBm1' - marks a database as a StoryBeam profile.
APPLICATION_ID = 0x53426D31
SQLITE_HEADER = b"SQLite format 3\x00"

#: Each entry upgrades the schema from version i to i+1 (index 0: empty -> 1).
MIGRATIONS: list[tuple[str, ...]] = [
    (  # 1: stories only (first release)
        """CREATE TABLE stories (
               id TEXT PRIMARY KEY,
               title TEXT NOT NULL,
               body TEXT NOT NULL,
               modified REAL NOT NULL)""",
    ),
    (  # 2: summary columns for the home screen, teacher mode, activity log
        "ALTER TABLE stories ADD COLUMN arc TEXT NOT NULL DEFAULT 'short'",
        "ALTER TABLE stories ADD COLUMN scene_count INTEGER NOT NULL DEFAULT 0",
        "ALTER TABLE stories ADD COLUMN created REAL NOT NULL DEFAULT 0",
        """UPDATE stories SET
               arc = COALESCE(json_extract(body, '$.arc'), 'short'),
               scene_count = COALESCE(json_array_length(body, '$.scenes'), 0),
               created = modified
           WHERE json_valid(body)""",
        "CREATE TABLE settings (key TEXT PRIMARY KEY, value TEXT NOT NULL)",
        """CREATE TABLE class_sessions (
               id INTEGER PRIMARY KEY AUTOINCREMENT,
               name TEXT NOT NULL,
               created REAL NOT NULL)""",
        """CREATE TABLE groups (
               id INTEGER PRIMARY KEY AUTOINCREMENT,
               session_id INTEGER NOT NULL REFERENCES class_sessions(id) ON DELETE CASCADE,
               name TEXT NOT NULL,
               members TEXT NOT NULL)""",
        """CREATE TABLE activity (
               id INTEGER PRIMARY KEY AUTOINCREMENT,
               at REAL NOT NULL,
               event TEXT NOT NULL,
               story_id TEXT,
               detail TEXT NOT NULL DEFAULT '')""",
    ),
    (  # 3: the bin (issue 29): a deleted story keeps its row and assets until the teacher empties the bin
        "ALTER TABLE stories ADD COLUMN binned REAL",
    ),
]
SCHEMA_VERSION = len(MIGRATIONS)


class StorageError(StoryBeamError):
    """The profile database, an asset or a story package cannot be used."""


def sqlite_problem(exc: BaseException) -> str:
    """A user-facing reason for an SQLite failure (a full disk is not "damage")."""
    name = getattr(exc, "sqlite_errorname", "")
    if name == "SQLITE_FULL" or "disk is full" in str(exc) or isinstance(exc, OSError) and exc.errno in (28, 27):
        return "the device storage is full; free some space (stories saved before are kept)"
    if name in ("SQLITE_READONLY", "SQLITE_PERM", "SQLITE_CANTOPEN"):
        return f"the file cannot be written ({exc})"
    if name == "SQLITE_IOERR" or name.startswith("SQLITE_IOERR"):
        return f"the storage reported an input/output error ({exc})"
    return f"the database is damaged ({exc})"


@contextlib.contextmanager
def as_storage_error(where: Path, action: str) -> Iterator[None]:
    """Turn SQLite (and undecodable-text) failures into :class:`StorageError`, so a damaged
    file or a full disk reaches the user as a message instead of a traceback. Found by
    the robustness campaign (tests/test_robust_storage.py): corrupted pages raised
    ``sqlite3.OperationalError``/``UnicodeDecodeError`` from reads, a full disk raised
    ``sqlite3.OperationalError`` from saves."""
    try:
        yield
    except (sqlite3.Error, UnicodeDecodeError) as exc:
        raise StorageError(f"{where}: {action}: {sqlite_problem(exc)}") from None


def atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` durably (:func:`retrieval.durable.durable_write`: a crash
    or power cut leaves the old file or the new one, and after return the new one)."""
    try:
        durable_write(path, data)
    except OSError as exc:
        raise StorageError(f"{path}: not saved ({os_problem(exc)})") from None


def os_problem(exc: OSError) -> str:
    """A user-facing reason for a failed file write."""
    if exc.errno in (28, 27):  # ENOSPC, EFBIG
        return "the device storage is full; free some space"
    if exc.errno in (13, 1, 30):  # EACCES, EPERM, EROFS
        return f"the folder cannot be written: {exc.strerror}"
    return f"{exc.strerror or exc}"


class ProfileDatabase:
    """The open SQLite connection of one profile: checked, configured (WAL,
    ``synchronous=FULL``, foreign keys) and migrated to :data:`SCHEMA_VERSION` on opening;
    every write goes through :meth:`transaction`."""

    def __init__(self, db_path: Path):
        self.db_path = db_path
        self.conn = self._open()

    def _open(self) -> sqlite3.Connection:
        path = self.db_path
        if path.is_dir():
            raise StorageError(f"{path}: is a folder, not a StoryBeam database")
        if path.exists() and path.stat().st_size > 0:
            with open(path, "rb") as fh:
                if fh.read(16) != SQLITE_HEADER:
                    raise StorageError(f"{path}: not a StoryBeam database (not an SQLite file, or its header is damaged)")
        make_dirs(path.parent)
        with as_storage_error(path, "cannot open"):
            conn = sqlite3.connect(str(path), isolation_level=None, timeout=5.0)
        try:
            self._configure_and_check(conn)
            self._migrate(conn)
        except (sqlite3.Error, UnicodeDecodeError) as exc:
            conn.close()
            raise StorageError(f"{path}: {sqlite_problem(exc)}") from None
        except StorageError:
            conn.close()
            raise
        return conn

    def _configure_and_check(self, conn: sqlite3.Connection) -> None:
        path = self.db_path
        app_id = conn.execute("PRAGMA application_id").fetchone()[0]
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        tables = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
        if app_id != APPLICATION_ID and (app_id != 0 or version != 0 or tables != 0):
            raise StorageError(f"{path}: not a StoryBeam database (an SQLite file from another program)")
        if version < 0:  # a damaged header (found by the corruption campaign: IndexError in _migrate)
            raise StorageError(f"{path}: the database is damaged (schema version {version})")
        if version > SCHEMA_VERSION:
            raise StorageError(f"{path}: made by a newer StoryBeam (schema {version}, this app knows up to {SCHEMA_VERSION})")
        check = conn.execute("PRAGMA quick_check").fetchone()[0]
        if check != "ok":
            raise StorageError(f"{path}: the database is damaged ({check})")
        mode = conn.execute("PRAGMA journal_mode=WAL").fetchone()[0]
        if mode.lower() != "wal":
            raise StorageError(f"{path}: could not switch to write-ahead logging (journal mode {mode})")
        conn.execute("PRAGMA synchronous=FULL")
        conn.execute("PRAGMA foreign_keys=ON")

    def _migrate(self, conn: sqlite3.Connection) -> None:
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        for target in range(version + 1, SCHEMA_VERSION + 1):
            conn.execute("BEGIN IMMEDIATE")
            try:
                for statement in MIGRATIONS[target - 1]:
                    conn.execute(statement)
                conn.execute(f"PRAGMA application_id={APPLICATION_ID}")
                conn.execute(f"PRAGMA user_version={target}")
                conn.execute("COMMIT")
            except BaseException as exc:
                conn.execute("ROLLBACK")
                if isinstance(exc, sqlite3.Error):  # say what failed: the stories are untouched
                    raise StorageError(f"{self.db_path}: could not upgrade the profile to schema {target} "
                                       f"({exc}); it was left as it was") from None
                raise

    @property
    def schema_version(self) -> int:
        return self.conn.execute("PRAGMA user_version").fetchone()[0]

    @property
    def journal_mode(self) -> str:
        return self.conn.execute("PRAGMA journal_mode").fetchone()[0]

    @contextlib.contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """``BEGIN IMMEDIATE`` ... ``COMMIT`` around the block; on any failure (the COMMIT's
        too) a ROLLBACK, and SQLite failures become :class:`StorageError` ("not saved")."""
        conn = self.conn
        with as_storage_error(self.db_path, "not saved"):
            conn.execute("BEGIN IMMEDIATE")
            try:
                yield conn
                conn.execute("COMMIT")  # inside the try: a COMMIT can fail too (disk full)
            except BaseException:
                if conn.in_transaction:  # SQLite's advice after SQLITE_FULL/IOERR
                    with contextlib.suppress(sqlite3.Error):
                        conn.execute("ROLLBACK")
                raise

    def close(self) -> None:
        """Close the connection (checkpointing the WAL into the main file)."""
        if self.conn is not None:
            self.conn.close()
            self.conn = None  # type: ignore[assignment]
