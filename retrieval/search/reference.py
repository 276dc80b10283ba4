"""Brute-force reference searches: every clip, no pruning, ``argsort(kind="stable")``.

What the fast searches must equal, bit for bit; the tests and the benchmark compare them.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from retrieval.codes import DiffTable
from retrieval.dtw import dtw_codes, find_subsequence, run_length_encode, runs_dtw_numpy


def brute_force_runs(queries: Sequence[np.ndarray], library: Sequence[np.ndarray], table: DiffTable,
                     k: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Reference k-NN for the ``"runs"`` approximation (numpy, every clip)."""
    idx = np.full((len(queries), k), -1, np.int64)
    dist = np.full((len(queries), k), np.inf)
    for qi, q in enumerate(queries):
        av, al = run_length_encode(q)
        d = np.empty(len(library))
        for c, b in enumerate(library):
            bv, bl = run_length_encode(b)
            d[c] = runs_dtw_numpy(table.lookup(av[:, None], bv[None, :]), al, bl) / (len(q) + len(b))
        order = np.argsort(d, kind="stable")[:k]
        idx[qi, :len(order)] = order
        dist[qi, :len(order)] = d[order]
    return idx, dist


def brute_force(queries: Sequence[np.ndarray], library: Sequence[np.ndarray], table, k: int = 1,
                band: int | None = None, backend: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Reference k-NN: the seed's DTW against every clip, ``argsort(kind="stable")``."""

    idx = np.full((len(queries), k), -1, np.int64)
    dist = np.full((len(queries), k), np.inf)
    for qi, q in enumerate(queries):
        d = np.array([dtw_codes(q, r, table, band, backend) for r in library])
        order = np.argsort(d, kind="stable")[:k]
        idx[qi, :len(order)] = order
        dist[qi, :len(order)] = d[order]
    return idx, dist


def brute_force_subsequence(query: np.ndarray, library: Sequence[np.ndarray], table: DiffTable, k: int = 1,
                            backend: str = "auto") -> list[tuple[int, int, int, float]]:
    """Reference subsequence search: :func:`~retrieval.dtw.find_subsequence` in every clip,
    the ``k`` best as (clip, start, end, distance), ties by the lower clip index."""
    hits = [find_subsequence(query, take, table, backend) for take in library]
    d = np.array([h.distance for h in hits])
    order = np.argsort(d, kind="stable")[:k]
    return [(int(c), hits[c].start, hits[c].end, float(d[c])) for c in order]
