"""Exact nearest-clip search over code sequences: the fast k-NN search
(:class:`FastSearcher`), the pruned subsequence search (:class:`SubsequenceSearcher`) and
the brute-force references they must equal (:mod:`~retrieval.search.reference`)."""
from __future__ import annotations

from retrieval.search.fast import (
    MODES,
    STAGES,
    FastSearcher,
    PackedCodes,
    SearchResult,
    SearchStats,
    runs_dtw_numpy,
    warm_up,
)
from retrieval.search.reference import (
    brute_force,
    brute_force_runs,
    brute_force_subsequence,
)
from retrieval.search.subsequence import SubsequenceHit, SubsequenceSearcher

__all__ = [
    "MODES",
    "STAGES",
    "PackedCodes",
    "SearchStats",
    "SearchResult",
    "FastSearcher",
    "runs_dtw_numpy",
    "warm_up",
    "SubsequenceHit",
    "SubsequenceSearcher",
    "brute_force",
    "brute_force_runs",
    "brute_force_subsequence",
]
