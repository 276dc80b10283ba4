"""Crash-safety of story storage (short CI version of `storybeam stress --only kill,packages`):
SIGKILL during saves, damaged and foreign databases, a full disk. Regression tests for the
storage defects the campaign found (raw sqlite3/Unicode errors instead of StorageError)."""
from __future__ import annotations

import sqlite3

import pytest

from app.story.storage import ProfileStore, StorageError
from app.story.model import Story
from lab.stress import files, kill


@pytest.mark.slow  # the kill campaign: 30 SIGKILLed child savers
def test_sigkill_during_saves_loses_no_story(tmp_path):
    """30 kills at random moments: every story equals its acknowledged (or in-flight) state."""
    report = kill.run_kill_campaign(tmp_path, kills=30, seed=7, max_delay_s=0.1, progress=False)
    assert report["kills"] == 30
    assert report["stories_lost"] == 0 and report["open_failures"] == 0 and report["integrity_failures"] == 0, \
        report["problems"]
    # The harness must actually have killed saves in progress, or it proves nothing.
    assert report["saves_acked"] > 30 and report["in_flight_at_kill"] > 5
    assert report["stories_checked"] > 30


def test_kill_verifier_detects_a_lost_story(tmp_path):
    """The verifier can fail: a story whose stored body differs from the acked one is lost."""
    db = tmp_path / "p.db"
    story = Story.new()
    with ProfileStore(db) as store:
        store.save_story(story)
    acked = story.to_dict()
    acked["title"] = "what the child really typed"
    report = kill.KillReport()
    kill.verify(db, {story.id: kill._Expected(acked=acked)}, report)
    assert report.stories_lost == 1
    report = kill.KillReport()
    kill.verify(db, {story.id: kill._Expected(acked=story.to_dict())}, report)
    assert report.stories_lost == 0


def test_damaged_and_foreign_databases_raise_storage_error(tmp_path):
    out = files.run_db_corruption(tmp_path, n=60, seed=3)
    assert out["crashes"] == 0, out["crash_examples"]
    assert out["original_unchanged"]
    assert out["refused"] >= 8  # at least every foreign file
    assert out["by_damage"]["foreign: another program's sqlite"] == 1
    assert sum(v for k, v in out["by_damage"].items() if k.startswith("wal ")) == 15  # damaged WAL files


@pytest.mark.parametrize("label", ["another program's sqlite", "newer StoryBeam schema", "png", "random", "zip"])
def test_foreign_file_message_says_why(tmp_path, label):
    path = tmp_path / "x.db"
    path.write_bytes(files.foreign_files()[label])
    with pytest.raises(StorageError, match="not a StoryBeam database|newer StoryBeam|damaged"):
        ProfileStore(path)


def _damaged_text_db(tmp_path):
    """A profile whose story body holds bytes that are not UTF-8 (a flipped bit on disk)."""
    db = tmp_path / "p.db"
    story = Story.new(title="abc")
    with ProfileStore(db) as store:
        store.save_story(story)
    conn = sqlite3.connect(db)
    conn.execute("UPDATE stories SET body = CAST(X'7B22FF' AS TEXT), title = CAST(X'61FF' AS TEXT)")
    conn.commit()
    conn.close()
    return db, story


def test_undecodable_story_raises_storage_error(tmp_path):
    """Found by the corruption campaign: reads raised sqlite3.OperationalError
    ("Could not decode to UTF-8") instead of StorageError."""
    db, story = _damaged_text_db(tmp_path)
    with ProfileStore(db) as store:
        with pytest.raises(StorageError, match="cannot be read"):
            store.load_story(story.id)
        with pytest.raises(StorageError):
            store.list_stories()


def test_undecodable_schema_raises_storage_error_on_open(tmp_path):
    """Found by the corruption campaign: a damaged schema text raised UnicodeDecodeError."""
    db = tmp_path / "p.db"
    with ProfileStore(db) as store:
        store.save_story(Story.new())
    conn = sqlite3.connect(db)
    conn.execute("PRAGMA writable_schema=ON")
    conn.execute("UPDATE sqlite_master SET sql = CAST(X'43FF' AS TEXT) WHERE name = 'settings'")
    conn.commit()
    conn.close()
    with pytest.raises(StorageError):
        with ProfileStore(db) as store:
            store.list_stories()


@pytest.mark.slow  # the full-disk campaign in a forked child
def test_full_disk_rlimit_keeps_saved_stories(tmp_path):
    """Quota-like full disk (RLIMIT_FSIZE in a forked child): a clear StorageError, no loss."""
    out = files.full_disk_rlimit(tmp_path, seed=1)
    assert out["saved_before_full"] >= 2
    assert out["error"] and "not saved" in out["error"]
    assert out["stories_lost"] == 0 and out["lost_while_full"] == 0 and out["ok"]


def test_full_disk_tmpfs_says_storage_is_full(tmp_path):
    """A real full filesystem (small tmpfs; needs root): found that saves raised
    sqlite3.OperationalError('database or disk is full'); now a StorageError saying so."""
    with files.small_tmpfs(tmp_path / "disk", 768) as disk:
        if disk is None:
            pytest.skip("mounting a tmpfs is not permitted here (the RLIMIT_FSIZE test covers a full disk)")
        out = files._full_disk_on(disk, seed=2)
    assert out["says_full"] and "storage is full" in out["error"]
    assert out["stories_lost"] == 0 and out["lost_while_full"] == 0 and out["lost_after_reopen"] == 0
    assert out["saves_after_freeing_space"]


def test_commit_failure_rolls_back_and_store_stays_usable(tmp_path, monkeypatch):
    """A COMMIT that fails (as on a full disk) leaves no open transaction behind."""
    db = tmp_path / "p.db"
    store = ProfileStore(db)
    kept = Story.new(title="kept")
    store.save_story(kept)

    class FailingCommit:
        def __init__(self, conn):
            self._conn = conn

        def execute(self, sql, *a):
            if sql == "COMMIT":
                raise sqlite3.OperationalError("database or disk is full")
            return self._conn.execute(sql, *a)

        def __getattr__(self, name):
            return getattr(self._conn, name)

    real = store._conn
    store._conn = FailingCommit(real)
    with pytest.raises(StorageError, match="storage is full"):
        store.save_story(Story.new(title="lost"))
    store._conn = real
    assert not real.in_transaction
    store.save_story(Story.new(title="after"))
    assert {s.title for s in store.list_stories()} == {"kept", "after"}
    store.close()


@pytest.mark.parametrize("version", [-1, -2, -2**31])
def test_negative_schema_version_is_damage_not_a_migration(tmp_path, version):
    """Found by the corruption campaign: a damaged header with a negative user_version made
    _migrate index MIGRATIONS backwards (IndexError, or applying the wrong migration)."""
    db = tmp_path / "p.db"
    with ProfileStore(db) as store:
        store.save_story(Story.new())
    conn = sqlite3.connect(db)
    conn.execute(f"PRAGMA user_version={version}")
    conn.commit()
    conn.close()
    before = db.read_bytes()
    with pytest.raises(StorageError, match="damaged"):
        ProfileStore(db)
    assert db.read_bytes() == before
