"""Error paths of the profile store and story packages, reached through the public API;
each test asserts the message the user sees (the file, then the problem) and that nothing
else was harmed. (The PIN's error paths are in tests/app/test_teacher_gate.py.)"""
from __future__ import annotations

import hashlib
import json
import sqlite3
import struct
import zipfile

import pytest

from app.story import storage
from app.story.demo_story import demo_story
from app.story.storage import MAX_PACKAGE_BYTES, ProfileStore, StorageError, read_package


def test_a_database_path_that_is_a_folder_is_refused(tmp_path):
    folder = tmp_path / "profile.db"
    folder.mkdir()
    with pytest.raises(StorageError) as err:
        ProfileStore(folder)
    assert str(err.value) == f"{folder}: is a folder, not a StoryBeam database"
    assert folder.is_dir() and not any(folder.iterdir())  # left as it was


def test_a_store_that_cannot_use_write_ahead_logging_is_refused():
    # SQLite's in-memory database has no WAL mode: PRAGMA journal_mode=WAL answers "memory"
    with pytest.raises(StorageError) as err:
        ProfileStore(":memory:")
    assert str(err.value) == ":memory:: could not switch to write-ahead logging (journal mode memory)"


def test_a_failed_migration_is_rolled_back_and_says_so(tmp_path, monkeypatch):
    path = tmp_path / "p.db"
    story = demo_story()
    with ProfileStore(path) as store:
        store.save_story(story)
    broken = (*storage.MIGRATIONS, ("CREATE TABLE half_done (a)", "INSERT INTO no_such_table VALUES (1)"))
    monkeypatch.setattr(storage.database, "MIGRATIONS", list(broken))
    monkeypatch.setattr(storage.database, "SCHEMA_VERSION", len(broken))
    with pytest.raises(StorageError) as err:
        ProfileStore(path)
    assert str(err.value) == (f"{path}: could not upgrade the profile to schema {len(broken)} "
                              "(no such table: no_such_table); it was left as it was")
    with sqlite3.connect(path) as conn:  # all or nothing: the first statement is undone too
        assert conn.execute("PRAGMA user_version").fetchone()[0] == len(broken) - 1
        assert conn.execute("SELECT count(*) FROM sqlite_master WHERE name = 'half_done'").fetchone()[0] == 0
    monkeypatch.undo()
    with ProfileStore(path) as store:  # the app that knows the schema opens it, story intact
        assert store.load_story(story.id).to_dict() == story.to_dict()


