"""StoryBeam's own retrieval method (``"storybeam"``): the seed's 2-bit codes find the
few nearest clips fast, exact DTW on the real-valued features ranks those few.

Method, for a query with features ``q`` (the ``"storybeam"`` feature set: MR17 plus the
turning rate plus where the hands are, :mod:`retrieval.features.storybeam_set`; the codes
see its first 18 columns, the summary and the re-ranking all 22):

1. **Shortlist.** PCA (``dims`` components) + the seed's 2-bit quantiser turn ``q`` into
   codes; the fast search (:class:`~retrieval.search.FastSearcher`, the 20 KiB
   difference table, lower bounds, early abandoning) returns the ``shortlist − summary``
   library clips nearest by look-up-table DTW (ties by library order), by default in its
   run-length form (``mode="runs"``, :data:`SHORTLIST_MODE`), which costs about a third
   of the exact code search and, measured, shortlists as well for the re-ranking. The
   other ``summary`` places (:data:`SUMMARY`, 2 of 3) go to the clips nearest by their
   **summary** (:func:`clip_summary`: each feature's mean and the range between its 10th
   and 90th percentiles over the clip; Euclidean distance, ties by library order) that the
   codes did not already bring. Why (issue 31): a performer in a style the library has
   never seen — an elderly wave, an active walk — shifts the 2-bit codes of every frame,
   and the code DTW then shortlists the wrong gesture (on bandai2, leaving one style out,
   all 4 shortlisted clips were raise-ups for 8 of the 21 left-hand waves, which exact
   DTW over the whole library answers right: 84.3 % against 90.5 %; now 90.0 %). A
   clip's summary says how much each feature *varies* (a waving hand's distances swing,
   a raised one's hold) and survives a change of tempo and timing. It costs the query's
   summary and one (2d)-vector distance per library clip, in one compiled call
   (:mod:`retrieval.search.summary`, the same numbers as numpy's bit for bit); the
   shortlist keeps its size. Measured on one core, every query searched by each
   configuration in turn: the 3 (1 by codes, 2 by summary) on the 22 columns take
   0.82–0.94 of the time of the code shortlist of 4 on the 18 columns that the method
   began with (docs/notebook/results.md, issue 31).
2. **Re-rank.** Each shortlisted clip's distance is then exact DTW with Euclidean frame
   cost on the float features (:func:`~retrieval.dtw.dtw_features`, normalised by
   ``len(q) + len(r)``) — the same distance as the exact-DTW baseline on the same
   features — and the shortlist is sorted by it (ties: code distance, then library
   order). A candidate is abandoned as soon as its partial DTW exceeds the
   ``k``-th best so far, which changes no answer
   (:func:`~retrieval.dtw.rerank.dtw_features_abandon`: bit for bit the
   baseline's kernel otherwise). A matrix-product form of the cost matrix was measured
   and dropped (no faster with one BLAS thread; far slower with OpenBLAS's default
   threads on a busy machine; docs/notebook/results.md).

What it guarantees: the answer is exact with respect to what is ranked — the ``k``
returned clips are the ``k`` nearest *by exact float DTW among the shortlist*, and their
distances are exact. It equals exact DTW over the whole library whenever the true
nearest clip is in the code shortlist; docs/notebook/results.md measures how often that holds
(the accuracy within 1 point of exact DTW) and what the shortlist size trades between
accuracy and speed. Saturation: quantised distances are coarse (several clips at 0.0
for a near-duplicate), and the float re-ranking breaks exactly those ties — "find this
clip" returns the clip itself first.

"Find this clip" (:meth:`StoryBeamSearcher.find`) is a separate ranking for identity,
not class: the class ranking above can put a near-duplicate (another take by the same
performer) before the clip itself when the clip comes back from another skeleton,
because retargeting shifts each feature by a per-clip offset (a body's head and
shoulders sit elsewhere) larger than the difference between two takes. ``find`` removes
exactly that offset: every feature column minus its mean over the clip
(:func:`centre`), for the query and the library alike. It then runs the same two steps
on the centred features — a second quantiser (PCA + 2-bit codes, fitted on the
library's centred frames, built on first use) shortlists the ``shortlist`` code-nearest
clips and ``summary`` more, those with the nearest centred summaries (a centred clip's
means are 0, so these are its spreads); exact float DTW on centred features ranks them —
so it is exact with respect to
what it ranks, and :meth:`search` (class retrieval, the evaluation's accuracy) is
untouched. Centred features are worse for class (they drop posture levels that tell a
jump from a walk: 91.7 % on CMU against 99.0 % raw, exact DTW) and better for identity
(205 / 205 CMU clips found first after a round trip onto another skeleton, against
164 / 205 by :meth:`search`; docs/notebook/results.md), hence two rankings.

Cost: one fast code search plus at most ``shortlist`` float DTWs (fewer cells when
abandoned), against one float DTW per library clip for exact DTW; memory: the codes
(int32 per frame) plus the float features of the library (float32 on disk; in memory
float64, held twice when there is no band — as given and transposed, for the
re-ranking kernel — 288 bytes per 18-D frame).
"""
from __future__ import annotations

