"""Exact subsequence search over a library: which clips pass through a short query, and where.

For every clip the answer is the open-begin / open-end DTW of
:func:`retrieval.dtw.find_subsequence` (the query may start and end at any frame of the
clip; distance = raw cost / (query frames + matched frames)). The search returns the
``k`` clips with the smallest such distance, ties by the lower library index — exactly
what :func:`retrieval.search.reference.brute_force_subsequence` returns — but it skips
most clips without running their DP:

* **bound** — every query frame is aligned with at least one clip frame, so the raw cost
  is at least ``Σ_i min_j D[q_i, b_j]`` (the query's envelope over the clip's distinct
  codes) and the matched span is at most the clip's length: ``raw / (x + ny)`` with that
  sum is a lower bound of the clip's distance;
* clips are visited in increasing bound order and the search stops at the first bound
  above the current k-th best distance (the rest cannot enter the answer).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from retrieval.codes import DiffTable
from retrieval.dtw import DTWError, envelope_sums, find_subsequence
from retrieval.search.results import Hit


class SubsequenceSearcher:
    """k best clips for a short query, by subsequence DTW over codes (see module docstring)."""

    def __init__(self, library: Sequence[np.ndarray], table: DiffTable, backend: str = "auto"):
        if len(library) == 0:
            raise DTWError("no code sequences to search")
        self.library = [np.ascontiguousarray(c, dtype=np.int32) for c in library]
        self.table = table
        self.backend = backend
        self.last_completed = 0  # clips whose DP ran in the last search (the rest were pruned)

    def __len__(self) -> int:
        return len(self.library)

    def search(self, query: np.ndarray, k: int = 5) -> list[Hit]:
        if k < 1:
            raise DTWError(f"k must be >= 1, got {k}")
        q = np.ascontiguousarray(query, dtype=np.int32)
        if q.ndim != 1 or q.size == 0:
            raise DTWError(f"query codes must be a non-empty 1-D array, got shape {q.shape}")
        nx = len(q)
        bounds = np.array([envelope_sums(q, b, self.table)[0] / (nx + len(b)) for b in self.library])
        # the bound's float sums may round differently from the DP's: compare it shrunk by
        # a relative 1e-9 so a clip at exactly the k-th distance is never pruned
        bounds *= 1.0 - 1e-9
        best: list[tuple[float, int, int, int]] = []  # (distance, index, start, end)
        completed = 0
        for c in np.argsort(bounds, kind="stable"):
            if len(best) >= k and bounds[c] > best[-1][0]:
                break
            m = find_subsequence(q, self.library[c], self.table, self.backend)
            completed += 1
            best = sorted(best + [(m.distance, int(c), m.start, m.end)])[:k]
        self.last_completed = completed
        return [Hit(i, d, start=s, end=e) for d, i, s, e in best]
