"""Saved stories: one row per story (the JSON body plus summary columns for the home
screen), inserted or replaced in one transaction by the autosave after every edit.

Deleting is two steps, so a child's tap is never final: :meth:`StoryShelf.to_bin` marks the
row (``binned`` = when; the body and the assets stay), the story leaves the home screen
and appears in the teacher's bin (:meth:`StoryShelf.binned`), from which
:meth:`StoryShelf.restore` brings it back and :meth:`StoryShelf.empty_bin` deletes for
good (each row committed before its assets go). Renaming (:meth:`StoryShelf.rename`)
rewrites the title and the cover (the name by picture and voice) in one transaction.
Every change is one SQLite transaction (the profile's durable writes)."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass

from app.story.model import Cover, Story, StoryError
from app.story.storage.assets import AssetFolder
from app.story.storage.database import ProfileDatabase, StorageError, as_storage_error


@dataclass(frozen=True)
class StorySummary:
    """What the home screen shows for a saved story, without parsing its body."""

    id: str
    title: str
    arc: str
    scene_count: int
    modified: float


class StoryShelf:
    """The ``stories`` table of a profile (and, on delete, the story's assets)."""

    def __init__(self, db: ProfileDatabase, assets: AssetFolder):
        self._db = db
        self._assets = assets

    def save(self, story: Story) -> None:
        """Insert or replace a story (the autosave after every edit)."""
        body = json.dumps(story.to_dict(), ensure_ascii=False, separators=(",", ":"))
        now = time.time()
        with self._db.transaction() as conn:
            conn.execute(
                """INSERT INTO stories (id, title, body, modified, arc, scene_count, created)
                   VALUES (?, ?, ?, ?, ?, ?, ?)
                   ON CONFLICT(id) DO UPDATE SET title=excluded.title, body=excluded.body,
                       modified=excluded.modified, arc=excluded.arc, scene_count=excluded.scene_count""",
                (story.id, story.title, body, now, story.arc, len(story.scenes), now),
            )

    def load(self, story_id: str) -> Story:
        """The story with ``story_id``, parsed; :class:`StorageError` when missing or damaged."""
        db_path = self._db.db_path
        with as_storage_error(db_path, f"story '{story_id}' cannot be read"):
            row = self._db.conn.execute("SELECT body FROM stories WHERE id = ?", (story_id,)).fetchone()
        if row is None:
            raise StorageError(f"{db_path}: no story with id '{story_id}'")
        try:
            return Story.from_dict(json.loads(row[0]))
        except (ValueError, StoryError) as exc:
            raise StorageError(f"{db_path}: story '{story_id}' is damaged ({exc})") from None

    def has(self, story_id: str) -> bool:
        """Whether a story with ``story_id`` is saved."""
        with as_storage_error(self._db.db_path, "stories cannot be read"):
            return self._db.conn.execute("SELECT 1 FROM stories WHERE id = ?", (story_id,)).fetchone() is not None

    def summaries(self) -> list[StorySummary]:
        """Saved stories, most recently changed first (summaries only: one damaged body
        does not hide the others)."""
        with as_storage_error(self._db.db_path, "the story list cannot be read"):
            rows = self._db.conn.execute(
                "SELECT id, title, arc, scene_count, modified FROM stories WHERE binned IS NULL "
                "ORDER BY modified DESC, id").fetchall()
        return [StorySummary(*row) for row in rows]

    def binned(self) -> list[StorySummary]:
        """Stories in the bin, most recently binned first."""
        with as_storage_error(self._db.db_path, "the bin cannot be read"):
            rows = self._db.conn.execute(
                "SELECT id, title, arc, scene_count, modified FROM stories WHERE binned IS NOT NULL "
                "ORDER BY binned DESC, id").fetchall()
        return [StorySummary(*row) for row in rows]

    def to_bin(self, story_id: str) -> None:
        """Move a story to the bin (it keeps its body and assets; :meth:`restore` undoes it)."""
        with self._db.transaction() as conn:
            if conn.execute("UPDATE stories SET binned = ? WHERE id = ?", (time.time(), story_id)).rowcount == 0:
                raise StorageError(f"{self._db.db_path}: no story with id '{story_id}'")

    def restore(self, story_id: str) -> None:
        """Take a story out of the bin, back onto the home screen."""
        with self._db.transaction() as conn:
            conn.execute("UPDATE stories SET binned = NULL WHERE id = ?", (story_id,))

    def empty_bin(self) -> int:
        """Delete every story in the bin for good (row, then assets); returns how many."""
        ids = [s.id for s in self.binned()]
        for story_id in ids:
            self.delete(story_id)
        return len(ids)

    def rename(self, story_id: str, title: str | None = None, cover: Cover | None = None) -> Story:
        """Give a story a new typed ``title`` and/or ``cover`` (picture, colour, voice);
        checked as a loaded story is (:meth:`Story.from_dict`), saved in one transaction."""
        story = self.load(story_id)
        if title is not None:
            story.title = title
        if cover is not None:
            story.cover = cover
        try:
            story = Story.from_dict(story.to_dict())
        except StoryError as exc:
            raise StorageError(f"{self._db.db_path}: story '{story_id}' cannot be renamed ({exc})") from None
        self.save(story)
        return story

    def delete(self, story_id: str) -> None:
        """Delete the row (committed first), then the story's assets."""
        with self._db.transaction() as conn:
            conn.execute("DELETE FROM stories WHERE id = ?", (story_id,))
        self._assets.remove_story(story_id)
