"""The benchmark's rival: a UCR-suite-style exact 1-NN search on the *same* code distance.

The fast search (:mod:`retrieval.search.fast`) is only as fast as what a specialist would
write instead. This module is that specialist's search, written as well as we can and kept
with the bench code (it is a yardstick, not part of the library). Its answer is the seed's:
the nearest clip under the look-up DTW over codes (full table, no band, normalised by
``len(a) + len(b)``), ties to the lower library index, the distance bit-identical.

Method (Rakthanmanon et al., "Searching and mining trillions of time series subsequences
under DTW", KDD 2012, adapted to whole-clip 1-NN with no warping window; Herrmann & Webb,
"Early abandoning and pruning for elastic distances", 2021, for the DTW):

1. **Per-query table rows.** ``R[u, t] = D[q_u, v_t]`` for every distinct query code u and
   every code v_t the library uses, and ``colmin[t] = min_u R[u, t]`` — after this one
   pass a cost is one load.
2. **Cascade of lower bounds, for every candidate** (every warping path from (0, 0) to
   (x−1, y−1) crosses every row and every column and both corners; costs are ≥ 0):

   * LB_Kim: ``D[a_0, b_0] + D[a_last, b_last]`` (first and last frames are on every path);
   * LB_Keogh(query | candidate envelope): with no window the envelope of the candidate is
     its whole set of codes, so row i costs at least ``min_j D[a_i, b_j]``; summed over
     rows (computed over distinct codes × multiplicity);
   * LB_Keogh(candidate | query envelope): the same with the roles swapped, one load per
     distinct candidate code (``colmin``).

   The bound is the maximum of the three, divided by ``x + y``.
3. **Order**, two strategies (:data:`STRATEGIES`); neither wins everywhere, so the
   benchmark runs both and compares with the faster on each data set:

   * ``"cascade"`` (the UCR suite's cascade, cheapest bound first): the two bounds that
     cost one load per distinct candidate code (LB_Kim, LB_Keogh(candidate | query
     envelope)) for every candidate, candidates sorted by them (stable: ties keep library
     order), the loop stopping at the first one above the best distance so far;
     LB_Keogh(query | candidate envelope), one load per (query code, candidate code) pair,
     only for the candidates the loop reaches, each skipped when it is above the best.
     Faster on large libraries, where the bounds of every clip are most of the work;
   * ``"sorted"``: all three bounds for every candidate, candidates sorted by their
     maximum, the loop stopping at the first one above the best. Faster on few, long
     clips (the paper protocol at 120 fps), where the better order finds a near
     neighbour sooner and saves DTW work.
4. **Early-abandoning, pruned DTW (EAPrunedDTW-style).** Each surviving candidate's DP runs
   row by row with the upper bound ``UB = best so far × (x + y)``; a cell whose value plus
   the cumulative LB_Keogh of the rows still to come, or of the columns still to come,
   exceeds UB is dead; each row only spans from its first live cell to the point where
   no live cell of the row above can feed it, and the DP stops when a row has no live
   cell. A cell on a path that finishes within UB is never killed, so a result within
   the limit is the exact DP value (same operations as the seed's kernel).

All bounds are multiplied by ``1 − 1e−9`` before a comparison, so floating-point sums in
another order than the DP's can never prune the true neighbour. The bounds are
property-tested against brute force in ``tests/lab/test_ucr_rival.py``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from retrieval.codes import DiffTable
from retrieval.dtw.jit import HAVE_NUMBA, numba
from retrieval.errors import StoryBeamError

#: relative safety factor applied to every bound before a comparison (see the module docstring)
SAFETY = 1.0 - 1e-9
#: the two candidate orders (module docstring, step 3); the benchmark runs both and
#: compares the fast search with the faster on each data set
STRATEGIES = ("cascade", "sorted")

if HAVE_NUMBA:  # optional: numba (the rival is compiled like the fast search)

    @numba.njit(cache=True, nogil=True)
    def _rows(q_dv, vocab, F, absdiff, shift, mask):  # pragma: no cover - compiled
        nv = vocab.shape[0]
        R = np.empty((q_dv.shape[0], nv))
        colmin = np.full(nv, np.inf)
        for u in range(q_dv.shape[0]):
            ulo = q_dv[u] & mask
            uhi = q_dv[u] >> shift
            for t in range(nv):
                v = vocab[t]
                x = np.float64(F[np.int64(absdiff[ulo, v & mask]) | (np.int64(absdiff[uhi, v >> shift]) << shift)])
                R[u, t] = x
                if x < colmin[t]:
                    colmin[t] = x
        return R, colmin

    @numba.njit(cache=True, nogil=True)
    def _envelope_rows(RT, c_codes, rowmin):  # pragma: no cover - compiled
        """``rowmin[u] = min over the candidate's distinct codes t of RT[t, u]``: each query
        code's cheapest candidate code (LB_Keogh's whole-clip envelope on codes), one
        contiguous row of the transposed table rows per candidate code, folded into every
        query code's minimum at once (a vector minimum; the fast search does the same)."""
        for u in range(rowmin.shape[0]):
            rowmin[u] = np.inf
        for s in range(c_codes.shape[0]):
            r = RT[c_codes[s]]
            for u in range(rowmin.shape[0]):
                rowmin[u] = min(rowmin[u], r[u])

    @numba.njit(cache=True, nogil=True)
    def _cheap_bounds(q_didx, nx, R, colmin, lc, lco, ldv, ldc, ldo, out):  # pragma: no cover - compiled
        """Normalised max(LB_Kim, LB_Keogh(candidate | query envelope)) of every candidate."""
        qf = q_didx[0]
        ql = q_didx[nx - 1]
        for c in range(lco.shape[0] - 1):
            b0, b1 = lco[c], lco[c + 1]
            ny = b1 - b0
            kim = R[qf, lc[b0]]
            if nx > 1 or ny > 1:
                kim += R[ql, lc[b1 - 1]]
            cols = 0.0
            for s in range(ldo[c], ldo[c + 1]):
                cols += colmin[ldv[s]] * ldc[s]
            out[c] = (kim if kim > cols else cols) / (nx + ny)

    @numba.njit(cache=True, nogil=True)
    def _bounds(q_didx, q_dcnt, nx, R, colmin, lc, lco, ldv, ldc, ldo, out):  # pragma: no cover - compiled
        """Normalised max(LB_Kim, LB_Keogh both ways) of every candidate: the cheap bounds
        (:func:`_cheap_bounds`), raised to LB_Keogh(query | candidate envelope) where that
        is larger."""
        _cheap_bounds(q_didx, nx, R, colmin, lc, lco, ldv, ldc, ldo, out)
        RT = np.ascontiguousarray(R.T)
        rowmin = np.empty(q_dcnt.shape[0])
        for c in range(lco.shape[0] - 1):
            _envelope_rows(RT, ldv[ldo[c]:ldo[c + 1]], rowmin)
            rows = 0.0
            for u in range(q_dcnt.shape[0]):
                rows += rowmin[u] * q_dcnt[u]
            rows /= nx + lco[c + 1] - lco[c]
            if rows > out[c]:
                out[c] = rows

    @numba.njit(cache=True, nogil=True)
    def _eap_dtw(q_didx, b, R, rest_row, rest_col, ub, prev, cur):  # pragma: no cover - compiled
        """EAPrunedDTW-style DP; the exact raw DTW if it is <= ub, else inf."""
        nx, ny = q_didx.shape[0], b.shape[0]
        inf = np.inf
        for j in range(ny):
            prev[j] = inf
            cur[j] = inf
        sc = 0  # first live column of the previous row
        ec = 0  # one past the last live column of the previous row (row -1: the start)
        for i in range(nx):
            Ri = R[q_didx[i]]
            rr = rest_row[i]
            nsc = -1
            nec = -1
            j = sc
            left = inf  # cur[j - 1]
            while j < ny:
                if i == 0 and j == 0:
                    best = 0.0
                else:
                    best = left
                    if i > 0 and j < ec and prev[j] < best:
                        best = prev[j]
                    if i > 0 and j > sc and j - 1 < ec and prev[j - 1] < best:
                        best = prev[j - 1]
                if best == inf and j >= ec:
                    break  # nothing live above or to the left: the rest of the row is dead
                v = Ri[b[j]] + best
                x = rest_col[j]
                if rr > x:
                    x = rr
                if v + x > ub:
                    v = inf
                elif nsc < 0:
                    nsc = j
                if v != inf:
                    nec = j + 1
                cur[j] = v
                left = v
                j += 1
            if nsc < 0:
                return inf
            # clear what this row left behind in the buffer beyond its reach
            for t in range(j, ny):
                cur[t] = inf
            sc = nsc
            ec = nec
            prev, cur = cur, prev
        if ec < ny:
            return inf
        return prev[ny - 1]

    @numba.njit(cache=True, nogil=True)
    def _abandoning_dtw(c, q_didx, R, colmin, lco, lrow, rowmin, ub, rest_row, rest_col, prev,
                        cur):  # pragma: no cover - compiled
        """Candidate ``c``'s early-abandoning DTW within ``ub`` (raw; inf when abandoned),
        pruned by the cumulative LB_Keogh of the rows still to come (from ``rowmin``, each
        query code's cheapest candidate code, :func:`_envelope_rows`) and of the columns."""
        nx = q_didx.shape[0]
        b0, b1 = lco[c], lco[c + 1]
        acc = 0.0
        for i in range(nx - 1, -1, -1):
            rest_row[i] = acc * 0.999999999
            acc += rowmin[q_didx[i]]
        acc = 0.0
        for j in range(b1 - b0 - 1, -1, -1):
            rest_col[j] = acc * 0.999999999
            acc += colmin[lrow[b0 + j]]
        return _eap_dtw(q_didx, lrow[b0:b1], R, rest_row, rest_col, ub, prev, cur)

    @numba.njit(cache=True, nogil=True)
    def _search(q_didx, q_dcnt, R, colmin, lbs, lco, ldv, ldo, lrow, check_rows, stats):  # pragma: no cover
        """Candidates in order of ``lbs``, stop at the first one above the best,
        early-abandoning DTW; returns (index, distance) of the nearest candidate.
        ``check_rows`` (the "cascade" strategy, whose ``lbs`` are the cheap bounds): the
        rows' envelope of each candidate reached is its second stage, the candidate
        skipped when that is above the best. Without it ("sorted", ``lbs`` already the
        full bound) the rows' minima only feed the DTW's bound of the rows to come."""
        nx = q_didx.shape[0]
        ncand = lco.shape[0] - 1
        order = np.argsort(lbs, kind="mergesort")
        maxlen = 1
        for c in range(ncand):
            if lco[c + 1] - lco[c] > maxlen:
                maxlen = lco[c + 1] - lco[c]
        prev = np.empty(maxlen)
        cur = np.empty(maxlen)
        rest_col = np.empty(maxlen)
        rest_row = np.empty(nx)
        rowmin = np.empty(q_dcnt.shape[0])
        RT = np.ascontiguousarray(R.T)
        best_d = np.inf
        best_c = -1
        pruned = 0
        abandoned = 0
        completed = 0
        for pos in range(ncand):
            c = order[pos]
            if lbs[c] * 0.999999999 > best_d:
                pruned += ncand - pos
                break
            norm = float(nx + lco[c + 1] - lco[c])
            ub = np.inf if best_d == np.inf else best_d * norm * 1.000000001
            # LB_Keogh(query | candidate envelope): each query code's cheapest candidate code,
            # which also gives the DTW the cumulative LB_Keogh of the rows still to come
            _envelope_rows(RT, ldv[ldo[c]:ldo[c + 1]], rowmin)
            if check_rows:
                rows = 0.0
                for u in range(q_dcnt.shape[0]):
                    rows += rowmin[u] * q_dcnt[u]
                if rows / norm * 0.999999999 > best_d:
                    pruned += 1
                    continue
            raw = _abandoning_dtw(c, q_didx, R, colmin, lco, lrow, rowmin, ub, rest_row, rest_col, prev, cur)
            if raw == np.inf:
                abandoned += 1
                continue
            completed += 1
            d = raw / norm
            if d < best_d or (d == best_d and c < best_c):
                best_d = d
                best_c = c
        stats[0] = ncand
        stats[1] = pruned
        stats[2] = abandoned
        stats[3] = completed
        return best_c, best_d


