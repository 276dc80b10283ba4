"""OS failures injected *below* the store (issue 17, part 3: the storage group at 100 % of
branches, each path reached through the public API).

The other storage tests make a store-level name (``storage.database.durable_write``,
``storage.packages.durable_move``) raise. Here the failure comes from the operating system instead:
``os.fsync``, ``os.replace``, ``os.open`` (creating the temporary file) or ``os.mkdir``
raise ``OSError`` with ENOSPC, EACCES, EROFS or EIO while the real code path runs
(:mod:`retrieval.durable` under :class:`ProfileStore`, the packages and
:class:`CameraCalibration`). Each test asserts the exact message the user sees (the file,
then the problem), that the previous version is untouched, that no temporary file or
staging folder is left behind, and that the store works again once the disk does. The
tests run as root, so permissions are simulated rather than set with ``chmod``.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import retrieval.durable as durable
from app.story.demo_story import demo_story
from app.story.storage import ProfileStore, StorageError
from ar.calibration import CameraCalibration
from ar.errors import CalibrationError


class DiskFaults:
    """Make one OS call fail (a fresh ``OSError(code, strerror, path)`` each time) for
    the paths ``match`` accepts; ``hits`` lists the paths that failed, so a test can show
    the fault was really reached."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch):
        self._mp = monkeypatch
        self.hits: list[str] = []

    def _raise(self, code: int, path: str) -> None:
        self.hits.append(path)
        raise OSError(code, os.strerror(code), path)

    def fail(self, call: str, code: int, match: Callable[[str], bool] = lambda path: True) -> None:
        if call == "fsync":
            real_fsync = os.fsync

            def fsync(fd):
                path = os.readlink(f"/proc/self/fd/{fd}")
                if match(path):
                    self._raise(code, path)
                return real_fsync(fd)

            self._mp.setattr(os, "fsync", fsync)
        elif call == "replace":
            real_replace = os.replace

            def replace(src, dst, **kw):
                if match(os.fspath(dst)):
                    self._raise(code, os.fspath(dst))
                return real_replace(src, dst, **kw)

            self._mp.setattr(os, "replace", replace)
        elif call == "create":  # os.open with O_CREAT: tempfile.mkstemp's temporary file
            real_open = os.open

            def open_(path, flags, *args, **kw):
                if flags & os.O_CREAT and match(os.fspath(path)):
                    self._raise(code, os.fspath(path))
                return real_open(path, flags, *args, **kw)

            self._mp.setattr(os, "open", open_)
        elif call == "mkdir":
            real_mkdir = os.mkdir

            def mkdir(path, *args, **kw):
                if match(os.fspath(path)):
                    self._raise(code, os.fspath(path))
                return real_mkdir(path, *args, **kw)

            self._mp.setattr(os, "mkdir", mkdir)
        else:  # a typo in a test
            raise ValueError(call)

    def heal(self) -> None:
        """The disk works again."""
        self._mp.undo()


@pytest.fixture
def faults(monkeypatch):
    return DiskFaults(monkeypatch)


#: What the store says for each errno (app.story.storage.database.os_problem).
REASON = {
    errno.ENOSPC: "the device storage is full; free some space",
    errno.EACCES: "the folder cannot be written: Permission denied",
    errno.EROFS: "the folder cannot be written: Read-only file system",
    errno.EIO: "Input/output error",
}
#: (OS call, errno): each failing step of a durable write, with the errors a tablet meets.
WRITE_FAULTS = [("fsync", errno.ENOSPC), ("fsync", errno.EIO), ("replace", errno.EACCES), ("replace", errno.EIO),
                ("create", errno.EROFS), ("create", errno.ENOSPC)]


