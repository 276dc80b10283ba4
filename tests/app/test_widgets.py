"""app.ui.widgets.newest_files: the listing behind the import picker and the narration picker."""
from __future__ import annotations

import os

from app.ui.import_picker import find_packages
from app.ui.narration import find_audio_files
from app.ui.widgets import newest_files


def _touch(path, mtime):
    path.write_bytes(b"x")
    os.utime(path, (mtime, mtime))
    return path


def test_newest_first_filtered_by_suffix_and_limited(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    old = _touch(a / "old.WAV", 1_000)
    new = _touch(b / "new.ogg", 3_000)
    mid = _touch(a / "mid.wav", 2_000)
    _touch(a / "notes.txt", 4_000)
    (a / "folder.wav").mkdir()  # a folder named like a file is not listed
    missing = tmp_path / "does-not-exist"
    assert newest_files([a, missing, b], (".wav", ".ogg")) == [new, mid, old]
    assert newest_files([a, b], (".wav", ".ogg"), limit=2) == [new, mid]
    assert find_audio_files([a, b]) == [new, mid, old]


def test_packages_listing(tmp_path):
    p1 = _touch(tmp_path / "one.zip", 10)
    p2 = _touch(tmp_path / "two.ZIP", 20)
    _touch(tmp_path / "three.wav", 30)
    assert find_packages([tmp_path]) == [p2, p1]
