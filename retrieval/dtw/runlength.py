"""Exact DTW over run-length encoded code sequences.

2-bit codes change slowly (at 30 fps a code lasts about 3 frames on the shared CMU clips,
at 120 fps about 4× longer), so the DTW cost matrix between two clips is made of constant
blocks: run p of the first clip × run q of the second all cost ``c = D[A_p, B_q]``.
Inside such a block the cheapest way from a cell on its boundary to a cell inside takes
Chebyshev-distance steps (diagonal moves), each costing ``c``, so the block's bottom row
and right column follow from its top and left neighbours in O(h + w) with prefix minima
and one sliding-window minimum — the h·w inner cells are never computed. Blocks of height
or width 1 (most blocks at low frame rates) use the plain recurrence.

**Exactness.** In exact arithmetic this is the same dynamic programme. In floating point
it is *bit-identical* too when every sum the DP forms is exact: the costs are float32
values, i.e. multiples of ``2^(e−23)`` where ``2^e`` ≤ the smallest non-zero cost, and
float64 adds such multiples without rounding while the totals stay below ``2^(53+e−23)``.
:func:`rle_is_exact` checks that condition (it holds by a margin of about 10⁵ for the
shared CMU data at n = 6); the fast search falls back to the plain DP when it does not.
"""
from __future__ import annotations

import math

import numpy as np

from retrieval.dtw.jit import HAVE_NUMBA, numba
from retrieval.dtw.kernels import band_limits, dtw_cost_numpy


