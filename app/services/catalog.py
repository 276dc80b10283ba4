"""Small interfaces between the app and the heavier parts (motion library, renderer).

The UI must start fast and keep working on a device where a part is missing (no numba on
Android, no pyrender, no bundled clips yet). Each service here answers from cheap data at
once and upgrades itself in the background when the heavy part is available.
"""
from __future__ import annotations

import csv
import logging
import threading
from dataclasses import dataclass
from pathlib import Path

from app.paths import MOTIONS_DIR
from retrieval.errors import IndexFormatError, StoryBeamError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ClipInfo:
    """One clip of the bundled library as the UI lists it."""

    trial: str
    label: str


class MotionCatalog:
    """The bundled motion library: clip names by class, and "more like this".

    ``labels.csv`` is read directly (cheap, no motion parsing) so the motion buttons are
    ready at start-up. "More like this" uses :class:`retrieval.library.MotionIndex` when it
    can be loaded (a saved index in ``<motions>/index``) or built in a background thread;
    until then it answers with other clips of the same class.
    """

    def __init__(self, motions_dir: str | Path = MOTIONS_DIR, build_index: bool = True):
        self.motions_dir = Path(motions_dir)
        self.clips: list[ClipInfo] = self._read_labels()
        self._index = None
        self._index_error: str | None = None
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._build_index = build_index

    def _read_labels(self) -> list[ClipInfo]:
        path = self.motions_dir / "labels.csv"
        if not path.is_file():
            return []
        try:
            with open(path, newline="", encoding="utf-8") as fh:
                return [ClipInfo(r["trial"].strip(), r["label"].strip()) for r in csv.DictReader(fh)
                        if (r.get("trial") or "").strip() and (r.get("label") or "").strip()]
        except (OSError, KeyError, UnicodeDecodeError, csv.Error) as exc:
            log.warning("motion library %s unreadable: %s", path, exc)
            return []

    @property
    def classes(self) -> list[str]:
        return sorted({c.label for c in self.clips})

    def clips_of(self, label: str) -> list[ClipInfo]:
        return [c for c in self.clips if c.label == label]

    def label_of(self, trial: str) -> str | None:
        return next((c.label for c in self.clips if c.trial == trial), None)

    def number_of(self, trial: str) -> int | None:
        """The clip's place among the clips of its class, from 1 (the library's order, so
        it never changes while the library does not), or None for a clip not in it. A
        window of a clip (``02_03@52``, an *Act it out* answer) is numbered as its clip."""
        base = trial.split("@", 1)[0]
        label = self.label_of(base)
        if label is None:
            return None
        return 1 + [c.trial for c in self.clips_of(label)].index(base)

    @property
    def index_ready(self) -> bool:
        return self._index is not None

    def start_index(self) -> None:
        """Load or build the retrieval index in a background thread (once)."""
        if not self._build_index or self._thread is not None or not self.clips:
            return
        self._thread = threading.Thread(target=self._load_index, name="storybeam-index", daemon=True)
        self._thread.start()

    def wait_index(self, timeout: float | None = None) -> bool:
        if self._thread is not None:
            self._thread.join(timeout)
        return self.index_ready

    def _load_index(self) -> None:
        try:
            # The search stack (numpy, numba kernels) is slow to import; it loads here, on the
            # index thread, so the motion buttons are ready at start-up without it.
            from retrieval.library import MotionIndex  # deferred: imported on the index thread, off the UI's start-up
            saved = self.motions_dir / "index"
            index = None
            if MotionIndex.is_index(saved):
                try:
                    index = MotionIndex.load(saved)
                except IndexFormatError as exc:  # saved by an older StoryBeam: built from the clips instead
                    log.warning("saved motion index not used, rebuilding: %s", exc)
            if index is None:
                index = MotionIndex.build(self.motions_dir)
            with self._lock:
                self._index = index
        except (StoryBeamError, ImportError, OSError, ValueError) as exc:
            self._index_error = str(exc)
            log.warning("motion index unavailable, 'more like this' lists same-class clips: %s", exc)

    def similar(self, trial_or_label: str, k: int = 8) -> list[ClipInfo]:
        """Clips like ``trial_or_label`` (a clip id, or a class name: its first clip)."""
        trial = trial_or_label
        anchor: list[ClipInfo] = []
        if self.label_of(trial) is None:  # a class: its first clip, then clips like it
            same = self.clips_of(trial_or_label)
            if not same:
                return []
            trial = same[0].trial
            anchor = [same[0]]
        with self._lock:
            index = self._index
        if index is not None:
            try:
                return (anchor + [ClipInfo(m.trial, m.label) for m in index.similar_to(trial, k)])[:k]
            except StoryBeamError as exc:
                log.warning("similar_to(%s) failed: %s", trial, exc)
        label = self.label_of(trial)
        others = [c for c in self.clips if c.label == label and c.trial != trial]
        return ([c for c in self.clips if c.trial == trial] + others)[:k]
