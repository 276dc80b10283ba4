"""The summary shortlist: library clips nearest to a query by their feature summary.

A clip's **summary** (:func:`clip_summary`) is each feature's mean over the clip, then
each feature's spread, the range between its 10th and 90th percentiles
(:data:`SPREAD_PERCENTILES`). StoryBeam's searcher gives a few of its shortlist's places to
the clips whose summaries are nearest the query's by Euclidean distance
(:class:`~retrieval.library.StoryBeamSearcher`, issue 31: a style the library has never
seen shifts every frame's codes, its summary much less).

Per query that costs one summary of the query and one distance per library clip. In
numpy that is a sort of the query's columns, a mean, a norm over the library and a
partition: about 75 µs a query on bandai2, a tenth of the whole search, most of it numpy's
fixed cost per call on arrays this small. :func:`summary_nearest` does the same in one
compiled call (numba) and returns **the same numbers bit for bit**: the mean adds the
rows in order, as numpy's reduction over the first axis does; the percentiles use
numpy's linear interpolation between the same two order statistics, found by selection
instead of a sort; each distance sums its squares the way
numpy's pairwise summation does for a row of up to 128 values (eight interleaved partial
sums, then the remainder); the pick is a stable argsort's, ties by position. A test
checks the equality on random data; without numba, or with more than 64 features, the
numpy path runs.
"""
from __future__ import annotations

from typing import Collection

import numpy as np

from retrieval.dtw.jit import HAVE_NUMBA, numba
from retrieval.errors import StoryBeamError

#: The percentiles whose difference is a feature's spread in :func:`clip_summary`.
SPREAD_PERCENTILES = (10.0, 90.0)

#: The compiled distance follows numpy's pairwise summation only up to this many summary
#: values (numpy's unrolled block); longer summaries take the numpy path.
_PAIRWISE_BLOCK = 128


def _spread_positions(frames: int) -> tuple[float, float]:
    """The fractional sorted positions of :data:`SPREAD_PERCENTILES` among ``frames`` values."""
    lo, hi = (p / 100.0 * (frames - 1) for p in SPREAD_PERCENTILES)
    return lo, hi


def clip_summary(features: np.ndarray) -> np.ndarray:
    """(2d,) summary of (frames, d) features: each column's mean over the frames, then
    each column's spread, the range between its :data:`SPREAD_PERCENTILES` (float64). A
    percentile range rather than the standard deviation so that a few glitched or
    transitional frames move it little; measured against the standard deviation and the
    mean absolute deviation (docs/notebook/results.md, issue 31), it held best when the
    style or the performer is new."""
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 2 or f.shape[0] == 0:
        raise StoryBeamError(f"clip summary: features must be (frames > 0, d), got {f.shape}")
    # np.percentile's linear interpolation, on one sort of the columns (several times
    # faster than np.percentile itself)
    ranked = np.sort(f, axis=0)
    last = len(ranked) - 1
    lo, hi = (ranked[int(x)] + (x - int(x)) * (ranked[min(int(x) + 1, last)] - ranked[int(x)])
              for x in _spread_positions(len(ranked)))
    return np.concatenate([f.mean(axis=0), hi - lo])


def nearest_not_in(gap: np.ndarray, taken: Collection[int], n: int) -> list[int]:
    """The ``n`` positions of smallest ``gap`` not in ``taken``, nearest first, ties by
    position: what a stable argsort of the whole array would give, from a partition and a
    sort of the few candidates (per query, the whole argsort and its Python loop cost as
    much as a third of the summary shortlist)."""
    m = min(len(gap), n + len(taken))
    if m <= 0:
        return []
    if m < len(gap):
        cand = np.flatnonzero(gap <= np.partition(gap, m - 1)[m - 1])  # every tie at the cut, in position order
    else:
        cand = np.arange(len(gap))
    order = cand[np.argsort(gap[cand], kind="stable")].tolist()
    return [i for i in order if i not in taken][:n]


def summary_gaps(summaries: np.ndarray, features: np.ndarray) -> np.ndarray:
    """Euclidean distance from each row of ``summaries`` ((clips, 2d)) to the summary of
    the (frames, d) ``features``: the numpy path."""
    return np.linalg.norm(summaries - clip_summary(features), axis=1)


