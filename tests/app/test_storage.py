"""Profile storage: autosave, reopen, WAL, migrations, refusal of bad files, packages,
teacher PIN, rosters and the activity log."""
from __future__ import annotations

import csv
import hashlib
import json
import sqlite3
import zipfile

import pytest

import app.story.storage as storage
import app.story.storage.packages as packages
import app.story.storage.teacher as teacher
from app.story.editing import StoryEditor
from app.story.storage import MIGRATIONS, SCHEMA_VERSION, ProfileStore, StorageError, read_package
from app.story.model import Story
from retrieval.errors import StoryBeamError


@pytest.fixture(autouse=True)
def fast_pin(monkeypatch):
    monkeypatch.setattr(teacher, "PIN_ITERATIONS", 1000)


def _story() -> Story:
    story = Story.new("short", title="ロボットのぼうけん")
    ed = StoryEditor(story)
    c = ed.add_character(story.scenes[0].id, "robot")
    ed.set_path(story.scenes[0].id, c.id, [(0.1, 0.1, 0.0), (0.6, 0.5, 1.5)])
    return story


def test_autosave_on_every_edit_and_reopen(tmp_path):
    db = tmp_path / "p.db"
    store = ProfileStore(db)
    assert store.journal_mode == "wal"
    assert store.schema_version == SCHEMA_VERSION
    story = Story.new("classic", title="Five parts")
    ed = StoryEditor(story)
    ed.add_listener(lambda s, label: store.save_story(s))
    c = ed.add_character(story.scenes[2].id, "animal")
    ed.set_path(story.scenes[2].id, c.id, [(0.2, 0.2, 0.0), (0.3, 0.3, 0.4)])
    # a second connection sees the committed state without the first one closing
    with ProfileStore(db) as other:
        assert other.load_story(story.id) == story
        assert [s.scene_count for s in other.list_stories()] == [5]
    store.close()
    with ProfileStore(db) as again:
        assert again.load_story(story.id).to_dict() == story.to_dict()
        assert sqlite3.connect(db).execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_migration_from_schema_1_keeps_stories(tmp_path):
    db = tmp_path / "old.db"
    conn = sqlite3.connect(db)
    for statement in MIGRATIONS[0]:
        conn.execute(statement)
    story = _story()
    conn.execute("INSERT INTO stories (id, title, body, modified) VALUES (?, ?, ?, ?)",
                 (story.id, story.title, json.dumps(story.to_dict()), 1000.0))
    conn.execute(f"PRAGMA application_id={storage.APPLICATION_ID}")
    conn.execute("PRAGMA user_version=1")
    conn.commit(); conn.close()
    with ProfileStore(db) as store:
        assert store.schema_version == SCHEMA_VERSION
        [summary] = store.list_stories()
        assert (summary.id, summary.arc, summary.scene_count) == (story.id, "short", 3)
        assert store.load_story(story.id) == story
        store.set_pin("1234")  # the tables added by migration 2 work
        assert store.verify_pin("1234")


def test_foreign_newer_and_damaged_files_are_refused(tmp_path):
    text = tmp_path / "notes.db"
    text.write_text("hello, this is not a database at all" * 10)
    with pytest.raises(StorageError, match="not an SQLite file"):
        ProfileStore(text)
    foreign = tmp_path / "foreign.db"
    conn = sqlite3.connect(foreign); conn.execute("CREATE TABLE t (x)"); conn.commit(); conn.close()
    with pytest.raises(StorageError, match="another program"):
        ProfileStore(foreign)
    newer = tmp_path / "newer.db"
    ProfileStore(newer).close()
    conn = sqlite3.connect(newer); conn.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}"); conn.commit(); conn.close()
    with pytest.raises(StorageError, match="newer StoryBeam"):
        ProfileStore(newer)
    # damage the inside pages of a real profile
    damaged = tmp_path / "damaged.db"
    with ProfileStore(damaged) as store:
        for _ in range(30):
            store.save_story(_story())
    raw = bytearray(damaged.read_bytes())
    assert len(raw) > 8192
    raw[4096:len(raw)] = b"\xa5" * (len(raw) - 4096)
    damaged.write_bytes(bytes(raw))
    with pytest.raises(StorageError, match="damaged") as info:
        ProfileStore(damaged)
    assert isinstance(info.value, StoryBeamError) and "damaged.db" in str(info.value)
    # the refusal leaves other profiles usable
    with ProfileStore(tmp_path / "good.db") as good:
        good.save_story(_story())
        assert len(good.list_stories()) == 1


