"""Clip matchers: each turns reference clips into a searchable form (``fit`` = index
building) and answers ``distances(query)`` = one DTW distance per reference (search).

The seed's method lives here (:class:`QuantizedMatcher`); the research's baselines are in
:mod:`lab.experiment.baselines`. All share this interface so the evaluation times exactly the
same phases for every method: ``fit`` is building, ``distances`` (including turning the
query's features into codes) is search.
"""
from __future__ import annotations

from typing import Protocol, Sequence

import numpy as np

from retrieval.codes import MAX_FULL_DIMS, DiffTable, Quantizer, SplitTable
from retrieval.dtw import dtw_codes
from retrieval.errors import StoryBeamError
from retrieval.library import SHORTLIST, SUMMARY, Clip, StoryBeamSearcher
from retrieval.search import FastSearcher, SearchStats


class Matcher(Protocol):
    name: str

    def fit(self, references: Sequence[Clip]) -> "Matcher": ...

    def distances(self, query: Clip) -> np.ndarray: ...


class MatcherError(StoryBeamError):
    """A matcher was used before fitting or on unsuitable clips."""


def stack_frames(arrays: Sequence[np.ndarray]) -> np.ndarray:
    if not arrays:
        raise MatcherError("no reference clips to fit on")
    return np.concatenate(arrays, axis=0)


class QuantizedMatcher:
    """The research's method: PCA (n components) + 2-bit codes + table-look-up DTW."""

    name = "quantized"

    def __init__(self, dims: int = 6, band: int | None = None, backend: str = "auto",
                 max_full_dims: int = MAX_FULL_DIMS):
        self.dims = dims
        self.band = band
        self.backend = backend
        self.max_full_dims = max_full_dims
        self.quantizer: Quantizer | None = None
        self.table: np.ndarray | SplitTable | None = None
        self.reference_codes: list[np.ndarray] = []

    def fit(self, references: Sequence[Clip]) -> "QuantizedMatcher":
        self.quantizer = Quantizer.fit(stack_frames([c.features for c in references]), self.dims)
        self.table = self.quantizer.table(self.max_full_dims)
        self.reference_codes = [self.quantizer.encode(c.features) for c in references]
        return self

    @classmethod
    def from_quantizer(cls, quantizer: Quantizer, reference_codes: list[np.ndarray], band: int | None = None,
                       backend: str = "auto") -> "QuantizedMatcher":
        m = cls(quantizer.n, band, backend)
        m.quantizer = quantizer
        m.table = quantizer.table(m.max_full_dims)
        m.reference_codes = reference_codes
        return m

    def encode(self, features: np.ndarray) -> np.ndarray:
        if self.quantizer is None:
            raise MatcherError("quantized matcher used before fit()")
        return self.quantizer.encode(features)

    def distances(self, query: Clip | np.ndarray) -> np.ndarray:
        feats = query.features if isinstance(query, Clip) else query
        codes = self.encode(feats)
        return np.array([dtw_codes(codes, r, self.table, self.band, self.backend) for r in self.reference_codes])


class FastMatcher:
    """:class:`~retrieval.search.fast.FastSearcher` behind the evaluation's matcher
    interface. ``distances`` returns inf for every reference but the nearest, whose
    distance is exact — enough for the 1-NN protocol's argmin.

    Its distances are those of :class:`QuantizedMatcher` (bit-identical: the difference
    table reproduces the seed's table exactly); only the work to find the nearest differs
    (lower bounds, early abandoning, run-length DTW). Registered as "quantized-fast".
    """

    def __init__(self, name: str = "quantized-fast", dims: int = 6, band: int | None = None, mode: str = "exact",
                 run_length: bool = True, use_bounds: bool = True, parallel: bool = False,
                 backend: str = "auto"):
        self.name = name
        self.backend = backend
        self.dims = dims
        self.band = band
        self.mode = mode
        self.run_length = run_length
        self.use_bounds = use_bounds
        self.parallel = parallel
        self.quantizer: Quantizer | None = None
        self.searcher: FastSearcher | None = None
        self.stats = SearchStats()

    def fit(self, references: Sequence[Clip]) -> "FastMatcher":
        self.quantizer = Quantizer.fit(stack_frames([c.features for c in references]), self.dims)
        table = DiffTable.from_ratios(self.quantizer.ratios)
        codes = [self.quantizer.encode(c.features) for c in references]
        self.searcher = FastSearcher(codes, table, band=self.band, mode=self.mode,
                                     run_length=self.run_length, use_bounds=self.use_bounds,
                                     backend=self.backend)
        return self

    def distances(self, query: Clip) -> np.ndarray:
        if self.searcher is None or self.quantizer is None:
            raise MatcherError("fast matcher used before fit()")
        res = self.searcher.search([self.quantizer.encode(query.features)], k=1, parallel=self.parallel)
        self.stats.add(np.array([res.stats.candidates, res.stats.pruned, res.stats.abandoned, res.stats.completed,
                                 res.stats.range_rejected]))
        out = np.full(len(self.searcher), np.inf)
        out[res.indices[0, 0]] = res.distances[0, 0]
        return out


class StoryBeamMatcher:
    """StoryBeam's own method (:class:`~retrieval.library.StoryBeamSearcher`): the
    ``shortlist`` nearest references by the seed's code DTW (exact fast search) and
    ``summary`` of them by clip summary (:func:`~retrieval.library.clip_summary`), re-ranked
    by exact DTW on the float features. ``distances`` returns the exact float-DTW
    distance of the nearest re-ranked reference and inf for every other one — enough for
    the 1-NN protocol's argmin. Registered as "storybeam"; it runs on whatever features
    the clips carry (the evaluation gives it the ``"storybeam"`` feature set), its codes on
    the first ``code_columns`` of them (None: all; the set's ``code_columns``)."""

    name = "storybeam"

    def __init__(self, dims: int = 6, band: int | None = None, shortlist: int = SHORTLIST, backend: str = "auto",
                 summary: int = SUMMARY, code_columns: int | None = None):
        self.dims = dims
        self.code_columns = code_columns
        self.band = band
        self.shortlist = shortlist
        self.summary = summary
        self.backend = backend
        self.searcher: StoryBeamSearcher | None = None
        self.shortlist_cells = 0

    def fit(self, references: Sequence[Clip]) -> "StoryBeamMatcher":
        if not references:
            raise MatcherError("no reference clips to fit on")
        self.searcher = StoryBeamSearcher.fit([c.features for c in references], self.dims, self.shortlist,
                                              self.band, self.backend, summary=self.summary,
                                              code_columns=self.code_columns)
        return self

    def distances(self, query: Clip) -> np.ndarray:
        if self.searcher is None:
            raise MatcherError("storybeam matcher used before fit()")
        hits = self.searcher.search(query.features, k=1)
        out = np.full(len(self.searcher), np.inf)
        out[hits[0].index] = hits[0].distance
        return out