def test_unknown_story_and_missing_or_unsafe_assets(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        db = tmp_path / "p.db"
        with pytest.raises(StorageError) as err:
            store.load_story("nope")
        assert str(err.value) == f"{db}: no story with id 'nope'"
        with pytest.raises(StorageError) as err:
            store.export_package("nope", tmp_path / "x.zip")
        assert str(err.value) == f"{db}: no story with id 'nope'"
        assert not (tmp_path / "x.zip").exists()
        story = demo_story()
        store.save_story(story)
        with pytest.raises(StorageError) as err:
            store.read_asset(story.id, "missing.png")
        assert str(err.value) == f"{store.assets_dir / story.id / 'missing.png'}: no such asset"
        with pytest.raises(StorageError) as err:
            store.read_asset(story.id, "../p.db")
        assert str(err.value) == f"story {story.id}: unsafe asset name '../p.db'"
        with pytest.raises(StorageError) as err:
            store.load_story("../../etc")
        assert str(err.value) == f"{db}: no story with id '../../etc'"
        assert store.asset_names(story.id) == []


def test_deleting_a_class_session_removes_its_groups(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        keep = store.create_session("1組")
        gone = store.create_session("2組")
        store.add_group(keep, "A", ["Ken"])
        store.add_group(gone, "B", ["Yui", "Mio"])
        store.delete_session(gone)
        assert store.list_sessions() == [(keep, "1組")]
        assert store.list_groups(gone) == [] and [g.name for g in store.list_groups(keep)] == ["A"]
        with pytest.raises(StorageError) as err:
            store.add_group(gone, "C", ["Ren"])
        assert str(err.value) == f"no class session {gone}"
        store.delete_session(9999)  # deleting what is not there is not an error
        assert store.list_sessions() == [(keep, "1組")]


def _package(tmp_path, store: ProfileStore):
    story = demo_story()
    store.save_story(story)
    store.put_asset(story.id, "bg.png", b"\x89PNG" + bytes(range(256)) * 4)
    return store.export_package(story.id, tmp_path / "story.zip")


def test_a_missing_package_path(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        for call in (read_package, store.import_package):
            with pytest.raises(StorageError) as err:
                call(tmp_path / "nowhere.zip")
            assert str(err.value) == f"{tmp_path / 'nowhere.zip'}: no such file"
        assert store.list_stories() == []


def test_a_package_over_64_mb_is_refused_before_it_is_opened(tmp_path):
    big = tmp_path / "big.zip"
    with open(big, "wb") as fh:  # sparse: no 64 MB written
        fh.truncate(MAX_PACKAGE_BYTES + 1)
    with ProfileStore(tmp_path / "p.db") as store:
        with pytest.raises(StorageError) as err:
            store.import_package(big)
        assert str(err.value) == f"{big}: package larger than 64 MB"
        assert store.list_stories() == []
    with open(big, "r+b") as fh:  # exactly the limit is not refused for its size
        fh.truncate(MAX_PACKAGE_BYTES)
    with pytest.raises(StorageError, match="not a story package"):
        read_package(big)


def _patch_central_size(path, entry: str, size: int) -> None:
    """Make the zip's central directory declare ``size`` uncompressed bytes for ``entry``
    (what a damaged or hostile package does); the data and the local header stay."""
    data = bytearray(path.read_bytes())
    at = 0
    while True:
        at = data.index(b"PK\x01\x02", at)
        name_len = struct.unpack_from("<H", data, at + 28)[0]
        if data[at + 46:at + 46 + name_len].decode() == entry:
            struct.pack_into("<I", data, at + 24, size)
            break
        at += 4
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(("delta", "problem"), [
    (+7, "assets/bg.png: size does not match its header"),  # the data ends before the declared size
    (-7, "assets/bg.png cannot be read (Bad CRC-32 for file 'assets/bg.png')"),  # zipfile stops early: CRC
])
def test_a_zip_entry_whose_size_disagrees_with_its_header(tmp_path, delta, problem):
    with ProfileStore(tmp_path / "p.db") as store:
        pkg = _package(tmp_path, store)
        with zipfile.ZipFile(pkg) as zf:
            real = zf.getinfo("assets/bg.png").file_size
        _patch_central_size(pkg, "assets/bg.png", real + delta)
    with ProfileStore(tmp_path / "other.db") as other:
        with pytest.raises(StorageError) as err:
            other.import_package(pkg)
        assert str(err.value) == f"{pkg}: {problem}"
        assert other.list_stories() == []
        assert not other.assets_dir.exists() or not any(other.assets_dir.iterdir())  # nothing written


def test_a_manifest_with_a_wrong_story_id_or_files_list(tmp_path):
    with ProfileStore(tmp_path / "p.db") as store:
        pkg = _package(tmp_path, store)
    with zipfile.ZipFile(pkg) as zf:
        entries = {n: zf.read(n) for n in zf.namelist()}
    manifest = json.loads(entries["manifest.json"])

    def write(name: str, changed: dict) -> str:
        path = tmp_path / name
        with zipfile.ZipFile(path, "w") as zf:
            for n, data in entries.items():
                zf.writestr(n, json.dumps(changed) if n == "manifest.json" else data)
        with pytest.raises(StorageError) as err:
            read_package(path)
        return str(err.value)

    assert write("id.zip", manifest | {"story_id": "someone-else"}) == \
        f"{tmp_path / 'id.zip'}: manifest story_id does not match story.json"
    assert write("files.zip", manifest | {"files": "all of them"}) == \
        f"{tmp_path / 'files.zip'}: manifest.json: 'files' must be a list of objects with a 'name'"
    assert write("version.zip", manifest | {"version": True}) == \
        f"{tmp_path / 'version.zip'}: package format True is not supported (this app reads 1 to 1)"


def _zip(path, entries: dict[str, bytes]) -> None:
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in entries.items():
            zf.writestr(name, data)


def _refusal(path) -> str:
    with pytest.raises(StorageError) as err:
        read_package(path)
    return str(err.value).removeprefix(f"{path}: ")


def test_package_structure_refusals(tmp_path):
    p = tmp_path / "p.zip"
    _zip(p, {f"assets/a{i}.png": b"x" for i in range(storage.MAX_PACKAGE_ENTRIES + 1)})
    assert _refusal(p) == "more than 200 files"
    with zipfile.ZipFile(p, "w") as zf, pytest.warns(UserWarning, match="Duplicate name"):
        zf.writestr("story.json", b"{}")
        zf.writestr("story.json", b"{}")
    assert _refusal(p) == "a file name appears twice"
    for name in ("/etc/passwd", "assets\\x.png", "c:x.png", "assets/../story.json", "./story.json", "assets//x"):
        _zip(p, {name: b"x"})
        assert _refusal(p) == f"unsafe file name {name!r}"
    _zip(p, {"other/x.png": b"x"})
    assert _refusal(p) == "unexpected file 'other/x.png'"
    _zip(p, {"assets/sub/x.png": b"x"})
    assert _refusal(p) == "unexpected file 'assets/sub/x.png'"
    _zip(p, {"assets/-x.png": b"x"})
    assert _refusal(p) == "unsafe asset name '-x.png'"
    _zip(p, {"story.json": b"{}"})
    assert _refusal(p) == "missing manifest.json or story.json"


def test_declared_sizes_are_checked_before_anything_is_inflated(tmp_path):
    p = tmp_path / "p.zip"
    _zip(p, {"manifest.json": b"{}", "story.json": b"{}", "assets/big.png": b"x" * 100})
    _patch_central_size(p, "assets/big.png", storage.MAX_ENTRY_BYTES + 1)
    assert _refusal(p) == "assets/big.png is larger than 16 MB"
    entries = {"manifest.json": b"{}", "story.json": b"{}", **{f"assets/b{i}.png": b"y" for i in range(7)}}
    _zip(p, entries)
    for i in range(7):  # 7 x 15 MB declared: within the per-file limit, over the total
        _patch_central_size(p, f"assets/b{i}.png", 15 * 1024 * 1024)
    assert _refusal(p) == "package unpacks to more than 96 MB"


def test_manifest_and_story_json_that_are_not_json(tmp_path):
    p = tmp_path / "p.zip"
    _zip(p, {"manifest.json": b"[" * 100_000, "story.json": b"{}"})
    assert _refusal(p).startswith("manifest.json is not JSON (maximum recursion depth exceeded")
    _zip(p, {"manifest.json": b"[1]", "story.json": b"{}"})
    assert _refusal(p) == "manifest.json is not a StoryBeam package manifest"
    story = b"{not json"
    manifest = {"format": storage.PACKAGE_FORMAT_NAME, "version": 1, "story_id": "x",
                "files": [{"name": "story.json", "size": len(story), "sha256": hashlib.sha256(story).hexdigest()}]}
    _zip(p, {"manifest.json": json.dumps(manifest).encode(), "story.json": story})
    assert _refusal(p).startswith("story.json is not valid JSON (Expecting property name enclosed in double quotes")
    manifest["files"].append({"name": "assets/x.png"})
    _zip(p, {"manifest.json": json.dumps(manifest).encode(), "story.json": story})
    assert _refusal(p) == "manifest.json does not list exactly the files in the package"


def test_closing_a_store_twice_is_harmless(tmp_path):
    store = ProfileStore(tmp_path / "p.db")
    store.close()
    store.close()
    with ProfileStore(tmp_path / "p.db") as again:
        assert again.list_stories() == []


class _FailingConnection:
    """An sqlite3 connection whose statements starting with ``prefix`` fail as SQLite
    reports ``errorname`` (a read-only file, an I/O error): the store is used through its
    public API, the fault comes from below."""

    def __init__(self, real: sqlite3.Connection, prefix: str, errorname: str, text: str):
        self._real, self._prefix, self._errorname, self._text = real, prefix, errorname, text

    def execute(self, sql, *args):
        if sql.lstrip().upper().startswith(self._prefix):
            exc = sqlite3.OperationalError(self._text)
            exc.sqlite_errorname = self._errorname
            raise exc
        return self._real.execute(sql, *args)

    def __getattr__(self, name):
        return getattr(self._real, name)


@pytest.mark.parametrize(("errorname", "text", "reason"), [
    ("SQLITE_READONLY", "attempt to write a readonly database",
     "the file cannot be written (attempt to write a readonly database)"),
    ("SQLITE_IOERR_WRITE", "disk I/O error", "the storage reported an input/output error (disk I/O error)"),
    ("SQLITE_FULL", "database or disk is full",
     "the device storage is full; free some space (stories saved before are kept)"),
])
def test_a_save_the_disk_refuses_says_why_and_keeps_the_last_save(tmp_path, monkeypatch, errorname, text, reason):
    path = tmp_path / "p.db"
    story = demo_story()
    with ProfileStore(path) as store:
        store.save_story(story)
    real_connect = sqlite3.connect
    monkeypatch.setattr(storage.database.sqlite3, "connect",
                        lambda *a, **k: _FailingConnection(real_connect(*a, **k), "INSERT INTO STORIES", errorname, text))
    with ProfileStore(path) as store:
        changed = demo_story()
        changed.title = "changed"
        with pytest.raises(StorageError) as err:
            store.save_story(changed)
        assert str(err.value) == f"{path}: not saved: {reason}"
        assert store.load_story(story.id).title == story.title  # the last save is still there
        store.set_setting("language", "en")  # and the store is still usable for the rest


@pytest.mark.parametrize(("errno_", "strerror", "reason"), [
    (28, "No space left on device", "the device storage is full; free some space"),
    (13, "Permission denied", "the folder cannot be written: Permission denied"),
    (30, "Read-only file system", "the folder cannot be written: Read-only file system"),
    (5, "Input/output error", "Input/output error"),
])
def test_an_asset_or_csv_the_disk_refuses_says_why(tmp_path, monkeypatch, errno_, strerror, reason):
    def refuse(path, data):
        raise OSError(errno_, strerror)
    with ProfileStore(tmp_path / "p.db") as store:
        story = demo_story()
        store.save_story(story)
        monkeypatch.setattr(storage.database, "durable_write", refuse)
        with pytest.raises(StorageError) as err:
            store.put_asset(story.id, "bg.png", b"png")
        assert str(err.value) == f"{store.assets_dir / story.id / 'bg.png'}: not saved ({reason})"
        with pytest.raises(StorageError) as err:
            store.export_activity_csv(tmp_path / "log.csv")
        assert str(err.value) == f"{tmp_path / 'log.csv'}: not saved ({reason})"
        assert store.asset_names(story.id) == []


def test_a_migration_that_fails_in_python_is_rolled_back_too(tmp_path, monkeypatch):
    path = tmp_path / "p.db"
    ProfileStore(path).close()
    broken = (*storage.MIGRATIONS, ("CREATE TABLE half_done (a)", None))  # not SQL at all: a TypeError
    monkeypatch.setattr(storage.database, "MIGRATIONS", list(broken))
    monkeypatch.setattr(storage.database, "SCHEMA_VERSION", len(broken))
    with pytest.raises(TypeError):  # a programming error is not dressed up as the user's problem
        ProfileStore(path)
    with sqlite3.connect(path) as conn:
        assert conn.execute("SELECT count(*) FROM sqlite_master WHERE name = 'half_done'").fetchone()[0] == 0
    conn.close()


def test_asset_paths_and_the_default_profile_path(tmp_path, monkeypatch):
    with ProfileStore(tmp_path / "p.db") as store:
        assert store.story_assets_dir("abc") == store.assets_dir / "abc"
        assert store.asset_path("abc", "voice.wav") == store.assets_dir / "abc" / "voice.wav"
        with pytest.raises(StorageError) as err:
            store.asset_path("abc", "../../x")
        assert str(err.value) == "story abc: unsafe asset name '../../x'"
        with pytest.raises(StorageError) as err:
            store.story_assets_dir("..")
        assert str(err.value) == "story id: unsafe asset name '..'"
    monkeypatch.setenv("STORYBEAM_HOME", str(tmp_path / "home"))
    assert storage.default_profile_path() == tmp_path / "home" / "profile.db"
    monkeypatch.delenv("STORYBEAM_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "user"))
    assert storage.default_profile_path() == tmp_path / "user" / ".storybeam" / "profile.db"


def test_packages_carry_only_the_narrations_the_story_uses(tmp_path):
    from app.story.model import Narration
    from app.story.narration import ASSET_PREFIX
    with ProfileStore(tmp_path / "p.db") as store:
        story = demo_story()
        store.save_story(story)
        store.put_asset(story.id, f"{ASSET_PREFIX}0123456789abcdef.wav", b"an old take")  # replaced, unused
        store.put_asset(story.id, "bg.png", b"png")
        pkg = store.export_package(story.id, tmp_path / "s.zip")
        with zipfile.ZipFile(pkg) as zf:
            assert sorted(zf.namelist()) == ["assets/bg.png", "manifest.json", "story.json"]
        story.scenes[0].narration = Narration(f"{ASSET_PREFIX}fedcba9876543210.wav", 1.0)  # not in the package
        story_bytes = json.dumps(story.to_dict()).encode()
        with zipfile.ZipFile(pkg) as zf:
            manifest = json.loads(zf.read("manifest.json"))
            bg = zf.read("assets/bg.png")
        for f in manifest["files"]:
            if f["name"] == "story.json":
                f.update(size=len(story_bytes), sha256=hashlib.sha256(story_bytes).hexdigest())
        bad = tmp_path / "bad.zip"
        _zip(bad, {"manifest.json": json.dumps(manifest).encode(), "story.json": story_bytes, "assets/bg.png": bg})
        with pytest.raises(StorageError) as err:
            store.import_package(bad)
        assert str(err.value) == (f"{bad}: scene 1 narration {ASSET_PREFIX}fedcba9876543210.wav: "
                                  "missing from the package")