def run_length_encode(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(values, lengths) of the runs of equal consecutive codes (int32, int64)."""
    c = np.asarray(codes)
    if c.size == 0:
        return np.zeros(0, np.int32), np.zeros(0, np.int64)
    starts = np.flatnonzero(np.concatenate(([True], c[1:] != c[:-1])))
    lengths = np.diff(np.append(starts, c.size)).astype(np.int64)
    return c[starts].astype(np.int32), lengths


def run_length_decode(values: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    return np.repeat(np.asarray(values, dtype=np.int32), np.asarray(lengths, dtype=np.int64))


def rle_is_exact(costs: np.ndarray, max_path_cells: int) -> bool:
    """True when float64 DP sums of these float32 costs over paths of up to
    ``max_path_cells`` cells (and the block formulas' ``c·k`` terms) are all exact."""
    c = np.asarray(costs, dtype=np.float32).astype(np.float64)
    nz = c[c > 0]
    if nz.size == 0:
        return True
    e = math.floor(math.log2(float(nz.min())))
    unit_exp = e - 23  # every float32 cost >= 2^e is a multiple of 2^unit_exp
    limit = 2.0 ** (53 + unit_exp)
    return float(nz.max()) * 4.0 * max(1, max_path_cells) < limit


if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True, inline="always")
    def _block(top, left, h, w, c, bottom_out, right_out, buf_a, buf_b, dq):
        """One constant-cost block. top[0..w] = DP row above (top[0] is the corner),
        left[1..h] = DP column to the left. Writes bottom_out[1..w], right_out[1..h]."""
        inf = np.inf
        if h == 1:
            prev = left[1]
            for t in range(1, w + 1):
                best = top[t]
                if top[t - 1] < best:
                    best = top[t - 1]
                if prev < best:
                    best = prev
                prev = c + best
                bottom_out[t] = prev
            right_out[1] = prev
            return
        if w == 1:
            prev = top[1]
            for s in range(1, h + 1):
                best = prev
                if left[s] < best:
                    best = left[s]
                if s == 1:
                    d = top[0]
                else:
                    d = left[s - 1]
                if d < best:
                    best = d
                prev = c + best
                right_out[s] = prev
            bottom_out[1] = prev
            return
        # ---- bottom row, t = 1..w
        # buf_a[u] = prefix min of (top[u] - c*u); buf_b[v] = prefix min of (left[v] - c*v)
        m = inf
        for u in range(w + 1):
            x = top[u] - c * u
            if x < m:
                m = x
            buf_a[u] = m
        m = inf
        buf_b[0] = inf
        for v in range(1, h + 1):
            x = left[v] - c * v
            if x < m:
                m = x
            buf_b[v] = m
        # suffix min of left: stored in right_out temporarily is unsafe; use dq area after
        # the deque (dq has room for h + w + 4 entries of float via a view) -> compute inline
        # sliding window min of top over [t-h, t] with a monotone deque of indices
        head = 0
        tail = 0
        ch = c * h
        # suffix minima of left[v..h], kept in a running array (reuse right_out as scratch
        # is not possible: right_out is an output). Compute on the fly: sufmin_left[v].
        # We store them in the upper part of buf_b's sibling: use bottom_out? no -> second pass.
        for t in range(0, w + 1):
            while tail > head and top[dq[tail - 1]] >= top[t]:
                tail -= 1
            dq[tail] = t
            tail += 1
            while dq[head] < t - h:
                head += 1
            if t == 0:
                continue
            best = ch + top[dq[head]]
            if t - h - 1 >= 0:
                x = c * t + buf_a[t - h - 1]
                if x < best:
                    best = x
            # B_t: v in [1, h-t] -> buf_b[h-t] + c*h ; v in [max(1,h-t+1), h] -> c*t + min left
            if h - t >= 1:
                x = buf_b[h - t] + ch
                if x < best:
                    best = x
            bottom_out[t] = best
        # second term of B_t needs suffix minima of left: one backward pass
        m = inf
        # walk v from h down to 1; the window [h-t+1, h] grows as t grows
        t = 1
        for v in range(h, 0, -1):
            if left[v] < m:
                m = left[v]
            # v == h - t + 1  <=>  t == h - v + 1
            t = h - v + 1
            if t <= w:
                x = c * t + m
                if x < bottom_out[t]:
                    bottom_out[t] = x
        if w > h:  # for t >= h the window is all of left[1..h]: m is its minimum
            for t in range(h + 1, w + 1):
                x = c * t + m
                if x < bottom_out[t]:
                    bottom_out[t] = x
        # ---- right column, s = 1..h
        # A'_s: u in [max(0,w-s), w] -> c*s + sufmin(top)[.]; u in [0, w-s-1] -> c*w + buf_a[w-s-1]
        # B'_s: v in [1, s-w] -> c*s + buf_b[s-w]; v in [max(1,s-w+1), s] -> c*w + window min of left
        head = 0
        tail = 0
        cw = c * w
        for s in range(1, h + 1):
            while tail > head and left[dq[tail - 1]] >= left[s]:
                tail -= 1
            dq[tail] = s
            tail += 1
            while dq[head] < s - w + 1:
                head += 1
            best = cw + left[dq[head]]
            if s - w >= 1:
                x = c * s + buf_b[s - w]
                if x < best:
                    best = x
            if w - s - 1 >= 0:
                x = cw + buf_a[w - s - 1]
                if x < best:
                    best = x
            right_out[s] = best
        # c*s + suffix min of top over [max(0, w-s), w]: backward pass over u
        m = inf
        for u in range(w, -1, -1):
            if top[u] < m:
                m = top[u]
            s = w - u  # window [w-s, w] starts at u
            if 1 <= s <= h:
                x = c * s + m
                if x < right_out[s]:
                    right_out[s] = x
        if h > w:  # s > w: window is all of top[0..w]
            for s in range(w + 1, h + 1):
                x = c * s + m
                if x < right_out[s]:
                    right_out[s] = x

    @numba.njit(cache=True, nogil=True, inline="always")
    def diff_cost(u, v, F, absdiff, shift, mask):
        """D[u, v] through a :class:`~retrieval.codes.tables.DiffTable` (float64)."""
        d = np.int64(absdiff[u & mask, v & mask]) | (np.int64(absdiff[u >> shift, v >> shift]) << shift)
        return np.float64(F[d])

    @numba.njit(cache=True, nogil=True)
    def rle_dtw_raw(a_val, a_len, b_val, b_len, F, absdiff, shift, mask, rest, rest_col, limit, norm,
                    row_prev, row_next, left, right, buf_a, buf_b, dq):
        """Raw DTW over runs. The block cost is ``D[a_val[p], b_val[q]]`` through the
        difference table (F, absdiff, shift, mask); ``rest[p, q]`` a lower bound
        of the cost of what follows any cell of block (p, q) on a path to the end (e.g. the
        envelope of the rows after row-run p, the same for every q, or the order-aware
        rows-and-columns bound of :func:`retrieval.dtw.range_bound.range_cover_both`),
        ``rest_col[j]`` one of the columns after column j. A cell with (D + max(rest[p, q], rest_col[j])) / norm
        > limit is marked dead
        (what is left of any path through it covers all later rows and all later columns),
        blocks no live cell can reach are skipped, and the result is inf as soon as a
        row-run has no live cell (early abandoning). With ``limit = inf`` nothing is cut. Work arrays:
        row_prev/row_next of length ny+1, left/right of length max run+2, buf_a/buf_b and
        dq of length max(ny, max run)+2."""
        inf = np.inf
        ny = 0
        for q in range(b_len.shape[0]):
            ny += b_len[q]
        kx, ky = a_val.shape[0], b_val.shape[0]
        row_prev[0] = 0.0  # virtual D[-1, -1]
        for j in range(1, ny + 1):
            row_prev[j] = inf
        for j in range(ny + 1):
            row_next[j] = inf
        ilo = 0  # live index range of row_prev (index = column + 1); outside it all inf
        near = limit * norm * (1.0 - 1e-9)  # the exact division test runs only near the limit
        ihi = 0
        # Only the stretch of a row that the blocks wrote can hold finite values: resetting
        # just that stretch (not all ny + 1 entries) keeps a row-run's cost proportional to
        # the corridor's width, not to the reference's length.
        dirty_lo = 0  # stretch of row_next written two row-runs ago (row_prev's initial corner)
        dirty_hi = -1
        prev_lo = 0  # stretch of row_prev that holds values
        prev_hi = 0
        for p in range(kx):
            h = a_len[p]
            for j in range(dirty_lo, dirty_hi + 1):
                row_next[j] = inf
            wlo = -1
            whi = -1
            for s in range(h + 1):
                left[s] = inf
            # skip the blocks whose top lies wholly left of the live range: their inputs
            # (and so their outputs) are all dead
            j0 = 0
            q = 0
            while q < ky and j0 + b_len[q] < ilo:
                j0 += b_len[q]
                q += 1
            left_alive = False
            nlo = -1
            nhi = -1
            while q < ky:
                if j0 > ihi and not left_alive:
                    break  # nothing live can reach the remaining blocks of this row-run
                w = b_len[q]
                rp = rest[p, q]
                c = diff_cost(a_val[p], b_val[q], F, absdiff, shift, mask)
                _block(row_prev[j0:j0 + w + 1], left, h, w, c,
                       row_next[j0:j0 + w + 1], right, buf_a, buf_b, dq)
                if wlo < 0:
                    wlo = j0 + 1
                whi = j0 + w
                # a cell whose value plus the bound of what must follow exceeds the limit
                # lies on no path worth finishing: mark it dead (PrunedDTW-style corridor)
                for t in range(1, w + 1):
                    idx = j0 + t
                    v = row_next[idx]
                    x = rest_col[idx - 1]
                    if rp > x:
                        x = rp
                    if v == inf or (v + x > near and (v + x) / norm > limit):
                        row_next[idx] = inf
                    else:
                        if nlo < 0:
                            nlo = idx
                        nhi = idx
                x = rest_col[j0 + w - 1]
                if rp > x:
                    x = rp
                left_alive = False
                for s in range(1, h + 1):
                    v = right[s]
                    if v == inf or (v + x > near and (v + x) / norm > limit):
                        left[s] = inf
                    else:
                        left[s] = v
                        left_alive = True
                j0 += w
                q += 1
            if nlo < 0:
                return inf
            ilo = nlo
            ihi = nhi
            row_prev, row_next = row_next, row_prev
            row_prev[0] = inf
            dirty_lo = prev_lo
            dirty_hi = prev_hi
            prev_lo = wlo
            prev_hi = whi
        return row_prev[ny]


def rle_dtw_numpy(a_val, a_len, b_val, b_len, cost: np.ndarray) -> float:
    """``cost[p, q]``: the block costs (run p of the first clip × run q of the second)."""
    """Reference/no-numba raw DTW over runs: expands the block costs and runs the plain
    anti-diagonal DP of :mod:`retrieval.dtw.kernels` (same numbers under :func:`rle_is_exact`)."""
    full = np.repeat(np.repeat(np.asarray(cost, dtype=np.float64), a_len, axis=0), b_len, axis=1)
    lo, hi = band_limits(full.shape[0], full.shape[1], None)
    return dtw_cost_numpy(full, lo, hi)