from typing import Collection, Sequence

import numpy as np

from retrieval.codes import DiffTable, Quantizer
from retrieval.errors import StoryBeamError
from retrieval.dtw import (
    dtw_features_abandon,
    dtw_features_abandon_t,
    dtw_features_many,
    resolve_backend,
    rows_kernel_ready,
)
from retrieval.search import FastSearcher, Hit, clip_summary, summary_nearest

#: Default number of clips re-ranked by exact float DTW (the ablations in
#: docs/notebook/results.md: accuracy against speed). 3 since the four hand columns
#: (issue 31) made each re-ranking DTW about 15 % dearer: 1 by codes and 2 by summary
#: answer as well as 2 and 2 did over five studios, at 0.82-0.94 of the time.
SHORTLIST = 3

#: Default kept PCA components of the shortlist's codes (the seed's n).
DIMS = 6

#: Of the ``shortlist`` clips re-ranked, how many come from the clip-summary ranking
#: (:func:`clip_summary`) instead of the code search (module docstring; the ablation in
#: docs/notebook/results.md, issue 31). 0 is the code shortlist alone.
SUMMARY = 2

#: How the shortlist's code distances are computed (:class:`~retrieval.search.FastSearcher`
#: ``mode``): "runs", the run-length form of the code DTW, ranks the shortlist at about a
#: third of the exact code search's cost and, measured on both shared data sets, picks
#: shortlists that give the same 1-NN accuracy after re-ranking (docs/notebook/results.md); the
#: re-ranking, and so every returned distance, stays exact float DTW either way.
SHORTLIST_MODE = "runs"


def centre(features: np.ndarray) -> np.ndarray:
    """(frames, d) features minus each column's mean over the frames (float64): the
    per-clip offset a retarget or a skeleton's proportions add is removed, the motion's
    shape over time is kept."""
    f = np.asarray(features, dtype=np.float64)
    return f - f.mean(axis=0, keepdims=True)


def _rank_key(hit: Hit) -> tuple[float, float, int]:
    """Re-ranking order: exact distance, then code distance (a clip the summary brought
    has none: after those that have one), then library order."""
    return hit.distance, np.inf if hit.code_distance is None else hit.code_distance, hit.index


