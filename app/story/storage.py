"""Crash-safe storage of one device profile: stories, teacher data and the activity log.

One SQLite database per device profile (stdlib :mod:`sqlite3`), with the story assets
(custom backgrounds, thumbnails) in a folder beside it (``<name>.assets/``).

Why these settings:

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

Every problem a user can cause (a damaged file, a foreign file, a bad package) raises
:class:`StorageError` with the file name and the problem; the store stays usable for
everything that is not affected.
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import hmac
import json
import math
import os
import re
import secrets
import shutil
import sqlite3
import tempfile
import time
import zipfile
import zlib
from lzma import LZMAError
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from app.story.model import Story, StoryError, new_id
from app.story.narration import ASSET_PREFIX, NarrationError, check_package_narrations, referenced_assets
from retrieval.durable import clean_temporaries, durable_file, durable_move, durable_tree, durable_write, make_dirs
from retrieval.durable import remove_tree
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
]
SCHEMA_VERSION = len(MIGRATIONS)

# Story package limits: checked before anything is written.
PACKAGE_FORMAT_NAME = "storybeam.package"
PACKAGE_FORMAT_VERSION = 1
MAX_PACKAGE_BYTES = 64 * 1024 * 1024
MAX_PACKAGE_ENTRIES = 200
MAX_ENTRY_BYTES = 16 * 1024 * 1024
MAX_UNCOMPRESSED_BYTES = 96 * 1024 * 1024
_ASSET_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")

# Teacher PIN hashing (hashlib.pbkdf2_hmac, random salt; parameters stored with the hash).
PIN_ITERATIONS = 200_000
_PIN_PATTERN = re.compile(r"^[0-9]{4,8}$")
# Wrong PINs are slowed down (see :func:`pin_delay_after`); the state is kept in the
# profile, so closing the app does not reset it.
PIN_FREE_ATTEMPTS = 4
PIN_FIRST_DELAY_S = 30.0
PIN_DELAY_DOUBLES_EVERY = 5
PIN_MAX_DELAY_S = 15 * 60.0
#: Digits of the recovery code shown once when a PIN is set (10**12 codes: not guessable by tapping).
RECOVERY_CODE_DIGITS = 12
_RECOVERY_PATTERN = re.compile(rf"^[0-9]{{{RECOVERY_CODE_DIGITS}}}$")


def pin_delay_after(failures: int) -> float:
    """Seconds to wait before the next PIN try after ``failures`` wrong ones in a row.

    The first :data:`PIN_FREE_ATTEMPTS` (4) are free (a teacher mistypes); from the 5th,
    30 s, doubling every 5 failures, at most 15 minutes (phones do the same: Android waits
    30 s after 5 failures). So failures 5-9 wait 30 s each, 10-14 60 s, 15-19 120 s, and
    the 20th wrong PIN in a row can be typed no earlier than
    ``5·30 + 5·60 + 5·120 = 1 050 s`` (17.5 minutes) after the first.
    """
    if failures <= PIN_FREE_ATTEMPTS:
        return 0.0
    doublings = min((failures - PIN_FREE_ATTEMPTS - 1) // PIN_DELAY_DOUBLES_EVERY, 32)
    return min(PIN_FIRST_DELAY_S * 2.0 ** doublings, PIN_MAX_DELAY_S)


def valid_pin(pin: object) -> bool:
    """Whether ``pin`` has the form of a teacher PIN (4 to 8 digits)."""
    return isinstance(pin, str) and _PIN_PATTERN.match(pin) is not None


@dataclass(frozen=True)
class PinCheck:
    """The answer to one PIN (or recovery code) try.

    ``ok``: it matched. ``refused``: it was not even checked, because the wait after the
    last wrong tries is not over. ``wait_s``: seconds before the next try is accepted.
    ``failures``: wrong tries in a row so far.
    """

    ok: bool
    refused: bool
    wait_s: float
    failures: int


MAX_NAME_CHARS = 40


class StorageError(StoryBeamError):
    """The profile database, an asset or a story package cannot be used."""


@dataclass(frozen=True)
class StorySummary:
    """What the home screen shows for a saved story, without parsing its body."""

    id: str
    title: str
    arc: str
    scene_count: int
    modified: float


@dataclass(frozen=True)
class Group:
    id: int
    session_id: int
    name: str
    members: tuple[str, ...]


def _check_asset_name(name: str, where: str) -> None:
    if not isinstance(name, str) or not _ASSET_NAME.match(name) or ".." in name:
        raise StorageError(f"{where}: unsafe asset name {name!r}")


def _check_person_name(name: str, where: str) -> str:
    name = name.strip() if isinstance(name, str) else ""
    if not name or len(name) > MAX_NAME_CHARS or not all(ch.isprintable() for ch in name):
        raise StorageError(f"{where}: a name must be 1-{MAX_NAME_CHARS} printable characters, got {name!r}")
    return name


def _sqlite_problem(exc: BaseException) -> str:
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
def _as_storage_error(where: Path, action: str) -> Iterator[None]:
    """Turn SQLite (and undecodable-text) failures into :class:`StorageError`, so a damaged
    file or a full disk reaches the user as a message instead of a traceback. Found by
    the robustness campaign (tests/test_robust_storage.py): corrupted pages raised
    ``sqlite3.OperationalError``/``UnicodeDecodeError`` from reads, a full disk raised
    ``sqlite3.OperationalError`` from saves."""
    try:
        yield
    except (sqlite3.Error, UnicodeDecodeError) as exc:
        raise StorageError(f"{where}: {action}: {_sqlite_problem(exc)}") from None


def _atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` durably (:func:`retrieval.durable.durable_write`: a crash
    or power cut leaves the old file or the new one, and after return the new one)."""
    try:
        durable_write(path, data)
    except OSError as exc:
        raise StorageError(f"{path}: not saved ({_os_problem(exc)})") from None


