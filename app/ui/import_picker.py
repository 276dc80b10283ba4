"""Teacher mode: pick a story package to import by tapping it (no typing, no file dialog).

The picker lists the ``.zip`` files in the places a teacher is likely to put one
(:func:`package_folders`): the profile's inbox, an ``import`` folder beside the profile,
and the device's downloads folder. One big tile per package; a tap imports it through
:meth:`app.story.storage.ProfileStore.import_package`, which validates the whole package before
writing anything -- a bad package is refused with the storage layer's message and the
profile is left as it was.
"""
from __future__ import annotations

import os
from pathlib import Path

from kivy.app import App
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.label import Label
from kivy.uix.modalview import ModalView

from app.story import StorageError
from app.ui.widgets import IconButton, big_label, file_tiles, filled, newest_files

MAX_LISTED = 60  # a downloads folder can be big; the newest packages are listed first


def package_folders(db_path: Path) -> list[Path]:
    """Where packages are looked for, most specific first (missing folders are skipped)."""
    db_path = Path(db_path)
    folders = [db_path.with_name(db_path.name + ".inbox"), db_path.parent / "import"]
    home = Path(os.path.expanduser("~"))
    folders += [home / "Downloads", Path("/sdcard/Download")]  # desktop; Android's shared downloads
    seen, out = set(), []
    for folder in folders:
        key = str(folder.resolve()) if folder.exists() else str(folder)
        if key not in seen:
            seen.add(key)
            out.append(folder)
    return out


def find_packages(folders: list[Path]) -> list[Path]:
    """``.zip`` files in ``folders`` (not recursive), newest first."""
    return newest_files(folders, (".zip",), MAX_LISTED)


class ImportPicker(ModalView):
    """Big tiles, one per package found; tap to import. ``message`` holds the last result."""

    def __init__(self, on_done=None, **kwargs):
        kwargs.setdefault("size_hint", (0.8, 0.85))
        super().__init__(**kwargs)
        self.on_done = on_done
        self.message = ""
        self.tiles: dict[str, IconButton] = {}
        self.refresh()

    def refresh(self) -> None:
        app = App.get_running_app()
        t = app.t
        self.clear_widgets()
        folders = package_folders(app.db_path)
        packages = find_packages(folders)
        box = filled(BoxLayout(orientation="vertical", padding=dp(16), spacing=dp(10)), (0.95, 0.97, 1, 1))
        box.add_widget(big_label(t("import_pick"), 22))
        scroll, self.tiles = file_tiles(packages, lambda p: p.stem, self.pick,
                                        t("import_none", where="\n".join(str(f) for f in folders)),
                                        row_dp=120, font_dp=15, empty_dp=16)
        box.add_widget(scroll)
        self.status = Label(text=self.message, color=(0.1, 0.2, 0.1, 1), font_size=dp(15), size_hint_y=None,
                            height=dp(60), halign="center", valign="middle")
        self.status.bind(size=lambda lbl, s: setattr(lbl, "text_size", s))
        box.add_widget(self.status)
        self.close_button = IconButton("home", t("back"), on_press=self.dismiss, size_hint_y=None, height=dp(72))
        box.add_widget(self.close_button)
        self.add_widget(box)

    def pick(self, path: Path) -> None:
        """Import ``path``; the storage layer refuses a bad package before writing."""
        app = App.get_running_app()
        try:
            story = app.store.import_package(path)
        except StorageError as exc:
            self.message = str(exc)
            self.ok = False
        else:
            app.store.log_activity("import package", story.id, path.name)
            self.message = app.t("imported", title=story.title or story.id)
            self.ok = True
        self.status.text = self.message
        self.status.color = (0.1, 0.45, 0.1, 1) if self.ok else (0.75, 0.1, 0.1, 1)
        if self.on_done:
            self.on_done(self.message)
