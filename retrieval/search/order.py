"""The fast search's visiting order, compiled (numba): a binary min-heap of (key, position,
level) entries for the best-first loop over lazily refined bounds, and the head of a stable
sort in one pass.

Twins: :func:`least_first` is the first ``m`` of ``np.argsort(values, kind="mergesort")``
(the tests compare them); the heap orders entries as ``heapq`` would order
``(key, position)`` tuples (ties to the earlier position, so the order is deterministic).
"""
from __future__ import annotations

import numpy as np

from retrieval.dtw.jit import HAVE_NUMBA, numba

if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True)
    def _heap_less(hk, hp, i, j):
        """Heap order: the smaller key, ties to the earlier position (deterministic)."""
        return hk[i] < hk[j] or (hk[i] == hk[j] and hp[i] < hp[j])

    @numba.njit(cache=True, nogil=True)
    def _heap_swap(hk, hp, hl, i, j):
        hk[i], hk[j] = hk[j], hk[i]
        hp[i], hp[j] = hp[j], hp[i]
        hl[i], hl[j] = hl[j], hl[i]

    @numba.njit(cache=True, nogil=True)
    def heap_push(hk, hp, hl, n, key, p, lvl):
        """Add (key, position, level) to the binary min-heap of ``n`` entries; returns n + 1."""
        hk[n], hp[n], hl[n] = key, p, lvl
        i = n
        while i > 0:
            up = (i - 1) >> 1
            if not _heap_less(hk, hp, i, up):
                break
            _heap_swap(hk, hp, hl, i, up)
            i = up
        return n + 1

    @numba.njit(cache=True, nogil=True)
    def heap_pop(hk, hp, hl, n):
        """Drop the least entry of the heap of ``n`` entries; returns n − 1."""
        n -= 1
        if n > 0:
            hk[0], hp[0], hl[0] = hk[n], hp[n], hl[n]
            i = 0
            while True:
                lft = 2 * i + 1
                if lft >= n:
                    break
                m = lft
                if lft + 1 < n and _heap_less(hk, hp, lft + 1, lft):
                    m = lft + 1
                if not _heap_less(hk, hp, m, i):
                    break
                _heap_swap(hk, hp, hl, i, m)
                i = m
        return n

    @numba.njit(cache=True, nogil=True)
    def least_first(values, m):
        """Indices of the ``m`` least ``values`` (all of them if fewer), in increasing order
        of (value, index) — the first ``m`` of a stable argsort, in one pass."""
        n = values.shape[0]
        m = m if m < n else n
        out = np.empty(m, np.int64)
        got = 0
        for i in range(n):
            v = values[i]
            if got == m and not v < values[out[m - 1]]:
                continue
            j = got if got < m else m - 1  # where it goes: shift the larger ones right
            while j > 0 and v < values[out[j - 1]]:
                out[j] = out[j - 1]
                j -= 1
            out[j] = i
            if got < m:
                got += 1
        return out
