"""Saving a finished story's video where the child's family can find it, and sharing it.

Behind one small interface (:class:`Gallery`: ``save(video, name) -> SavedVideo``,
``share(saved) -> bool``), chosen by platform (:func:`gallery_for`):

* :class:`DesktopGallery` -- a file in the user's videos folder: ``$XDG_VIDEOS_DIR`` (or
  the ``VIDEOS`` line of ``~/.config/user-dirs.dirs``), ``~/Videos``, ``~/Movies`` (macOS),
  else the app's export folder, under ``StoryBeam/``; copied through the durable write
  (:mod:`retrieval.durable`: a temporary file, fsync, rename, fsync of the folder), never
  over an existing video (``name (2).mp4``...). ``share`` opens the folder where a desktop
  can (``xdg-open``/``open``), else says it cannot.
* :class:`AndroidGallery` -- the shared *Movies* collection through MediaStore (pyjnius):
  a ``ContentValues`` row (``DISPLAY_NAME``, ``MIME_TYPE`` video/mp4,
  ``RELATIVE_PATH`` ``Movies/StoryBeam``, ``IS_PENDING`` 1) inserted into
  ``MediaStore.Video.Media.EXTERNAL_CONTENT_URI``, the bytes written through the resolver's
  output stream, then ``IS_PENDING`` 0 so the gallery sees a complete file; ``share`` sends
  the content URI to the system share sheet (``Intent.ACTION_SEND``, ``video/mp4``,
  ``EXTRA_STREAM``, read permission granted). Written for Android 10+ (API 29, scoped
  storage, no storage permission needed). **Untested on a real tablet** (no device here):
  see docs/guide/app.md, "Saving a story's video".

The teacher's switch: the profile setting :data:`VIDEO_SAVE_SETTING` (``on`` by default).
No Kivy here.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from retrieval.durable import durable_file, make_dirs
from retrieval.errors import StoryBeamError

VIDEO_SAVE_SETTING = "video_saving"
SUBFOLDER = "StoryBeam"


class GalleryError(StoryBeamError):
    """The video could not be saved or shared."""


def video_saving_allowed(store) -> bool:
    """Whether children may save their story's video (the teacher's switch; on by default)."""
    return store.get_setting(VIDEO_SAVE_SETTING, "on") != "off"


def set_video_saving_allowed(store, allowed: bool) -> None:
    store.set_setting(VIDEO_SAVE_SETTING, "on" if allowed else "off")


@dataclass
class SavedVideo:
    """Where a saved video is: a file path (desktop) or a ``content://`` URI (Android)."""

    location: str
    uri: object = None  # the Android Uri object, for sharing


def safe_name(name: str) -> str:
    """A file name from a story's title: letters (any script), digits, spaces, - and _."""
    cleaned = re.sub(r"[^\w \-]", "", name, flags=re.UNICODE).strip()[:60]
    return cleaned or "story"


class Gallery:
    """Save a finished video where people find it; share it."""

    def save(self, video: Path, name: str) -> SavedVideo:
        raise NotImplementedError

    def share(self, saved: SavedVideo) -> bool:
        return False


def videos_folder(home: Path | None = None, env: dict | None = None) -> Path | None:
    """The user's videos folder (XDG, then ~/Videos, then ~/Movies), or None."""
    env = os.environ if env is None else env
    home = Path(home or Path.home())
    xdg = env.get("XDG_VIDEOS_DIR")
    if not xdg:
        dirs = home / ".config" / "user-dirs.dirs"
        try:
            for line in dirs.read_text(encoding="utf-8").splitlines():
                if line.startswith("XDG_VIDEOS_DIR="):
                    xdg = line.split("=", 1)[1].strip().strip('"').replace("$HOME", str(home))
        except OSError:
            pass
    candidates = ([Path(xdg)] if xdg else []) + [home / "Videos", home / "Movies"]
    for folder in candidates:
        if folder.is_dir() and folder != home:
            return folder
    return None


