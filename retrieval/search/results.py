"""What the searches over code sequences answer: one clip found, by library position
(:class:`Hit`, every search that answers clip by clip), a batch of k-nearest-neighbour
answers as arrays (:class:`SearchResult`, the fast search) and how much work the bounds
saved (:class:`SearchStats`)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class SearchStats:
    """How much work the bounds saved: candidates pruned by their bound, DTWs abandoned
    early, DTWs run to the end."""

    candidates: int = 0
    pruned: int = 0
    abandoned: int = 0
    completed: int = 0
    range_rejected: int = 0  # of the abandoned: rejected by the segment- or range-cover bound before the exact DTW

    @property
    def pruned_fraction(self) -> float:
        return self.pruned / self.candidates if self.candidates else 0.0

    @property
    def abandoned_fraction(self) -> float:
        return self.abandoned / self.candidates if self.candidates else 0.0

    def add(self, arr: np.ndarray) -> None:
        self.candidates += int(arr[0])
        self.pruned += int(arr[1])
        self.abandoned += int(arr[2])
        self.completed += int(arr[3])
        if len(arr) > 4:
            self.range_rejected += int(arr[4])

    def as_dict(self) -> dict:
        return {"candidates": self.candidates, "pruned": self.pruned, "abandoned": self.abandoned,
                "completed": self.completed, "range_rejected": self.range_rejected,
                "pruned_fraction": self.pruned_fraction,
                "abandoned_fraction": self.abandoned_fraction}


@dataclass
class SearchResult:
    """k nearest library indices and their normalised DTW distances per query."""

    indices: np.ndarray  # (queries, k) int64, -1 where the library has fewer than k clips
    distances: np.ndarray  # (queries, k) float64
    stats: SearchStats = field(default_factory=SearchStats)


@dataclass(frozen=True)
class Hit:
    """One clip found, by library position: its ``index`` and ``distance`` to the query,
    and as the search gives them the code DTW distance that shortlisted it
    (``code_distance``: StoryBeam's re-ranked search,
    :class:`~retrieval.library.StoryBeamSearcher`) or the clip's frames ``start``..``end``
    (inclusive) it matched (the subsequence search, :class:`~retrieval.search.SubsequenceSearcher`)."""

    index: int
    distance: float
    code_distance: float | None = None
    start: int | None = None
    end: int | None = None
