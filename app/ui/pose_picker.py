"""The motion picker's two new ways in: search by pose and the library's own groups.

* **Pose** — a :class:`~app.ui.pose_figure.PoseFigure` beside a grid of clip tiles; when the
  child lets go of a handle, the pose is searched (:class:`retrieval.library.PoseSearch`:
  the index's subsequence search, refined on the features) and the tiles show the clips
  that pass through it, each stick figure starting at the moment it does. Tapping a tile
  picks the clip for the selected character.
* **Groups** — the library clustered without labels (:func:`retrieval.library.group_folder`:
  kinetic energy per body part and the frame codes). A group is shown by its most common
  label when one of its clips has a label, else by a picture: the animated stick figure of
  its most typical clip. Tapping a group lists its clips as tiles.

Both need the library's features, codes and kinetic energy, which take a few seconds to
load: :class:`LibraryExtras` loads them once on a background thread; until then the
picker says it is getting ready and answers as soon as they are.
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from kivy.app import App
from kivy.clock import Clock
from kivy.metrics import dp
from kivy.uix.boxlayout import BoxLayout
from kivy.uix.modalview import ModalView

from app.services import BackgroundLoad
from app.ui.art import MOTION_COLOURS
from app.ui.clip_tiles import ClipTile, clip_tile_name, numbered_names
from app.ui.pose_figure import PoseFigure, PoseModel
from app.ui.widgets import IconButton, big_label, filled, tile_grid
from retrieval.errors import StoryBeamError

if TYPE_CHECKING:
    from retrieval.library import FolderGrouping, Match, PoseSearch

log = logging.getLogger(__name__)

TILE_DP = 150
RESULTS = 6  # clips shown for a pose
LIBRARY_FPS = 30.0


class LibraryExtras(BackgroundLoad):
    """The pose search and the groups of a motion folder, loaded once in the background.
    ``ready``, ``error`` and ``groups_error`` tell where loading stands; ``when_ready(callback)`` runs the
    callback (on the Kivy thread) once loading has finished, well or not."""

    thread_name = "storybeam-library-extras"

    def __init__(self, folder: str | Path):
        super().__init__()
        self.folder = Path(folder)
        self.pose_search: PoseSearch | None = None
        self.groups: FolderGrouping | None = None
        self.error: str | None = None  # why the pose search is unavailable
        self.groups_error: str | None = None  # why the groups are unavailable

    def _deliver(self, callback: Callable[[], object]) -> None:
        Clock.schedule_once(lambda dt: callback(), 0)

    def _work(self) -> None:
        """Build the pose search, then the groups, each on its own: a library too small
        to group can still be searched. Loading always ends (``ready``), whatever fails."""
        from retrieval.library import PoseSearch, group_folder  # deferred: the search stack loads off the UI thread
        try:
            self.pose_search = PoseSearch.build(self.folder, fps=LIBRARY_FPS)
        except (StoryBeamError, OSError, ValueError) as exc:
            self.error = str(exc)
            log.warning("pose search unavailable: %s", exc)
        try:
            self.groups = group_folder(self.folder, fps=LIBRARY_FPS)
        except (StoryBeamError, OSError, ValueError) as exc:
            self.groups_error = str(exc)
            log.warning("library groups unavailable: %s", exc)

    def search(self, model: PoseModel, k: int = RESULTS) -> list[Match]:
        """The clips passing closest through the figure's pose ([] until ready)."""
        if self.pose_search is None:
            return []
        return self.pose_search.search(model.features(self.pose_search.index.feature_set), k=k)

    def clip_frames(self, trial: str) -> int:
        """Frames of an indexed clip at the library's rate (1 when unknown)."""
        if self.pose_search is None:
            return 1
        return len(self.pose_search.features[self.pose_search.index.position(trial)])


def library_extras(app) -> LibraryExtras:
    """The app's one :class:`LibraryExtras`, over its catalogue's folder (made on first use)."""
    extras = getattr(app, "_library_extras", None)
    if extras is None or extras.folder != Path(app.catalog.motions_dir):
        extras = LibraryExtras(app.catalog.motions_dir)
        app._library_extras = extras
    extras.start()
    return extras