class StoryBeamSearcher:
    """Code shortlist + exact float-DTW re-ranking over a fixed library (see the module
    docstring). ``features`` are the library's (frames, d) float features, ``codes``
    their codes under ``quantizer``; ``summary`` of the ``shortlist`` places go to the
    clip-summary ranking (0 here, so a searcher built directly keeps the code shortlist;
    :meth:`fit` and :class:`~retrieval.library.MotionIndex` use :data:`SUMMARY`)."""

    def __init__(self, quantizer: Quantizer, codes: Sequence[np.ndarray], features: Sequence[np.ndarray],
                 shortlist: int = SHORTLIST, band: int | None = None, backend: str = "auto",
                 searcher: FastSearcher | None = None, mode: str = SHORTLIST_MODE, summary: int = 0):
        if len(codes) != len(features) or not codes:
            raise StoryBeamError("storybeam search: codes and features must be non-empty and of equal length")
        if shortlist < 1:
            raise StoryBeamError(f"storybeam search: shortlist must be >= 1, got {shortlist}")
        if summary < 0:
            raise StoryBeamError(f"storybeam search: summary must be >= 0, got {summary}")
        self.quantizer = quantizer
        self.codes = [np.ascontiguousarray(c, dtype=np.int32) for c in codes]
        self.features = [np.ascontiguousarray(f, dtype=np.float64) for f in features]
        # the features transposed, for the compiled no-band re-ranking kernel (saves a copy per candidate)
        self.features_t = [np.ascontiguousarray(f.T) for f in self.features] if band is None else None
        self.shortlist = int(shortlist)
        self.summary = int(summary)
        # every clip's summary (clip_summary), for the summary part of the shortlist
        self.summaries = np.stack([clip_summary(f) for f in self.features]) if self.summary else None
        self.band = band
        self.table = DiffTable.from_ratios(quantizer.ratios)
        if mode == "runs" and band is not None:
            mode = "exact"  # the run-length form has no band
        self.mode = mode
        # ``searcher``: an existing fast search over exactly these codes (MotionIndex shares
        # its own), used when it computes the shortlist's distances the same way
        if searcher is None or searcher.mode != mode:
            searcher = FastSearcher(self.codes, self.table, band=band, backend=backend, mode=mode)
        self.searcher = searcher
        self._identity: StoryBeamSearcher | None = None  # the centred-feature searcher of find(), built on first use

    @classmethod
    def fit(cls, features: Sequence[np.ndarray], dims: int = DIMS, shortlist: int = SHORTLIST,
            band: int | None = None, backend: str = "auto", mode: str = SHORTLIST_MODE,
            summary: int = SUMMARY, code_columns: int | None = None) -> "StoryBeamSearcher":
        """PCA and quantiser fitted on the library's frames only, then the searcher;
        ``code_columns``: the codes see only the features' first that many columns (the
        feature set's :attr:`~retrieval.features.FeatureSet.coded`), the summary and the
        re-ranking every column."""
        if not features:
            raise StoryBeamError("storybeam search: no clips to index")
        quantizer = Quantizer.fit(np.concatenate(list(features), axis=0), dims, code_columns)
        return cls(quantizer, [quantizer.encode(f) for f in features], features, shortlist, band, backend,
                   mode=mode, summary=summary)

    def __len__(self) -> int:
        return len(self.codes)

    @property
    def backend(self) -> str:
        return self.searcher.backend

    def search(self, query: np.ndarray, k: int = 1, codes: np.ndarray | None = None,
               exclude: int | Collection[int] | None = None) -> list[Hit]:
        """The ``k`` nearest clips to the (frames, d) float features ``query`` by exact
        float DTW among the code shortlist (:meth:`shortlist_of`: ``max(shortlist, k)``
        clips, plus one per library position in ``exclude`` — one position or several —
        which are left out), nearest first: the two steps of the module docstring."""
        q = np.ascontiguousarray(query, dtype=np.float64)
        if q.ndim != 2 or q.shape[0] == 0 or q.shape[1] != self.features[0].shape[1]:
            raise StoryBeamError(f"storybeam search: query features must be (frames, {self.features[0].shape[1]}), "
                                 f"got {q.shape}")
        if k <= 0:
            return []
        return self.rerank(q, self.shortlist_of(q, k, codes, exclude), k)

    def shortlist_of(self, query: np.ndarray, k: int, codes: np.ndarray | None = None,
                     exclude: int | Collection[int] | None = None) -> list[tuple[int, float]]:
        """Step 1, the shortlist of (frames, d) float features ``query`` (``codes``: its
        codes, when the caller has them): the ``max(shortlist − summary, k)`` code-nearest
        clips, plus one per position in ``exclude``, those positions then dropped, as
        (library index, code distance) pairs in code order (ties by library order); then
        the ``summary`` summary-nearest clips not among them nor excluded, as (library
        index, None) — what :meth:`rerank` takes."""
        drop = () if exclude is None else (exclude,) if isinstance(exclude, (int, np.integer)) else exclude
        c = self.quantizer.encode(query) if codes is None else np.ascontiguousarray(codes, dtype=np.int32)
        want = min(len(self), max(self.shortlist - self.summary, k) + len(drop))
        out: list[tuple[int, float | None]] = []
        if want > 0:
            res = self.searcher.search([c], k=want, parallel=False)
            out = [(int(i), float(d)) for i, d in zip(res.indices[0], res.distances[0])
                   if i >= 0 and int(i) not in drop]
        if self.summaries is not None:
            taken = {i for i, _ in out} | {int(i) for i in drop}
            out += [(i, None) for i in summary_nearest(self.summaries, query, taken, self.summary,
                                                       compiled=resolve_backend(self.backend) == "numba")]
        return out

    def identity_searcher(self) -> "StoryBeamSearcher":
        """The searcher of :meth:`find`: the same method over the library's centred
        features (its own PCA and quantiser, fitted on those frames; the same code
        shortlist, with this searcher's summary places added to it), built once."""
        if self._identity is None:
            dims = self.quantizer.n
            # the code shortlist as before, plus this searcher's summary places on top: the
            # centred summaries are the spreads, which caught a third-party conversion (a
            # Daz-figure 10_02) that the centred codes ranked below four other soccer kicks.
            # On top rather than instead, so no clip the codes shortlist is lost (results.md, issue 31)
            self._identity = StoryBeamSearcher.fit([centre(f) for f in self.features], dims,
                                                   self.shortlist + self.summary, self.band, self.backend,
                                                   self.mode, summary=self.summary,
                                                   code_columns=self.quantizer.columns)
        return self._identity

    def find(self, query: np.ndarray, k: int = 1, exclude: int | None = None) -> list[Hit]:
        """"Find this clip": the ``k`` library clips nearest to ``query`` by exact float
        DTW on centred features (:func:`centre`) among the centred codes' shortlist,
        nearest first (see the module docstring). ``distance`` is the centred DTW and
        ``code_distance`` the centred code DTW; indices are library positions."""
        q = np.asarray(query, dtype=np.float64)
        if q.ndim != 2 or q.shape[0] == 0 or q.shape[1] != self.features[0].shape[1]:
            raise StoryBeamError(f"storybeam find: query features must be (frames, {self.features[0].shape[1]}), "
                                 f"got {q.shape}")
        return self.identity_searcher().search(centre(q), k, exclude=exclude)

    @property
    def reranks_every_candidate(self) -> bool:
        """Whether :meth:`rerank` computes every candidate's distance whatever ``k`` (the
        numpy path: one sweep, no abandoning), so asking for all of them costs no more."""
        return resolve_backend(self.backend) == "numpy"

    def rerank(self, q: np.ndarray, candidates: Sequence[tuple[int, float | None]], k: int) -> list[Hit]:
        """Exact float DTW of ``q`` to each (index, code distance) candidate, the ``k``
        nearest kept. Candidates come in code order, so the first few set a tight
        abandoning limit; a candidate whose partial DTW already exceeds the current
        ``k``-th best cannot enter the answer and is abandoned (its distance is not
        needed)."""
        best: list[Hit] = []
        q = np.ascontiguousarray(q, dtype=np.float64)
        if candidates and resolve_backend(self.backend) == "numpy":
            # the tablet's path: every candidate's exact DTW in one numpy sweep (no abandoning
            # there, which changes no answer: an abandoned candidate is never in the k best)
            ds = dtw_features_many(q, [self.features[i] for i, _ in candidates], self.band)
            best = [Hit(i, float(d), cd) for (i, cd), d in zip(candidates, ds)]
            best.sort(key=_rank_key)
            return best[:k]
        # the compiled no-band kernel straight away when the arrays fit it (checked once here)
        direct = (self.features_t is not None and q.ndim == 2 and len(q) > 0
                  and q.shape[1] == self.features[0].shape[1] and rows_kernel_ready(self.backend))
        for i, cd in candidates:
            limit = best[k - 1].distance if len(best) >= k else np.inf
            if direct:
                d = dtw_features_abandon_t(q, self.features_t[i], limit)
            else:
                d = dtw_features_abandon(q, self.features[i], limit, self.band, self.backend,
                                         None if self.features_t is None else self.features_t[i])
            if d <= limit:
                best.append(Hit(i, d, cd))
                best.sort(key=_rank_key)
                del best[k:]
        return best