if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True, inline="always")
    def _select(a, lo, hi, k):
        """Rearrange ``a[lo..hi]`` (inclusive) so that ``a[k]`` holds the value a sort would
        put there, those before it no larger and those after no smaller (Hoare's selection,
        as in Wirth's *Algorithms + Data Structures*; expected linear time)."""
        while lo < hi:
            x = a[k]
            i = lo
            j = hi
            while True:
                while a[i] < x:
                    i += 1
                while x < a[j]:
                    j -= 1
                if i <= j:
                    t = a[i]
                    a[i] = a[j]
                    a[j] = t
                    i += 1
                    j -= 1
                if i > j:
                    break
            if j < k:
                lo = i
            if k < i:
                hi = j

    @numba.njit(cache=True, nogil=True)
    def _nb_summary_nearest(q, summaries, lo_at, hi_at, taken, n, out):
        """Compiled :func:`summary_nearest` (module docstring): writes up to ``n`` library
        positions into ``out`` and returns how many. ``taken``: a mask of positions left out."""
        frames, d = q.shape
        s = np.empty(2 * d)
        for j in range(d):
            s[j] = 0.0
        for i in range(frames):  # numpy's mean over the first axis: rows added in order
            for j in range(d):
                s[j] += q[i, j]
        for j in range(d):
            s[j] = s[j] / frames
        col = np.empty(frames)
        ilo, ihi = int(lo_at), int(hi_at)
        flo, fhi = lo_at - ilo, hi_at - ihi
        for j in range(d):
            for i in range(frames):
                col[i] = q[i, j]
            # the four order statistics the interpolation needs, by selection (the sorted
            # column's values at ilo, ilo + 1, ihi, ihi + 1; the last one clamps to the end)
            _select(col, 0, frames - 1, ihi)
            at_hi = col[ihi]
            after_hi = at_hi
            if ihi + 1 < frames:
                after_hi = np.inf
                for i in range(ihi + 1, frames):  # all >= col[ihi]: their minimum is next
                    if col[i] < after_hi:
                        after_hi = col[i]
            _select(col, 0, ihi, ilo)
            at_lo = col[ilo]
            after_lo = after_hi
            if ilo < ihi:
                after_lo = np.inf
                for i in range(ilo + 1, ihi + 1):
                    if col[i] < after_lo:
                        after_lo = col[i]
            lo = at_lo + flo * (after_lo - at_lo)
            hi = at_hi + fhi * (after_hi - at_hi)
            s[d + j] = hi - lo
        m, w = summaries.shape
        gap = np.empty(m)
        sq = np.empty(w)
        r = np.empty(8)
        for c in range(m):
            for t in range(w):
                x = summaries[c, t] - s[t]
                sq[t] = x * x
            if w < 8:  # numpy's pairwise_sum for a short row: in order
                acc = 0.0
                for t in range(w):
                    acc += sq[t]
            else:  # ... and for up to 128 values: eight interleaved sums, then the rest
                for u in range(8):
                    r[u] = sq[u]
                full = w - w % 8
                for t in range(8, full, 8):
                    for u in range(8):
                        r[u] += sq[t + u]
                acc = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
                for t in range(full, w):
                    acc += sq[t]
            gap[c] = np.sqrt(acc)
        got = 0
        while got < n:  # the smallest gap not taken, first position on ties: a stable argsort's order
            best = -1
            for c in range(m):
                if not taken[c] and (best < 0 or gap[c] < gap[best]):
                    best = c
            if best < 0:
                break
            out[got] = best
            taken[best] = True
            got += 1
        return got


def summary_nearest(summaries: np.ndarray, features: np.ndarray, taken: Collection[int], n: int,
                    compiled: bool = True) -> list[int]:
    """The ``n`` library positions whose summaries (rows of ``summaries``, C-contiguous
    float64) are nearest to the summary of the (frames, d) ``features``, not in
    ``taken``, nearest first, ties by position: :func:`nearest_not_in` of
    :func:`summary_gaps`. ``compiled``: one numba call with the same result bit for bit
    (module docstring) where numba is present and the summary has at most 128 values."""
    f = np.ascontiguousarray(features, dtype=np.float64)
    if f.ndim != 2 or f.shape[0] == 0 or 2 * f.shape[1] != summaries.shape[1]:
        raise StoryBeamError(f"summary shortlist: features must be (frames > 0, {summaries.shape[1] // 2}), "
                             f"got {f.shape}")
    if n <= 0:
        return []
    if compiled and HAVE_NUMBA and summaries.shape[1] <= _PAIRWISE_BLOCK:
        mask = np.zeros(len(summaries), np.bool_)
        for i in taken:
            mask[i] = True
        out = np.empty(n, np.int64)
        lo_at, hi_at = _spread_positions(len(f))
        got = _nb_summary_nearest(f, summaries, lo_at, hi_at, mask, n, out)
        return out[:got].tolist()
    return nearest_not_in(summary_gaps(summaries, f), taken, n)