class DesktopGallery(Gallery):
    """A file under the user's videos folder (or ``fallback``), in ``StoryBeam/``."""

    def __init__(self, fallback: Path, home: Path | None = None, env: dict | None = None):
        base = videos_folder(home, env)
        self.folder = (base / SUBFOLDER) if base is not None else Path(fallback)

    def save(self, video: Path, name: str) -> SavedVideo:
        try:
            make_dirs(self.folder)
            stem = safe_name(name)
            target = self.folder / f"{stem}.mp4"
            k = 2
            while target.exists():
                target = self.folder / f"{stem} ({k}).mp4"
                k += 1
            with open(video, "rb") as src, durable_file(target) as dst:
                shutil.copyfileobj(src, dst, 1 << 20)
        except OSError as exc:
            raise GalleryError(f"{self.folder}: the video could not be saved ({exc.strerror or exc})") from None
        return SavedVideo(str(target))

    def share(self, saved: SavedVideo) -> bool:
        opener = "open" if sys.platform == "darwin" else "xdg-open"
        if shutil.which(opener) is None:
            return False
        subprocess.Popen([opener, str(Path(saved.location).parent)], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
        return True


class AndroidGallery(Gallery):
    """MediaStore's Movies collection and the share sheet (see the module docstring)."""

    def __init__(self) -> None:
        from jnius import autoclass  # optional: pyjnius (Android only)

        self._autoclass = autoclass
        self.activity = autoclass("org.kivy.android.PythonActivity").mActivity

    def save(self, video: Path, name: str) -> SavedVideo:
        ac = self._autoclass
        Media = ac("android.provider.MediaStore$Video$Media")
        MediaColumns = ac("android.provider.MediaStore$MediaColumns")
        values = ac("android.content.ContentValues")()
        values.put(MediaColumns.DISPLAY_NAME, f"{safe_name(name)}.mp4")
        values.put(MediaColumns.MIME_TYPE, "video/mp4")
        values.put(MediaColumns.RELATIVE_PATH, f"Movies/{SUBFOLDER}")
        values.put(MediaColumns.IS_PENDING, ac("java.lang.Integer")(1))
        resolver = self.activity.getContentResolver()
        uri = resolver.insert(Media.EXTERNAL_CONTENT_URI, values)
        if uri is None:
            raise GalleryError(f"{video}: the gallery refused the video")
        try:
            stream = resolver.openOutputStream(uri)
            with open(video, "rb") as src:
                while chunk := src.read(1 << 16):
                    stream.write(chunk)
            stream.close()
            done = ac("android.content.ContentValues")()
            done.put(MediaColumns.IS_PENDING, ac("java.lang.Integer")(0))
            resolver.update(uri, done, None, None)
        except Exception as exc:  # noqa: BLE001 - any Java exception: remove the half-written row
            resolver.delete(uri, None, None)
            raise GalleryError(f"{video}: the video could not be saved ({exc})") from None
        return SavedVideo(uri.toString(), uri)

    def share(self, saved: SavedVideo) -> bool:
        from jnius import cast  # optional: pyjnius (Android only)

        if saved.uri is None:
            return False
        Intent = self._autoclass("android.content.Intent")
        intent = Intent(Intent.ACTION_SEND)
        intent.setType("video/mp4")
        intent.putExtra(Intent.EXTRA_STREAM, cast("android.os.Parcelable", saved.uri))
        intent.addFlags(Intent.FLAG_GRANT_READ_URI_PERMISSION)
        self.activity.startActivity(Intent.createChooser(intent, None))
        return True


def gallery_for(platform: str, export_dir: Path) -> Gallery:
    """The gallery of ``platform`` (Kivy's ``kivy.utils.platform``)."""
    if platform == "android":
        return AndroidGallery()
    return DesktopGallery(export_dir)


__all__ = ["VIDEO_SAVE_SETTING", "SUBFOLDER", "GalleryError", "SavedVideo", "Gallery", "DesktopGallery",
           "AndroidGallery", "gallery_for", "videos_folder", "safe_name", "video_saving_allowed",
           "set_video_saving_allowed"]