def _os_problem(exc: OSError) -> str:
    """A user-facing reason for a failed file write."""
    if exc.errno in (28, 27):  # ENOSPC, EFBIG
        return "the device storage is full; free some space"
    if exc.errno in (13, 1, 30):  # EACCES, EPERM, EROFS
        return f"the folder cannot be written: {exc.strerror}"
    return f"{exc.strerror or exc}"


class ProfileStore:
    """One device profile: a SQLite database plus an assets folder beside it."""

    def __init__(self, db_path: str | Path):
        self.db_path = Path(db_path)
        self.assets_dir = self.db_path.with_name(self.db_path.name + ".assets")
        self._conn = self._open()
        self.leftovers_removed = self._clean_leftovers()

    def _clean_leftovers(self) -> int:
        """Remove what a crash can leave in the assets folder: temporary files of an
        unfinished durable write and ``.import-*`` staging folders of an unfinished
        import (their story row was never committed). Returns how many were removed."""
        if not self.assets_dir.is_dir():
            return 0
        removed = len(clean_temporaries(self.assets_dir, recursive=True))
        for staging in self.assets_dir.glob(".import-*"):
            if staging.is_dir():
                remove_tree(staging)
                removed += 1
        return removed

    # -- opening, checking and migrating ---------------------------------------------
    def _open(self) -> sqlite3.Connection:
        path = self.db_path
        if path.is_dir():
            raise StorageError(f"{path}: is a folder, not a StoryBeam database")
        if path.exists() and path.stat().st_size > 0:
            with open(path, "rb") as fh:
                if fh.read(16) != SQLITE_HEADER:
                    raise StorageError(f"{path}: not a StoryBeam database (not an SQLite file, or its header is damaged)")
        make_dirs(path.parent)
        with _as_storage_error(path, "cannot open"):
            conn = sqlite3.connect(str(path), isolation_level=None, timeout=5.0)
        try:
            self._configure_and_check(conn)
            self._migrate(conn)
        except (sqlite3.Error, UnicodeDecodeError) as exc:
            conn.close()
            raise StorageError(f"{path}: {_sqlite_problem(exc)}") from None
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
        return self._conn.execute("PRAGMA user_version").fetchone()[0]

    @property
    def journal_mode(self) -> str:
        return self._conn.execute("PRAGMA journal_mode").fetchone()[0]

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        conn = self._conn
        with _as_storage_error(self.db_path, "not saved"):
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
        """Close the database (checkpointing the WAL into the main file)."""
        if self._conn is not None:
            self._conn.close()
            self._conn = None  # type: ignore[assignment]

    def __enter__(self) -> "ProfileStore":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- stories ----------------------------------------------------------------------
    def save_story(self, story: Story) -> None:
        """Insert or replace a story (the autosave after every edit)."""
        body = json.dumps(story.to_dict(), ensure_ascii=False, separators=(",", ":"))
        now = time.time()
        with self._transaction() as conn:
            conn.execute(
                """INSERT INTO stories (id, title, body, modified, arc, scene_count, created)
                   VALUES (?, ?, ?, ?, ?, ?, ?)
                   ON CONFLICT(id) DO UPDATE SET title=excluded.title, body=excluded.body,
                       modified=excluded.modified, arc=excluded.arc, scene_count=excluded.scene_count""",
                (story.id, story.title, body, now, story.arc, len(story.scenes), now),
            )

    def load_story(self, story_id: str) -> Story:
        with _as_storage_error(self.db_path, f"story '{story_id}' cannot be read"):
            row = self._conn.execute("SELECT body FROM stories WHERE id = ?", (story_id,)).fetchone()
        if row is None:
            raise StorageError(f"{self.db_path}: no story with id '{story_id}'")
        try:
            return Story.from_dict(json.loads(row[0]))
        except (ValueError, StoryError) as exc:
            raise StorageError(f"{self.db_path}: story '{story_id}' is damaged ({exc})") from None

    def has_story(self, story_id: str) -> bool:
        with _as_storage_error(self.db_path, "stories cannot be read"):
            return self._conn.execute("SELECT 1 FROM stories WHERE id = ?", (story_id,)).fetchone() is not None

    def list_stories(self) -> list[StorySummary]:
        """Saved stories, most recently changed first (summaries only: one damaged body
        does not hide the others)."""
        with _as_storage_error(self.db_path, "the story list cannot be read"):
            rows = self._conn.execute(
                "SELECT id, title, arc, scene_count, modified FROM stories ORDER BY modified DESC, id").fetchall()
        return [StorySummary(*row) for row in rows]

    def delete_story(self, story_id: str) -> None:
        with self._transaction() as conn:
            conn.execute("DELETE FROM stories WHERE id = ?", (story_id,))
        remove_tree(self._story_assets(story_id))

    # -- assets -----------------------------------------------------------------------
    def _story_assets(self, story_id: str) -> Path:
        _check_asset_name(story_id, "story id")
        return self.assets_dir / story_id

    def put_asset(self, story_id: str, name: str, data: bytes) -> Path:
        """Store an asset file (e.g. a custom background PNG) for a story."""
        _check_asset_name(name, f"story {story_id}")
        path = self._story_assets(story_id) / name
        _atomic_write(path, data)
        return path

    def story_assets_dir(self, story_id: str) -> Path:
        """The folder of a story's assets (it may not exist yet)."""
        return self._story_assets(story_id)

    def asset_path(self, story_id: str, name: str) -> Path:
        """Where a story's asset file is (e.g. a narration, for a player that wants a path)."""
        _check_asset_name(name, f"story {story_id}")
        return self._story_assets(story_id) / name

    def asset_names(self, story_id: str) -> list[str]:
        folder = self._story_assets(story_id)
        if not folder.is_dir():
            return []
        return sorted(p.name for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))

    def read_asset(self, story_id: str, name: str) -> bytes:
        _check_asset_name(name, f"story {story_id}")
        path = self._story_assets(story_id) / name
        if not path.is_file():
            raise StorageError(f"{path}: no such asset")
        return path.read_bytes()

    # -- settings ---------------------------------------------------------------------
    def get_setting(self, key: str, default: str | None = None) -> str | None:
        with _as_storage_error(self.db_path, "settings cannot be read"):
            row = self._conn.execute("SELECT value FROM settings WHERE key = ?", (key,)).fetchone()
        return default if row is None else row[0]

    def set_setting(self, key: str, value: str) -> None:
        with self._transaction() as conn:
            conn.execute("INSERT INTO settings (key, value) VALUES (?, ?) "
                         "ON CONFLICT(key) DO UPDATE SET value = excluded.value", (key, value))

    # -- teacher PIN ------------------------------------------------------------------
    #: The clock PIN delays are measured with (seconds since the epoch, so a wait survives
    #: closing the app). Tests and the UI monkey assign their own (no real sleeps).
    pin_clock = staticmethod(time.time)

    def has_pin(self) -> bool:
        return self.get_setting("teacher_pin") is not None

    def _hash_secret(self, secret: str) -> str:
        salt = os.urandom(16)
        digest = hashlib.pbkdf2_hmac("sha256", secret.encode(), salt, PIN_ITERATIONS)
        return f"pbkdf2_sha256${PIN_ITERATIONS}${salt.hex()}${digest.hex()}"

    def _secret_matches(self, key: str, secret: str, what: str) -> bool:
        """Compare ``secret`` with the salted hash under setting ``key`` (constant time).
        A damaged record is an error that says so, not a silent "wrong PIN" forever."""
        record = self.get_setting(key)
        if record is None:
            return False
        damaged = f"{self.db_path}: the {what} record is damaged"
        parts = record.split("$")
        if len(parts) != 4:
            raise StorageError(f"{damaged} ({len(parts)} fields instead of 4); "
                               "reset the PIN with the recovery code")
        scheme, iterations, salt_hex, digest_hex = parts
        if scheme != "pbkdf2_sha256":
            raise StorageError(f"{damaged} (unknown scheme {scheme[:32]!r}); reset the PIN with the recovery code")
        try:
            rounds = int(iterations)
            salt, want = bytes.fromhex(salt_hex), bytes.fromhex(digest_hex)
            if not 1 <= rounds <= 10_000_000:
                raise ValueError(f"{rounds} iterations")
        except ValueError as exc:
            raise StorageError(f"{damaged} ({exc}); reset the PIN with the recovery code") from None
        return hmac.compare_digest(hashlib.pbkdf2_hmac("sha256", secret.encode(), salt, rounds), want)

    def _set_pin_records(self, pin: str) -> str:
        if not valid_pin(pin):
            raise StorageError("teacher PIN: must be 4 to 8 digits")
        code = "".join(secrets.choice("0123456789") for _ in range(RECOVERY_CODE_DIGITS))
        records = {"teacher_pin": self._hash_secret(pin), "teacher_recovery": self._hash_secret(code)}
        with self._transaction() as conn:  # PIN, recovery code and cleared delays: all or nothing
            for key, value in records.items():
                conn.execute("INSERT INTO settings (key, value) VALUES (?, ?) "
                             "ON CONFLICT(key) DO UPDATE SET value = excluded.value", (key, value))
            conn.execute("DELETE FROM settings WHERE key IN ('teacher_pin_attempts', 'teacher_recovery_attempts')")
        return code

    def has_recovery_code(self) -> bool:
        return self.get_setting("teacher_recovery") is not None

    def new_recovery_code(self) -> str:
        """A new recovery code for the PIN in place (the old code stops working): for a
        profile whose PIN was set before recovery codes existed. The UI calls it only right
        after the right PIN was typed, and shows the code once."""
        if not self.has_pin():
            raise StorageError(f"{self.db_path}: no teacher PIN to make a recovery code for")
        code = "".join(secrets.choice("0123456789") for _ in range(RECOVERY_CODE_DIGITS))
        self.set_setting("teacher_recovery", self._hash_secret(code))
        return code

    def set_pin(self, pin: str) -> str:
        """Set the teacher PIN (4-8 digits) and return a new recovery code
        (:data:`RECOVERY_CODE_DIGITS` digits) to show the teacher once; only salted PBKDF2
        hashes of both are stored. The UI asks a grown-up question before the first PIN."""
        return self._set_pin_records(pin)

    def verify_pin(self, pin: str) -> bool:
        """True when ``pin`` matches the stored PIN (no delays: the UI uses :meth:`try_pin`)."""
        if not valid_pin(pin):
            return False
        return self._secret_matches("teacher_pin", pin, "teacher PIN")

    def _attempts(self, key: str) -> tuple[int, float, float]:
        """(failures in a row, wait-until time, the wait's length) stored under ``key``."""
        raw = self.get_setting(key)
        if raw is None:
            return 0, 0.0, 0.0
        try:
            data = json.loads(raw)
            failures, until, delay = int(data["failures"]), float(data["until"]), float(data["delay"])
        except (ValueError, TypeError, KeyError):  # damaged: never fewer delays than one failure more
            failures = PIN_FREE_ATTEMPTS + 1
            delay = pin_delay_after(failures)
            return failures, self.pin_clock() + delay, delay
        return max(failures, 0), until, delay

    def _wait(self, key: str) -> float:
        _failures, until, delay = self._attempts(key)
        # never longer than the wait that was set: a clock put back cannot lock a teacher out
        return max(0.0, min(until - self.pin_clock(), delay))

    def _throttled_try(self, key: str, matches: bool | None) -> PinCheck:
        """Record one try of the secret whose attempts are under ``key``; ``matches`` is
        None when the try was refused before checking."""
        failures, _until, _delay = self._attempts(key)
        if matches is None:
            return PinCheck(False, True, self._wait(key), failures)
        if matches:
            with self._transaction() as conn:
                conn.execute("DELETE FROM settings WHERE key = ?", (key,))
            return PinCheck(True, False, 0.0, 0)
        failures += 1
        delay = pin_delay_after(failures)
        self.set_setting(key, json.dumps({"failures": failures, "until": self.pin_clock() + delay, "delay": delay}))
        return PinCheck(False, False, delay, failures)

    def pin_wait(self) -> float:
        """Seconds before the next teacher PIN try is accepted (0: now)."""
        return self._wait("teacher_pin_attempts")

    def recovery_wait(self) -> float:
        """Seconds before the next recovery-code try is accepted (0: now)."""
        return self._wait("teacher_recovery_attempts")

    def try_pin(self, pin: str) -> PinCheck:
        """One PIN try from the number pad: refused unchecked while a wait runs; a wrong
        PIN adds a failure and sets the next wait (:func:`pin_delay_after`), persisted."""
        key = "teacher_pin_attempts"
        if self._wait(key) > 0:
            return self._throttled_try(key, None)
        return self._throttled_try(key, valid_pin(pin) and self._secret_matches("teacher_pin", pin, "teacher PIN"))

    def try_recovery_code(self, code: str) -> PinCheck:
        """One recovery-code try (spaces and dashes ignored), slowed down like the PIN but
        counted apart, so a child's wrong PINs never block the teacher's recovery."""
        key = "teacher_recovery_attempts"
        if self._wait(key) > 0:
            return self._throttled_try(key, None)
        code = code.replace(" ", "").replace("-", "") if isinstance(code, str) else ""
        if self.get_setting("teacher_recovery") is None:
            raise StorageError(f"{self.db_path}: no recovery code was set with this PIN")
        ok = _RECOVERY_PATTERN.match(code) is not None and self._secret_matches("teacher_recovery", code,
                                                                                "recovery code")
        return self._throttled_try(key, ok)

    def reset_pin(self, recovery_code: str, new_pin: str) -> str:
        """Replace a forgotten PIN: the recovery code must match; returns the next
        recovery code (the used one stops working). Stories and every other setting are
        untouched."""
        if not valid_pin(new_pin):
            raise StorageError("teacher PIN: must be 4 to 8 digits")
        check = self.try_recovery_code(recovery_code)
        if not check.ok:
            wait = f"; try again in {math.ceil(check.wait_s)} s" if check.wait_s > 0 else ""
            raise StorageError(f"recovery code: wrong code{wait}")
        return self._set_pin_records(new_pin)

    # -- class sessions and rosters ---------------------------------------------------
    def create_session(self, name: str) -> int:
        name = _check_person_name(name, "session")
        with self._transaction() as conn:
            cur = conn.execute("INSERT INTO class_sessions (name, created) VALUES (?, ?)", (name, time.time()))
            return int(cur.lastrowid)

    def list_sessions(self) -> list[tuple[int, str]]:
        return [(r[0], r[1]) for r in self._conn.execute("SELECT id, name FROM class_sessions ORDER BY id")]

    def delete_session(self, session_id: int) -> None:
        with self._transaction() as conn:
            conn.execute("DELETE FROM class_sessions WHERE id = ?", (session_id,))

    def add_group(self, session_id: int, name: str, members: list[str]) -> int:
        """Add a group of children (names or nicknames only) to a class session."""
        name = _check_person_name(name, "group")
        members = [_check_person_name(m, f"group {name}") for m in members]
        with self._transaction() as conn:
            if conn.execute("SELECT 1 FROM class_sessions WHERE id = ?", (session_id,)).fetchone() is None:
                raise StorageError(f"no class session {session_id}")
            cur = conn.execute("INSERT INTO groups (session_id, name, members) VALUES (?, ?, ?)",
                               (session_id, name, json.dumps(members, ensure_ascii=False)))
            return int(cur.lastrowid)

    def list_groups(self, session_id: int) -> list[Group]:
        rows = self._conn.execute("SELECT id, session_id, name, members FROM groups WHERE session_id = ? ORDER BY id",
                                  (session_id,)).fetchall()
        return [Group(r[0], r[1], r[2], tuple(json.loads(r[3]))) for r in rows]

    # -- activity log (opt-in) --------------------------------------------------------
    @property
    def activity_logging(self) -> bool:
        return self.get_setting("activity_log") == "on"

    def set_activity_logging(self, enabled: bool) -> None:
        self.set_setting("activity_log", "on" if enabled else "off")

    def log_activity(self, event: str, story_id: str | None = None, detail: str = "") -> bool:
        """Record an event when the teacher has switched the log on; returns whether it did."""
        if not self.activity_logging:
            return False
        with self._transaction() as conn:
            conn.execute("INSERT INTO activity (at, event, story_id, detail) VALUES (?, ?, ?, ?)",
                         (time.time(), event, story_id, detail))
        return True

    def export_activity_csv(self, path: str | Path) -> int:
        """Write the activity log as CSV (UTC ISO times); returns the number of rows."""
        rows = self._conn.execute("SELECT at, event, story_id, detail FROM activity ORDER BY id").fetchall()
        lines: list[list[str]] = [["time_utc", "event", "story_id", "detail"]]
        for at, event, story_id, detail in rows:
            lines.append([time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(at)), event, story_id or "", detail])
        import io
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows(lines)
        _atomic_write(Path(path), buf.getvalue().encode("utf-8"))
        return len(rows)

    # -- story packages ---------------------------------------------------------------
    def export_package(self, story_id: str, zip_path: str | Path) -> Path:
        """Write a story and its assets as a zip: ``manifest.json``, ``story.json``, ``assets/``."""
        story = self.load_story(story_id)
        story_bytes = json.dumps(story.to_dict(), ensure_ascii=False, indent=1).encode("utf-8")
        files = {"story.json": story_bytes}
        voices = referenced_assets(story)
        for name in self.asset_names(story_id):
            if name.startswith(ASSET_PREFIX) and name not in voices:
                continue  # a replaced or undone narration: not part of the story
            files[f"assets/{name}"] = self.read_asset(story_id, name)
        manifest = {
            "format": PACKAGE_FORMAT_NAME,
            "version": PACKAGE_FORMAT_VERSION,
            "story_id": story.id,
            "title": story.title,
            "files": [{"name": n, "size": len(b), "sha256": hashlib.sha256(b).hexdigest()} for n, b in files.items()],
        }
        zip_path = Path(zip_path)
        try:  # durable: a temporary zip beside it, fsynced, renamed into place, folder fsynced
            with durable_file(zip_path) as fh, zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED) as zf:
                zf.writestr("manifest.json", json.dumps(manifest, ensure_ascii=False, indent=1))
                for name, data in files.items():
                    zf.writestr(name, data)
        except OSError as exc:
            raise StorageError(f"{zip_path}: not exported ({_os_problem(exc)})") from None
        return zip_path

    def import_package(self, zip_path: str | Path) -> Story:
        """Validate a whole story package, then add it; nothing is written if any check fails.

        A story whose id already exists on this device is imported as a copy with a new id,
        so an import never overwrites a child's work.

        Order, so that a crash or power cut at any point leaves either no story or the
        story with all its assets: the assets are written into a ``.import-*`` staging
        folder, each file and the folder fsynced, the folder renamed into place and the
        assets folder fsynced, and only then is the story row committed. A crash before
        the commit leaves an asset folder no story refers to (harmless; a later import of
        the same package replaces it) or a staging folder (removed when the store opens).
        """
        story, assets = read_package(zip_path)
        if self.has_story(story.id):
            story.id = new_id()
        final = self._story_assets(story.id)
        staging: Path | None = None
        try:
            remove_tree(final)  # no story has this id: an orphan from an earlier import cut short
            if assets:
                staging = Path(tempfile.mkdtemp(prefix=".import-", dir=self._ensure_assets_dir()))
                for name, data in assets.items():
                    (staging / name).write_bytes(data)
                durable_tree(staging)
                durable_move(staging, final)
                staging = None
        except OSError as exc:
            raise StorageError(f"{zip_path}: not imported ({_os_problem(exc)})") from None
        finally:
            if staging is not None:
                shutil.rmtree(staging, ignore_errors=True)
        self.save_story(story)
        return story

    def _ensure_assets_dir(self) -> Path:
        return make_dirs(self.assets_dir)