def _leftovers(folder: Path) -> list[str]:
    """Temporary files and staging folders under ``folder``."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                  if p.name.endswith(durable.TEMP_SUFFIX) or p.name.startswith(".import-"))


# ----------------------------------------------------------------------------- assets and the CSV


@pytest.mark.parametrize(("call", "code"), WRITE_FAULTS)
def test_an_asset_the_disk_refuses_keeps_the_old_one(tmp_path, faults, call, code):
    with ProfileStore(tmp_path / "p.db") as store:
        story = demo_story()
        store.save_story(story)
        path = store.put_asset(story.id, "bg.png", b"old png")
        faults.fail(call, code)
        with pytest.raises(StorageError) as err:
            store.put_asset(story.id, "bg.png", b"new png")
        assert str(err.value) == f"{path}: not saved ({REASON[code]})"
        assert faults.hits
        assert store.read_asset(story.id, "bg.png") == b"old png"
        assert _leftovers(store.assets_dir) == []
        faults.heal()
        store.put_asset(story.id, "bg.png", b"new png")
        assert store.read_asset(story.id, "bg.png") == b"new png"


def test_a_failed_folder_fsync_after_the_rename_is_reported_not_hidden(tmp_path, faults):
    """The rename happened but the disk refused to make it durable: the user is told the
    asset was not saved (it may not survive a power cut), never that it was."""
    with ProfileStore(tmp_path / "p.db") as store:
        story = demo_story()
        store.save_story(story)
        folder = store.story_assets_dir(story.id)
        store.put_asset(story.id, "bg.png", b"old png")
        faults.fail("fsync", errno.EIO, match=lambda path: path == str(folder))
        with pytest.raises(StorageError) as err:
            store.put_asset(story.id, "bg.png", b"new png")
        assert str(err.value) == f"{folder / 'bg.png'}: not saved (Input/output error)"
        assert faults.hits == [str(folder)]
        assert _leftovers(store.assets_dir) == []


def test_a_new_story_folder_the_disk_refuses(tmp_path, faults):
    with ProfileStore(tmp_path / "p.db") as store:
        story = demo_story()
        store.save_story(story)
        faults.fail("mkdir", errno.EACCES)
        with pytest.raises(StorageError) as err:
            store.put_asset(story.id, "bg.png", b"png")
        assert str(err.value) == \
            f"{store.assets_dir / story.id / 'bg.png'}: not saved (the folder cannot be written: Permission denied)"
        assert faults.hits and store.asset_names(story.id) == []


@pytest.mark.parametrize(("call", "code"), [("fsync", errno.ENOSPC), ("replace", errno.EROFS)])
def test_an_activity_csv_the_disk_refuses_keeps_the_old_export(tmp_path, faults, call, code):
    out = tmp_path / "class" / "activity.csv"
    with ProfileStore(tmp_path / "p.db") as store:
        store.set_activity_logging(True)
        store.log_activity("story_opened", "s1")
        assert store.export_activity_csv(out) == 1
        old = out.read_bytes()
        store.log_activity("story_opened", "s2")
        faults.fail(call, code)
        with pytest.raises(StorageError) as err:
            store.export_activity_csv(out)
        assert str(err.value) == f"{out}: not saved ({REASON[code]})"
    assert out.read_bytes() == old and _leftovers(out.parent) == []


# ----------------------------------------------------------------------------- packages


@pytest.mark.parametrize(("call", "code"), WRITE_FAULTS)
def test_an_export_the_disk_refuses_keeps_the_old_package(tmp_path, faults, call, code):
    out = tmp_path / "usb" / "story.zip"
    with ProfileStore(tmp_path / "p.db") as store:
        story = demo_story()
        store.save_story(story)
        store.put_asset(story.id, "bg.png", b"png")
        store.export_package(story.id, out)
        old = out.read_bytes()
        story.title = "changed"
        store.save_story(story)
        faults.fail(call, code)
        with pytest.raises(StorageError) as err:
            store.export_package(story.id, out)
        assert str(err.value) == f"{out}: not exported ({REASON[code]})"
        assert faults.hits
        faults.heal()
        assert out.read_bytes() == old and _leftovers(out.parent) == []
        store.export_package(story.id, out)
    with ProfileStore(tmp_path / "q.db") as other:
        assert other.import_package(out).title == "changed"


@pytest.fixture
def package(tmp_path) -> tuple[Path, str]:
    """A package with two assets, and its story's id."""
    with ProfileStore(tmp_path / "src.db") as src:
        story = demo_story()
        src.save_story(story)
        src.put_asset(story.id, "bg.png", b"png bytes")
        src.put_asset(story.id, "thumb.png", b"thumb bytes")
        return src.export_package(story.id, tmp_path / "story.zip"), story.id


@pytest.mark.parametrize(("call", "code"), [("fsync", errno.EIO), ("fsync", errno.ENOSPC), ("replace", errno.EACCES),
                                            ("replace", errno.EIO), ("mkdir", errno.EROFS)])
def test_an_import_the_disk_refuses_adds_nothing_and_leaves_no_staging(tmp_path, faults, package, call, code):
    """A failure anywhere before the commit (staging folder, file or folder fsync, the
    rename into place) adds no story and leaves no staging folder or orphan asset folder;
    once the disk works the same package imports with its assets."""
    zip_path, story_id = package
    db = tmp_path / "dst.db"
    with ProfileStore(db) as dst:
        dst.put_asset("other", "keep.png", b"another story's asset")  # the assets folder exists
        faults.fail(call, code)
        with pytest.raises(StorageError) as err:
            dst.import_package(zip_path)
        assert str(err.value) == f"{zip_path}: not imported ({REASON[code]})"
        assert faults.hits
        faults.heal()
        assert dst.list_stories() == []
        assert sorted(p.name for p in dst.assets_dir.iterdir()) == ["other"]
    with ProfileStore(db) as dst:
        assert dst.leftovers_removed == 0
        imported = dst.import_package(zip_path)
        assert imported.id == story_id
        assert dst.read_asset(story_id, "bg.png") == b"png bytes"
        assert dst.read_asset(story_id, "thumb.png") == b"thumb bytes"
        assert _leftovers(dst.assets_dir) == []