class RivalError(StoryBeamError):
    """The rival cannot run as asked (no numba, empty library, codes outside the table)."""


@dataclass
class RivalResult:
    index: int
    distance: float
    candidates: int
    pruned: int
    abandoned: int
    completed: int


class UCRRival:
    """UCR-suite-style exact 1-NN over code sequences (see the module docstring).

    ``library``: the clips' codes; ``table``: the quantiser's :class:`DiffTable`;
    ``strategy``: one of :data:`STRATEGIES` (module docstring, step 3)."""

    def __init__(self, library: Sequence[np.ndarray], table: DiffTable, strategy: str = "cascade"):
        if strategy not in STRATEGIES:
            raise RivalError(f"unknown rival strategy {strategy!r}; choose from {', '.join(STRATEGIES)}")
        self.strategy = strategy
        if not HAVE_NUMBA:
            raise RivalError("the UCR-suite rival is compiled with numba, which is not installed")
        if len(library) == 0:
            raise RivalError("the rival needs at least one library clip")
        self.table = table
        seqs = [np.ascontiguousarray(s, dtype=np.int64) for s in library]
        for i, s in enumerate(seqs):
            if s.ndim != 1 or s.size == 0 or s.min() < 0 or s.max() >= table.size:
                raise RivalError(f"library clip {i}: codes must be a non-empty 1-D array in [0, {table.size})")
        codes = np.concatenate(seqs)
        self.vocab = np.unique(codes)
        self.lco = np.concatenate(([0], np.cumsum([len(s) for s in seqs]))).astype(np.int64)
        self.lrow = np.searchsorted(self.vocab, codes).astype(np.int64)  # codes as vocabulary indices
        dv, dc = [], []
        for s in range(len(seqs)):
            v, n = np.unique(self.lrow[self.lco[s]:self.lco[s + 1]], return_counts=True)
            dv.append(v)
            dc.append(n.astype(np.float64))
        self.ldv = np.concatenate(dv).astype(np.int64)
        self.ldc = np.concatenate(dc)
        self.ldo = np.concatenate(([0], np.cumsum([len(v) for v in dv]))).astype(np.int64)
        self._shift = 2 * table.low_dims
        self._mask = (1 << self._shift) - 1

    def __len__(self) -> int:
        return len(self.lco) - 1

    def bounds(self, query: np.ndarray) -> np.ndarray:
        """Normalised max(LB_Kim, LB_Keogh EQ, LB_Keogh EC) of every clip (for the tests)."""
        q_didx, q_dcnt, R, colmin = self._prepare(query)
        out = np.empty(len(self))
        _bounds(q_didx, q_dcnt, len(q_didx), R, colmin, self.lrow, self.lco, self.ldv, self.ldc, self.ldo, out)
        return out

    def _prepare(self, query: np.ndarray):
        q = np.ascontiguousarray(query, dtype=np.int64)
        if q.ndim != 1 or q.size == 0 or q.min() < 0 or q.max() >= self.table.size:
            raise RivalError(f"query codes must be a non-empty 1-D array in [0, {self.table.size})")
        q_dv, q_didx, q_dcnt = np.unique(q, return_inverse=True, return_counts=True)
        t = self.table
        R, colmin = _rows(q_dv, self.vocab, t.F, t.absdiff, self._shift, self._mask)
        return q_didx.astype(np.int64), q_dcnt.astype(np.float64), R, colmin

    def search(self, query: np.ndarray) -> RivalResult:
        """The nearest clip and its normalised distance (the seed's, bit for bit)."""
        q_didx, q_dcnt, R, colmin = self._prepare(query)
        lbs = np.empty(len(self))
        stats = np.zeros(4, np.int64)
        cascade = self.strategy == "cascade"
        if cascade:
            _cheap_bounds(q_didx, len(q_didx), R, colmin, self.lrow, self.lco, self.ldv, self.ldc, self.ldo, lbs)
        else:
            _bounds(q_didx, q_dcnt, len(q_didx), R, colmin, self.lrow, self.lco, self.ldv, self.ldc, self.ldo, lbs)
        c, d = _search(q_didx, q_dcnt, R, colmin, lbs, self.lco, self.ldv, self.ldo, self.lrow, cascade, stats)
        return RivalResult(int(c), float(d), *(int(x) for x in stats))
