"""What the library holds and answers: a labelled clip's features, and a search hit."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Clip:
    """One labelled clip, ready for matching: ``features`` (T, 17) relational features and,
    when asked for, ``pose`` (T, P) weighted pose-space vectors (only the Forbes–Fiume
    baseline reads them), at ``fps``; ``subject`` is the performer or style group from
    ``labels.csv`` (empty when unknown)."""

    trial: str
    label: str
    features: np.ndarray
    pose: np.ndarray | None
    fps: float
    source: str = ""
    subject: str = ""

    @property
    def n_frames(self) -> int:
        return int(self.features.shape[0])

    @property
    def seconds(self) -> float:
        return self.n_frames / self.fps


@dataclass(frozen=True)
class Match:
    """One answer of any search of the library: the clip's trial name and label and its
    distance to the query; and, where the search knows them,

    * ``start``, ``end``: the library frames ``[start, end)`` a subsequence search matched;
    * ``frame``, ``code_distance``: the clip's frame nearest to a pose query
      (:class:`~retrieval.library.PoseSearch`) and the code search's distance that found it;
    * ``subject``, ``clip_path``, ``start_s``, ``end_s``: the performer, the motion file and
      the part of the clip (seconds) an Act-it-out take matched
      (:class:`~retrieval.library.ActSearch`).

    ``as_dict`` gives the fields the search filled (the JSON of ``storybeam search``)."""

    trial: str
    label: str
    distance: float
    start: int | None = None
    end: int | None = None
    frame: int | None = None
    code_distance: float | None = None
    subject: str | None = None
    clip_path: str | None = None
    start_s: float | None = None
    end_s: float | None = None

    def as_dict(self) -> dict:
        out = {"trial": self.trial, "label": self.label, "distance": self.distance}
        if self.start is not None:
            out.update(start=self.start, end=self.end)
        for key in ("frame", "code_distance", "subject", "clip_path", "start_s", "end_s"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        return out