def test_a_staging_folder_a_crash_left_is_removed_at_open_and_the_import_then_works(tmp_path, package):
    """The state a kill between the staging writes and the rename leaves (a ``.import-*``
    folder, no story row): the next open removes it, and the import can be done again."""
    zip_path, story_id = package
    db = tmp_path / "dst.db"
    with ProfileStore(db) as dst:
        staging = dst.assets_dir / ".import-a1b2c3d4"
        staging.mkdir(parents=True)
        (staging / "bg.png").write_bytes(b"png by")  # cut mid-write
        (staging / f".thumb.png.abcd1234{durable.TEMP_SUFFIX}").write_bytes(b"")
    with ProfileStore(db) as dst:
        assert dst.leftovers_removed == 2  # the temporary inside it, then the staging folder
        assert list(dst.assets_dir.iterdir()) == []
        assert dst.import_package(zip_path).id == story_id
        assert dst.read_asset(story_id, "bg.png") == b"png bytes"


# ----------------------------------------------------------------------------- calibration


def _calibration(f: float) -> CameraCalibration:
    K = np.array([[f, 0.0, 320.0], [0.0, f, 240.0], [0.0, 0.0, 1.0]])
    return CameraCalibration(K, np.zeros(5), (640, 480), 0.2, {}, {}, "charuco")


@pytest.mark.parametrize(("call", "code"), WRITE_FAULTS + [("mkdir", errno.EROFS)])
def test_a_calibration_save_the_disk_refuses_keeps_the_old_calibration(tmp_path, faults, call, code):
    path = tmp_path / "rig" / "camera.json"
    if call != "mkdir":
        _calibration(600.0).save(path)
    faults.fail(call, code)
    with pytest.raises(CalibrationError) as err:
        _calibration(700.0).save(path)
    assert str(err.value) == f"{path}: cannot write: {os.strerror(code)}"
    assert err.value.path == str(path) and faults.hits
    faults.heal()
    if call == "mkdir":
        assert not path.parent.exists()
    else:
        assert CameraCalibration.load(path).camera_matrix[0, 0] == 600.0
        assert _leftovers(path.parent) == []
    _calibration(700.0).save(path)
    assert CameraCalibration.load(path).camera_matrix[0, 0] == 700.0


# ----------------------------------------------------------------------------- durable writes


def test_a_temporary_that_cannot_be_removed_does_not_hide_the_first_error(tmp_path, faults, monkeypatch):
    """The rename fails (EIO) and so does removing the temporary (EACCES): the caller sees
    the rename's error, and the next write of the same file removes the stale temporary."""
    target = tmp_path / "camera.json"
    durable.durable_write(target, b"old")
    faults.fail("replace", errno.EIO)
    real_unlink = os.unlink

    def unlink(path, *a, **k):
        raise OSError(errno.EACCES, os.strerror(errno.EACCES), path)

    monkeypatch.setattr(os, "unlink", unlink)
    with pytest.raises(OSError) as err:
        durable.durable_write(target, b"new")
    assert err.value.errno == errno.EIO
    stale = _leftovers(tmp_path)
    assert len(stale) == 1 and stale[0].startswith(".camera.json.")
    faults.heal()
    assert os.unlink is real_unlink
    durable.durable_write(target, b"new")
    assert target.read_bytes() == b"new" and _leftovers(tmp_path) == []


def test_folder_fsync_is_skipped_where_folders_cannot_be_opened(tmp_path, monkeypatch):
    """On Windows a folder cannot be opened for fsync: fsync_dir does nothing there."""
    opened: list[str] = []
    real_open = os.open
    monkeypatch.setattr(os, "open", lambda path, *a, **k: (opened.append(os.fspath(path)), real_open(path, *a, **k))[1])
    durable.fsync_dir(tmp_path)
    assert opened == [str(tmp_path)]  # POSIX: the folder is opened and fsynced
    opened.clear()
    with monkeypatch.context() as windows:  # os.name restored before pytest reports (it makes paths)
        windows.setattr(os, "name", "nt")
        durable.fsync_dir(tmp_path)
    assert opened == []
