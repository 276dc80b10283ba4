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
    """One answer of a search: the clip's trial name and label, its distance to the query
    and, for a subsequence search, the library frames ``[start, end)`` it matched."""

    trial: str
    label: str
    distance: float
    start: int | None = None
    end: int | None = None

    def as_dict(self) -> dict:
        out = {"trial": self.trial, "label": self.label, "distance": self.distance}
        if self.start is not None:
            out.update(start=self.start, end=self.end)
        return out
