"""Exact nearest-clip search over code sequences: the fast k-NN search
(:class:`FastSearcher`: the API in :mod:`~retrieval.search.fast`, its compiled kernels and
their numpy twins in modules of their own), the summary shortlist over float features
(:mod:`~retrieval.search.summary`), the pruned subsequence search
(:class:`SubsequenceSearcher`) and the brute-force references they must equal
(:mod:`~retrieval.search.reference`)."""
from __future__ import annotations

from retrieval.search.fast import MODES, STAGES, FastSearcher, warm_up
from retrieval.search.packed import PackedCodes
from retrieval.search.results import Hit, SearchResult, SearchStats
from retrieval.search.reference import (
    brute_force,
    brute_force_runs,
    brute_force_subsequence,
)
from retrieval.search.subsequence import SubsequenceSearcher
from retrieval.search.summary import clip_summary, summary_nearest

__all__ = [
    "MODES",
    "STAGES",
    "PackedCodes",
    "SearchStats",
    "SearchResult",
    "FastSearcher",
    "warm_up",
    "Hit",
    "SubsequenceSearcher",
    "clip_summary",
    "summary_nearest",
    "brute_force",
    "brute_force_runs",
    "brute_force_subsequence",
]