def test_one_damaged_story_does_not_hide_the_others(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        a, b = _story(), _story()
        store.save_story(a); store.save_story(b)
        store._conn.execute("UPDATE stories SET body = '{broken' WHERE id = ?", (a.id,))
        assert {s.id for s in store.list_stories()} == {a.id, b.id}
        with pytest.raises(StorageError, match="damaged"):
            store.load_story(a.id)
        assert store.load_story(b.id) == b


def test_package_round_trip_is_identical(tmp_path):
    with ProfileStore(tmp_path / "a.db") as a:
        story = _story()
        a.save_story(story)
        a.put_asset(story.id, "drawing.png", b"\x89PNG fake bytes")
        first = a.export_package(story.id, tmp_path / "out" / "story.zip")
    with ProfileStore(tmp_path / "b.db") as b:
        imported = b.import_package(first)
        assert imported == story
        assert b.read_asset(story.id, "drawing.png") == b"\x89PNG fake bytes"
        second = b.export_package(story.id, tmp_path / "again.zip")
        # importing the same package again makes a copy, never an overwrite
        copy_ = b.import_package(first)
        assert copy_.id != story.id and len(b.list_stories()) == 2
    with zipfile.ZipFile(first) as z1, zipfile.ZipFile(second) as z2:
        assert sorted(z1.namelist()) == sorted(z2.namelist())
        for name in z1.namelist():
            assert z1.read(name) == z2.read(name)


def _write_package(path, files: dict[str, bytes], manifest: dict | None = None, **manifest_changes):
    if manifest is None:
        story_id = json.loads(files["story.json"])["id"] if "story.json" in files else "x"
        manifest = {"format": "storybeam.package", "version": 1, "story_id": story_id, "title": "t",
                    "files": [{"name": n, "size": len(b), "sha256": hashlib.sha256(b).hexdigest()} for n, b in files.items()]}
    manifest.update(manifest_changes)
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("manifest.json", json.dumps(manifest))
        for name, data in files.items():
            zf.writestr(name, data)
    return path


@pytest.mark.parametrize("files_change, manifest_change, fragment", [
    ({"assets/../../evil.txt": b"x"}, {}, "unsafe file name"),
    ({"/etc/evil": b"x"}, {}, "unsafe file name"),
    ({"assets/sub/evil.png": b"x"}, {}, "unexpected file"),
    ({"other.txt": b"x"}, {}, "unexpected file"),
    ({}, {"version": 99}, "not supported"),
    ({}, {"format": "zip"}, "not a StoryBeam package"),
    ({"assets/big.bin": b"\0" * 2048}, {}, "larger than"),
])
def test_malicious_packages_are_refused_before_writing(tmp_path, monkeypatch, files_change, manifest_change, fragment):
    monkeypatch.setattr(packages, "MAX_ENTRY_BYTES", 1024)
    story = _story()
    files = {"story.json": json.dumps(story.to_dict()).encode(), **files_change}
    pkg = tmp_path / "bad.zip"
    _write_package(pkg, files, **manifest_change)
    with ProfileStore(tmp_path / "p.db") as store:
        with pytest.raises(StorageError, match=fragment):
            store.import_package(pkg)
        assert store.list_stories() == []
        assert not store.assets_dir.exists() or not any(store.assets_dir.rglob("*"))
    assert not (tmp_path.parent / "evil.txt").exists()


def test_package_checksum_story_and_zip_errors(tmp_path):
    story = _story()
    body = json.dumps(story.to_dict()).encode()
    good = {"story.json": body}
    manifest = {"format": "storybeam.package", "version": 1, "story_id": story.id, "title": "",
                "files": [{"name": "story.json", "size": len(body), "sha256": "0" * 64}]}
    with pytest.raises(StorageError, match="checksum"):
        read_package(_write_package(tmp_path / "sum.zip", good, manifest=manifest))
    bad_story = story.to_dict(); bad_story["version"] = 7
    with pytest.raises(StorageError, match="newer StoryBeam"):
        read_package(_write_package(tmp_path / "ver.zip", {"story.json": json.dumps(bad_story).encode()}))
    (tmp_path / "junk.zip").write_bytes(b"PK\x03\x04 not really")
    with pytest.raises(StorageError, match="not a story package"):
        read_package(tmp_path / "junk.zip")
    with pytest.raises(StorageError, match="missing manifest"):
        with zipfile.ZipFile(tmp_path / "nomani.zip", "w") as zf:
            zf.writestr("story.json", body)
        read_package(tmp_path / "nomani.zip")


def test_teacher_pin_is_salted_hash(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        assert not store.verify_pin("1234")
        with pytest.raises(StorageError, match="4 to 8 digits"):
            store.set_pin("12a4")
        store.set_pin("2468")
        record = store.get_setting("teacher_pin")
        assert "2468" not in record and record.startswith("pbkdf2_sha256$1000$")
        assert store.verify_pin("2468") and not store.verify_pin("2469") and not store.verify_pin("")
        first_salt = record.split("$")[2]
        store.set_pin("2468")
        assert store.get_setting("teacher_pin").split("$")[2] != first_salt


def test_sessions_rosters_and_opt_in_activity_csv(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        sid = store.create_session("3年2組")
        store.add_group(sid, "Group A", ["Ken", "ゆい"])
        with pytest.raises(StorageError, match="name must be"):
            store.add_group(sid, "B", ["ok", ""])
        with pytest.raises(StorageError, match="no class session"):
            store.add_group(999, "C", ["x"])
        [group] = store.list_groups(sid)
        assert group.members == ("Ken", "ゆい")
        assert not store.log_activity("open")  # off by default
        store.set_activity_logging(True)
        assert store.log_activity("open story", "abc", "scene 1")
        n = store.export_activity_csv(tmp_path / "log.csv")
    rows = list(csv.reader(open(tmp_path / "log.csv", encoding="utf-8")))
    assert n == 1 and rows[0] == ["time_utc", "event", "story_id", "detail"]
    assert rows[1][1:] == ["open story", "abc", "scene 1"]