class PosePicker(ModalView):
    """Pose the figure, see the clips that pass through the pose, tap one to pick it.
    ``on_pick(label, trial)`` is called with the chosen clip."""

    def __init__(self, on_pick: Callable[[str, str], object], **kwargs):
        kwargs.setdefault("size_hint", (0.92, 0.94))
        super().__init__(**kwargs)
        app = App.get_running_app()
        self.t, self.on_pick = app.t, on_pick
        self.extras = library_extras(app)
        self.thumbs = app.motion_thumbnails()
        self.hits: list[Match] = []
        self.tiles: list[ClipTile] = []
        self.searches = 0
        box = filled(BoxLayout(orientation="vertical", padding=dp(12), spacing=dp(8)), (0.93, 0.97, 1, 1))
        self.title = big_label(self.t("pose_title"), 22)
        box.add_widget(self.title)
        row = BoxLayout(spacing=dp(12))
        self.figure = PoseFigure(on_pose=self._searched, size_hint_x=0.42)
        row.add_widget(filled(self.figure, (1, 1, 1, 1)))
        right = BoxLayout(orientation="vertical", spacing=dp(6))
        self.status = big_label(self.t("pose_hint"), 16)
        right.add_widget(self.status)
        scroll, self.grid = tile_grid(2, TILE_DP)
        right.add_widget(scroll)
        row.add_widget(right)
        box.add_widget(row)
        box.add_widget(IconButton("delete", self.t("back"), on_press=self.dismiss, size_hint_y=None, height=dp(64)))
        self.add_widget(box)
        if not self.extras.ready:
            self.status.text = self.t("library_loading")
        self.extras.when_ready(lambda: self._searched(self.figure.model))

    def _searched(self, model: PoseModel) -> None:
        if not self.extras.ready:
            return  # searched once loading ends (when_ready)
        if self.extras.error is not None:
            self.status.text = self.t("no_clips")
            return
        self.hits = self.extras.search(model)
        self.searches += 1
        self.status.text = self.t("pose_found") if self.hits else self.t("no_clips")
        self.grid.clear_widgets()
        self.tiles = []
        for h in self.hits:
            start = h.frame / max(self.extras.clip_frames(h.trial) - 1, 1)
            tile = ClipTile(h.trial, clip_tile_name(self.t, h.label, h.trial, App.get_running_app().catalog.number_of),
                            h.label if h.label in MOTION_COLOURS
                            else "more", MOTION_COLOURS.get(h.label, (0.4, 0.4, 0.4)), self.thumbs,
                            lambda h=h: self._pick(h), start=start)
            self.tiles.append(tile)
            self.grid.add_widget(tile)

    def _pick(self, hit: Match) -> None:
        self.dismiss()
        self.on_pick(hit.label, hit.trial)


class GroupBrowser(ModalView):
    """The library's own groups as big tiles (a label's name, or a picture); tapping one
    lists its clips; tapping a clip calls ``on_pick(label, trial)``."""

    def __init__(self, on_pick: Callable[[str, str], object], **kwargs):
        kwargs.setdefault("size_hint", (0.86, 0.92))
        super().__init__(**kwargs)
        app = App.get_running_app()
        self.t, self.on_pick = app.t, on_pick
        self.extras = library_extras(app)
        self.thumbs = app.motion_thumbnails()
        self.group_tiles: list[ClipTile] = []
        self.clip_tiles: list[ClipTile] = []
        self.opened_group: int | None = None
        box = filled(BoxLayout(orientation="vertical", padding=dp(16), spacing=dp(10)), (0.95, 1, 0.93, 1))
        self.title = big_label(self.t("groups_title"), 24)
        box.add_widget(self.title)
        scroll, self.grid = tile_grid(3, TILE_DP)
        box.add_widget(scroll)
        self.back_button = IconButton("delete", self.t("back"), on_press=self._back, size_hint_y=None,
                                      height=dp(64))
        box.add_widget(self.back_button)
        self.add_widget(box)
        if not self.extras.ready:
            self.grid.add_widget(big_label(self.t("library_loading"), 20))
        self.extras.when_ready(self.show_groups)

    def group_name(self, number: int) -> str:
        """A group's name: its class ("Kick"), numbered where two groups share one
        ("Kick 1", "Kick 2"); an unnamed group is "Group N"."""
        names = [self.t("group_n", n=g.number + 1) if g.name is None
                 else self.t(f"motion_{g.name}") if g.name in MOTION_COLOURS else g.name
                 for g in self.extras.groups.grouping.groups]
        return numbered_names(names)[number]

    def show_groups(self) -> None:
        self.opened_group = None
        self.title.text = self.t("groups_title")
        self.grid.clear_widgets()
        self.group_tiles, self.clip_tiles = [], []
        if self.extras.groups is None:
            self.grid.add_widget(big_label(self.t("no_clips"), 20))
            return
        for grp in self.extras.groups.grouping.groups:
            label = f"{self.group_name(grp.number)} ({len(grp.members)})"
            if grp.name is not None:  # named: the label's icon
                tile = ClipTile(grp.representative, label, grp.name if grp.name in MOTION_COLOURS else "more",
                                MOTION_COLOURS.get(grp.name, (0.4, 0.4, 0.4)), None,
                                lambda n=grp.number: self.show_group(n))
            else:  # no label: a picture of its most typical clip
                tile = ClipTile(grp.representative, label, "more", (0.4, 0.4, 0.4), self.thumbs,
                                lambda n=grp.number: self.show_group(n))
            self.group_tiles.append(tile)
            self.grid.add_widget(tile)

    def show_group(self, number: int) -> None:
        grouping = self.extras.groups
        grp = grouping.grouping.groups[number]
        self.opened_group = number
        self.title.text = self.group_name(number)
        self.grid.clear_widgets()
        self.group_tiles, self.clip_tiles = [], []
        for i in grp.members:
            trial, label = grouping.trials[i], grouping.labels[i]
            tile = ClipTile(trial, clip_tile_name(self.t, label, trial, App.get_running_app().catalog.number_of),
                            label if label in MOTION_COLOURS else "more",
                            MOTION_COLOURS.get(label, (0.4, 0.4, 0.4)), self.thumbs,
                            lambda trial=trial, label=label: self._pick(label, trial))
            self.clip_tiles.append(tile)
            self.grid.add_widget(tile)

    def _back(self) -> None:
        if self.opened_group is not None:
            self.show_groups()
        else:
            self.dismiss()

    def _pick(self, label: str, trial: str) -> None:
        self.dismiss()
        self.on_pick(label, trial)