#: What a damaged zip can raise while opening or inflating an entry (found by the package
#: fuzzing in tests/test_robust_files.py: zlib.error and EOFError escaped before).
_ZIP_READ_ERRORS = (zipfile.BadZipFile, OSError, RuntimeError, ValueError, EOFError, zlib.error, LZMAError)


def read_package(zip_path: str | Path) -> tuple[Story, dict[str, bytes]]:
    """Read and fully validate a story package; returns the story and its assets by name.

    Checks, in order: file size, zip structure, entry count, entry names (no folders other
    than ``assets/``, no ``..``, no absolute paths), declared and actual sizes (read with a
    cap, so a lying header cannot inflate memory), the manifest format and version, that
    the manifest lists exactly the files present with matching SHA-256, and the story.
    """
    zip_path = Path(zip_path)
    where = str(zip_path)

    def fail(problem: str) -> StorageError:
        return StorageError(f"{where}: {problem}")

    if not zip_path.is_file():
        raise fail("no such file")
    if zip_path.stat().st_size > MAX_PACKAGE_BYTES:
        raise fail(f"package larger than {MAX_PACKAGE_BYTES // (1024 * 1024)} MB")
    try:
        zf = zipfile.ZipFile(zip_path)
    except _ZIP_READ_ERRORS as exc:
        raise fail(f"not a story package ({exc})") from None
    with zf:
        infos = zf.infolist()
        if len(infos) > MAX_PACKAGE_ENTRIES:
            raise fail(f"more than {MAX_PACKAGE_ENTRIES} files")
        names = [i.filename for i in infos]
        if len(set(names)) != len(names):
            raise fail("a file name appears twice")
        total = 0
        for info in infos:
            name = info.filename
            if name.startswith(("/", "\\")) or "\\" in name or ":" in name or any(
                    part in ("", ".", "..") for part in name.split("/")):
                raise fail(f"unsafe file name {name!r}")
            if name not in ("manifest.json", "story.json"):
                head, _, tail = name.partition("/")
                if head != "assets" or "/" in tail:
                    raise fail(f"unexpected file {name!r}")
                _check_asset_name(tail, where)
            if info.file_size > MAX_ENTRY_BYTES:
                raise fail(f"{name} is larger than {MAX_ENTRY_BYTES // (1024 * 1024)} MB")
            total += info.file_size
            if total > MAX_UNCOMPRESSED_BYTES:
                raise fail(f"package unpacks to more than {MAX_UNCOMPRESSED_BYTES // (1024 * 1024)} MB")
        if "manifest.json" not in names or "story.json" not in names:
            raise fail("missing manifest.json or story.json")
        contents: dict[str, bytes] = {}
        for info in infos:
            try:
                with zf.open(info) as fh:
                    data = fh.read(MAX_ENTRY_BYTES + 1)
            except _ZIP_READ_ERRORS as exc:
                raise fail(f"{info.filename} cannot be read ({exc})") from None
            if len(data) > MAX_ENTRY_BYTES or len(data) != info.file_size:
                raise fail(f"{info.filename}: size does not match its header")
            contents[info.filename] = data
    try:
        manifest = json.loads(contents.pop("manifest.json"))
    except (ValueError, RecursionError) as exc:  # RecursionError: "[[[[..." nested too deep
        raise fail(f"manifest.json is not JSON ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != PACKAGE_FORMAT_NAME:
        raise fail("manifest.json is not a StoryBeam package manifest")
    version = manifest.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= PACKAGE_FORMAT_VERSION:
        raise fail(f"package format {version!r} is not supported (this app reads 1 to {PACKAGE_FORMAT_VERSION})")
    listed = manifest.get("files")
    if not isinstance(listed, list) or not all(isinstance(f, dict) and isinstance(f.get("name"), str) for f in listed):
        raise fail("manifest.json: 'files' must be a list of objects with a 'name'")
    listed_names = {f.get("name") for f in listed}
    if listed_names != set(contents) or len(listed) != len(contents):
        raise fail("manifest.json does not list exactly the files in the package")
    for entry in listed:
        data = contents[entry["name"]]
        if entry.get("size") != len(data) or entry.get("sha256") != hashlib.sha256(data).hexdigest():
            raise fail(f"{entry['name']}: size or checksum does not match the manifest")
    try:
        story = Story.from_dict(json.loads(contents.pop("story.json")))
    except (ValueError, RecursionError) as exc:
        raise fail(f"story.json is not valid JSON ({exc})") from None
    except StoryError as exc:
        raise fail(f"story.json: {exc}") from None
    if manifest.get("story_id") != story.id:
        raise fail("manifest story_id does not match story.json")
    assets = {name.split("/", 1)[1]: data for name, data in contents.items()}
    try:
        check_package_narrations(story, assets, where)
    except NarrationError as exc:
        raise StorageError(str(exc)) from None
    return story, assets


def default_profile_path() -> Path:
    """Where the app keeps the device profile unless ``--db`` says otherwise."""
    base = os.environ.get("STORYBEAM_HOME") or os.path.join(os.path.expanduser("~"), ".storybeam")
    return Path(base) / "profile.db"


__all__ = ["ProfileStore", "StorageError", "StorySummary", "Group", "read_package", "default_profile_path",
           "SCHEMA_VERSION", "MIGRATIONS", "APPLICATION_ID", "PinCheck", "pin_delay_after", "valid_pin",
           "RECOVERY_CODE_DIGITS"]
