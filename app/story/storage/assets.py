"""Story assets (custom backgrounds, thumbnails, narrations): files in a folder beside the
profile database (``<name>.assets/<story id>/<asset name>``), each written durably."""
from __future__ import annotations

import re
from pathlib import Path

from app.story.storage.database import StorageError, atomic_write
from retrieval.durable import clean_temporaries, make_dirs, remove_tree

ASSET_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


def check_asset_name(name: str, where: str) -> None:
    """Refuse a story id or asset name that is not one safe path component
    (:data:`ASSET_NAME`, no ``..``)."""
    if not isinstance(name, str) or not ASSET_NAME.match(name) or ".." in name:
        raise StorageError(f"{where}: unsafe asset name {name!r}")


class AssetFolder:
    """The assets folder of one profile: one subfolder per story, created on first write."""

    def __init__(self, assets_dir: Path):
        self.assets_dir = assets_dir

    def clean_leftovers(self) -> int:
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

    def story_folder(self, story_id: str) -> Path:
        """The folder of a story's assets (it may not exist yet); the id is checked."""
        check_asset_name(story_id, "story id")
        return self.assets_dir / story_id

    def ensure(self) -> Path:
        """The assets folder, created (durably) if missing."""
        return make_dirs(self.assets_dir)

    def put(self, story_id: str, name: str, data: bytes) -> Path:
        """Store an asset file (e.g. a custom background PNG) for a story."""
        check_asset_name(name, f"story {story_id}")
        path = self.story_folder(story_id) / name
        atomic_write(path, data)
        return path

    def path(self, story_id: str, name: str) -> Path:
        """Where a story's asset file is (e.g. a narration, for a player that wants a path)."""
        check_asset_name(name, f"story {story_id}")
        return self.story_folder(story_id) / name

    def names(self, story_id: str) -> list[str]:
        """A story's asset names, sorted (hidden temporaries left out)."""
        folder = self.story_folder(story_id)
        if not folder.is_dir():
            return []
        return sorted(p.name for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))

    def read(self, story_id: str, name: str) -> bytes:
        """The bytes of a story's asset; :class:`StorageError` when there is none."""
        check_asset_name(name, f"story {story_id}")
        path = self.story_folder(story_id) / name
        if not path.is_file():
            raise StorageError(f"{path}: no such asset")
        return path.read_bytes()

    def remove_story(self, story_id: str) -> None:
        """Remove a story's asset folder (after its row is deleted)."""
        remove_tree(self.story_folder(story_id))
