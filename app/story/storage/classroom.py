"""Teacher data: class sessions, their groups of children (names or nicknames only) and
the opt-in activity log (exported as CSV)."""
from __future__ import annotations

import csv
import io
import json
import time
from dataclasses import dataclass
from pathlib import Path

from app.story.storage.database import ProfileDatabase, StorageError, atomic_write
from app.story.storage.teacher import Settings

MAX_NAME_CHARS = 40


@dataclass(frozen=True)
class Group:
    id: int
    session_id: int
    name: str
    members: tuple[str, ...]


def check_person_name(name: str, where: str) -> str:
    """``name`` stripped; :class:`StorageError` unless it is 1-:data:`MAX_NAME_CHARS`
    printable characters."""
    name = name.strip() if isinstance(name, str) else ""
    if not name or len(name) > MAX_NAME_CHARS or not all(ch.isprintable() for ch in name):
        raise StorageError(f"{where}: a name must be 1-{MAX_NAME_CHARS} printable characters, got {name!r}")
    return name


class Classroom:
    """The ``class_sessions``, ``groups`` and ``activity`` tables of a profile."""

    def __init__(self, db: ProfileDatabase, settings: Settings):
        self._db = db
        self._settings = settings

    # -- class sessions and rosters ---------------------------------------------------
    def create_session(self, name: str) -> int:
        name = check_person_name(name, "session")
        with self._db.transaction() as conn:
            cur = conn.execute("INSERT INTO class_sessions (name, created) VALUES (?, ?)", (name, time.time()))
            return int(cur.lastrowid)

    def list_sessions(self) -> list[tuple[int, str]]:
        return [(r[0], r[1]) for r in self._db.conn.execute("SELECT id, name FROM class_sessions ORDER BY id")]

    def delete_session(self, session_id: int) -> None:
        with self._db.transaction() as conn:
            conn.execute("DELETE FROM class_sessions WHERE id = ?", (session_id,))

    def add_group(self, session_id: int, name: str, members: list[str]) -> int:
        """Add a group of children (names or nicknames only) to a class session."""
        name = check_person_name(name, "group")
        members = [check_person_name(m, f"group {name}") for m in members]
        with self._db.transaction() as conn:
            if conn.execute("SELECT 1 FROM class_sessions WHERE id = ?", (session_id,)).fetchone() is None:
                raise StorageError(f"no class session {session_id}")
            cur = conn.execute("INSERT INTO groups (session_id, name, members) VALUES (?, ?, ?)",
                               (session_id, name, json.dumps(members, ensure_ascii=False)))
            return int(cur.lastrowid)

    def list_groups(self, session_id: int) -> list[Group]:
        rows = self._db.conn.execute(
            "SELECT id, session_id, name, members FROM groups WHERE session_id = ? ORDER BY id",
            (session_id,)).fetchall()
        return [Group(r[0], r[1], r[2], tuple(json.loads(r[3]))) for r in rows]

    # -- activity log (opt-in) --------------------------------------------------------
    @property
    def activity_logging(self) -> bool:
        return self._settings.get("activity_log") == "on"

    def set_activity_logging(self, enabled: bool) -> None:
        self._settings.set("activity_log", "on" if enabled else "off")

    def log_activity(self, event: str, story_id: str | None = None, detail: str = "") -> bool:
        """Record an event when the teacher has switched the log on; returns whether it did."""
        if not self.activity_logging:
            return False
        with self._db.transaction() as conn:
            conn.execute("INSERT INTO activity (at, event, story_id, detail) VALUES (?, ?, ?, ?)",
                         (time.time(), event, story_id, detail))
        return True

    def export_activity_csv(self, path: str | Path) -> int:
        """Write the activity log as CSV (UTC ISO times); returns the number of rows."""
        rows = self._db.conn.execute("SELECT at, event, story_id, detail FROM activity ORDER BY id").fetchall()
        lines: list[list[str]] = [["time_utc", "event", "story_id", "detail"]]
        for at, event, story_id, detail in rows:
            lines.append([time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(at)), event, story_id or "", detail])
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows(lines)
        atomic_write(Path(path), buf.getvalue().encode("utf-8"))
        return len(rows)
