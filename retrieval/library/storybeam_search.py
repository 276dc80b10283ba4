"""StoryBeam's own retrieval method (``"storybeam"``): the seed's 2-bit codes find the
few nearest clips fast, exact DTW on the real-valued features ranks those few.

Method, for a query with features ``q`` (the ``"storybeam"`` feature set: MR17 plus the
turning rate, :mod:`retrieval.features.storybeam_set`):

1. **Shortlist.** PCA (``dims`` components) + the seed's 2-bit quantiser turn ``q`` into
   codes; the exact fast search (:class:`~retrieval.search.FastSearcher`, the 20 KiB
   difference table, lower bounds, early abandoning) returns the ``shortlist`` library
   clips nearest by look-up-table DTW (ties by library order).
2. **Re-rank.** Each shortlisted clip's distance is then exact DTW with Euclidean frame
   cost on the float features (:func:`~retrieval.dtw.dtw_features`, normalised by
   ``len(q) + len(r)``) — the same distance as the exact-DTW baseline on the same
   features — and the shortlist is sorted by it (ties: code distance, then library
   order). A candidate is abandoned as soon as its partial DTW exceeds the
   ``k``-th best so far, which changes no answer
   (:func:`~retrieval.library.rerank_kernel.dtw_features_abandon`: bit for bit the
   baseline's kernel otherwise). The matrix-product form
   (:func:`~retrieval.library.rerank_kernel.dtw_features_gemm`, 2.5× faster per cell with
   one BLAS thread) is not used: with OpenBLAS's default threads on a busy 2-core machine
   a bandai2 eval run's search took 26 s with it against about 1 s without.

What it guarantees: the answer is exact with respect to what is ranked — the ``k``
returned clips are the ``k`` nearest *by exact float DTW among the shortlist*, and their
distances are exact. It equals exact DTW over the whole library whenever the true
nearest clip is in the code shortlist; docs/results.md measures how often that holds
(the accuracy within 1 point of exact DTW) and what the shortlist size trades between
accuracy and speed. Saturation: quantised distances are coarse (several clips at 0.0
for a near-duplicate), and the float re-ranking breaks exactly those ties — "find this
clip" returns the clip itself first.

Cost: one fast code search plus at most ``shortlist`` float DTWs (fewer cells when
abandoned), against one float DTW per library clip for exact DTW; memory: the codes
(int32 per frame) plus the float features of the library (float32 on disk).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from retrieval.codes import DiffTable, Quantizer
from retrieval.errors import StoryBeamError
from retrieval.library.rerank_kernel import dtw_features_abandon
from retrieval.search import FastSearcher

#: Default number of code-nearest clips re-ranked by exact float DTW (the ablation in
#: docs/results.md: accuracy against speed).
SHORTLIST = 4

#: Default kept PCA components of the shortlist's codes (the seed's n).
DIMS = 6


@dataclass(frozen=True)
class Hit:
    """One re-ranked answer: library ``index``, exact float-DTW ``distance`` and the code
    DTW distance ``code_distance`` that shortlisted it."""

    index: int
    distance: float
    code_distance: float


class StoryBeamSearcher:
    """Code shortlist + exact float-DTW re-ranking over a fixed library (see the module
    docstring). ``features`` are the library's (frames, d) float features, ``codes``
    their codes under ``quantizer``."""

    def __init__(self, quantizer: Quantizer, codes: Sequence[np.ndarray], features: Sequence[np.ndarray],
                 shortlist: int = SHORTLIST, band: int | None = None, backend: str = "auto",
                 searcher: FastSearcher | None = None):
        if len(codes) != len(features) or not codes:
            raise StoryBeamError("storybeam search: codes and features must be non-empty and of equal length")
        if shortlist < 1:
            raise StoryBeamError(f"storybeam search: shortlist must be >= 1, got {shortlist}")
        self.quantizer = quantizer
        self.codes = [np.ascontiguousarray(c, dtype=np.int32) for c in codes]
        self.features = [np.ascontiguousarray(f, dtype=np.float64) for f in features]
        self.shortlist = int(shortlist)
        self.band = band
        self.table = DiffTable.from_ratios(quantizer.ratios)
        # ``searcher``: an existing fast search over exactly these codes (MotionIndex shares its own)
        self.searcher = searcher or FastSearcher(self.codes, self.table, band=band, backend=backend)

    @classmethod
    def fit(cls, features: Sequence[np.ndarray], dims: int = DIMS, shortlist: int = SHORTLIST,
            band: int | None = None, backend: str = "auto") -> "StoryBeamSearcher":
        """PCA and quantiser fitted on the library's frames only, then the searcher."""
        if not features:
            raise StoryBeamError("storybeam search: no clips to index")
        quantizer = Quantizer.fit(np.concatenate(list(features), axis=0), dims)
        return cls(quantizer, [quantizer.encode(f) for f in features], features, shortlist, band, backend)

    def __len__(self) -> int:
        return len(self.codes)

    @property
    def backend(self) -> str:
        return self.searcher.backend

    def search(self, query: np.ndarray, k: int = 1, codes: np.ndarray | None = None,
               exclude: int | None = None) -> list[Hit]:
        """The ``k`` nearest clips to the (frames, d) float features ``query`` by exact
        float DTW among the code shortlist (``max(shortlist, k)`` clips, plus one when
        ``exclude`` — a library position to leave out — is given), nearest first."""
        q = np.ascontiguousarray(query, dtype=np.float64)
        if q.ndim != 2 or q.shape[0] == 0 or q.shape[1] != self.features[0].shape[1]:
            raise StoryBeamError(f"storybeam search: query features must be (frames, {self.features[0].shape[1]}), "
                                 f"got {q.shape}")
        if k <= 0:
            return []
        c = self.quantizer.encode(q) if codes is None else np.ascontiguousarray(codes, dtype=np.int32)
        want = min(len(self), max(self.shortlist, k) + (exclude is not None))
        res = self.searcher.search([c], k=want, parallel=False)
        cands = [(int(i), float(d)) for i, d in zip(res.indices[0], res.distances[0]) if i >= 0 and i != exclude]
        return self.rerank(q, cands, k)

    def rerank(self, q: np.ndarray, candidates: Sequence[tuple[int, float]], k: int) -> list[Hit]:
        """Exact float DTW of ``q`` to each (index, code distance) candidate, the ``k``
        nearest kept. Candidates come in code order, so the first few set a tight
        abandoning limit; a candidate whose partial DTW already exceeds the current
        ``k``-th best cannot enter the answer and is abandoned (its distance is not
        needed)."""
        best: list[Hit] = []
        for i, cd in candidates:
            limit = best[k - 1].distance if len(best) >= k else np.inf
            d = dtw_features_abandon(q, self.features[i], limit, self.band, self.backend)
            if d <= limit:
                best.append(Hit(i, d, cd))
                best.sort(key=lambda h: (h.distance, h.code_distance, h.index))
                del best[k:]
        return best
