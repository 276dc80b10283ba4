"""Story packages: a story and its assets as one zip (``manifest.json``, ``story.json``,
``assets/``), to move a story between devices.

A package is validated whole before anything is written (:func:`read_package`: sizes read
with a cap, safe names, a manifest listing exactly the files with their SHA-256); an import
makes its assets durable before the story row is committed (:meth:`PackageShelf.import_package`).
"""
from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
import zipfile
import zlib
from lzma import LZMAError
from pathlib import Path

from app.story.model import Story, StoryError, new_id
from app.story.narration import ASSET_PREFIX, NarrationError, check_package_narrations, referenced_assets
from app.story.storage.assets import AssetFolder, check_asset_name
from app.story.storage.database import StorageError, os_problem
from app.story.storage.stories import StoryShelf
from retrieval.durable import durable_file, durable_move, durable_tree, remove_tree

# Story package limits: checked before anything is written.
PACKAGE_FORMAT_NAME = "storybeam.package"
PACKAGE_FORMAT_VERSION = 1
MAX_PACKAGE_BYTES = 64 * 1024 * 1024
MAX_PACKAGE_ENTRIES = 200
MAX_ENTRY_BYTES = 16 * 1024 * 1024
MAX_UNCOMPRESSED_BYTES = 96 * 1024 * 1024


class PackageShelf:
    """Exports a saved story as a package and imports one as a new story."""

    def __init__(self, stories: StoryShelf, assets: AssetFolder):
        self._stories = stories
        self._assets = assets

    def export_package(self, story_id: str, zip_path: str | Path) -> Path:
        """Write a story and its assets as a zip: ``manifest.json``, ``story.json``, ``assets/``."""
        story = self._stories.load(story_id)
        story_bytes = json.dumps(story.to_dict(), ensure_ascii=False, indent=1).encode("utf-8")
        files = {"story.json": story_bytes}
        voices = referenced_assets(story)
        for name in self._assets.names(story_id):
            if name.startswith(ASSET_PREFIX) and name not in voices:
                continue  # a replaced or undone narration: not part of the story
            files[f"assets/{name}"] = self._assets.read(story_id, name)
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
            raise StorageError(f"{zip_path}: not exported ({os_problem(exc)})") from None
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
        if self._stories.has(story.id):
            story.id = new_id()
        final = self._assets.story_folder(story.id)
        staging: Path | None = None
        try:
            remove_tree(final)  # no story has this id: an orphan from an earlier import cut short
            if assets:
                staging = Path(tempfile.mkdtemp(prefix=".import-", dir=self._assets.ensure()))
                for name, data in assets.items():
                    (staging / name).write_bytes(data)
                durable_tree(staging)
                durable_move(staging, final)
                staging = None
        except OSError as exc:
            raise StorageError(f"{zip_path}: not imported ({os_problem(exc)})") from None
        finally:
            if staging is not None:
                shutil.rmtree(staging, ignore_errors=True)
        self._stories.save(story)
        return story


#: What a damaged zip can raise while opening or inflating an entry (found by the package
#: fuzzing in tests/test_robust_files.py: zlib.error and EOFError escaped before).
ZIP_READ_ERRORS = (zipfile.BadZipFile, OSError, RuntimeError, ValueError, EOFError, zlib.error, LZMAError)


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
    except ZIP_READ_ERRORS as exc:
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
                check_asset_name(tail, where)
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
            except ZIP_READ_ERRORS as exc:
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
