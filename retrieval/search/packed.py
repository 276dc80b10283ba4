"""Many code sequences packed into flat arrays, what the fast search's compiled kernels take.

Per sequence: its plain codes, its runs of equal codes (value, length, and each run's
index among the sequence's distinct codes) and its distinct codes (value, count), each kind
concatenated over the sequences with per-sequence offsets. :func:`pack_one` (compiled)
computes one sequence's runs and distinct codes in two passes; its numpy twin is
:func:`~retrieval.dtw.run_length_encode`, :func:`~retrieval.dtw.distinct_counts` and a
``searchsorted`` (the path without numba, or without a code range to check), which give the
same arrays.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from retrieval.dtw import DTWError, distinct_counts, run_length_encode
from retrieval.dtw.jit import HAVE_NUMBA, numba

if HAVE_NUMBA:

    @numba.njit(cache=True, nogil=True)
    def pack_one(seq, size):
        """Runs (value, length), each run's index among the distinct codes, and the sorted
        distinct codes with their counts, of one sequence of codes in [0, size) — what
        run_length_encode, distinct_counts and a searchsorted give, in two passes. A code
        outside [0, size) gives empty arrays (the caller raises, naming the range)."""
        n = seq.shape[0]
        nr = 1
        for i in range(n):
            if seq[i] < 0 or seq[i] >= size:
                e = np.empty(0, np.int32)
                f = np.empty(0, np.int64)
                return e, f, f, e, f
            if i > 0 and seq[i] != seq[i - 1]:
                nr += 1
        run_val = np.empty(nr, np.int32)
        run_len = np.empty(nr, np.int64)
        r = 0
        start = 0
        for i in range(1, n + 1):
            if i == n or seq[i] != seq[i - 1]:
                run_val[r] = seq[i - 1]
                run_len[r] = i - start
                start = i
                r += 1
        cnt = np.zeros(size, np.int64)
        nd = 0
        for i in range(n):
            if cnt[seq[i]] == 0:
                nd += 1
            cnt[seq[i]] += 1
        dist_val = np.empty(nd, np.int32)
        dist_cnt = np.empty(nd, np.int64)
        k = 0
        for v in range(size):
            if cnt[v] > 0:
                dist_val[k] = v
                dist_cnt[k] = cnt[v]
                cnt[v] = k  # from here on: the code's index among the distinct codes
                k += 1
        run_didx = np.empty(nr, np.int64)
        for r in range(nr):
            run_didx[r] = cnt[run_val[r]]
        return run_val, run_len, run_didx, dist_val, dist_cnt


@dataclass
class PackedCodes:
    """Many code sequences packed into flat arrays (what the compiled kernels take):
    plain codes, runs (value, length) and distinct codes (value, count), each with
    per-sequence offsets."""

    codes: np.ndarray
    code_off: np.ndarray
    run_val: np.ndarray
    run_len: np.ndarray
    run_off: np.ndarray
    run_didx: np.ndarray  # index of each run's code within its sequence's distinct codes
    dist_val: np.ndarray
    dist_cnt: np.ndarray
    dist_off: np.ndarray

    @classmethod
    def from_sequences(cls, sequences: Sequence[np.ndarray], size: int | None = None) -> "PackedCodes":
        if len(sequences) == 0:
            raise DTWError("no code sequences to search")
        seqs = [np.ascontiguousarray(s, dtype=np.int32) for s in sequences]

        def out_of_range(i: int, s: np.ndarray) -> DTWError:
            return DTWError(f"sequence {i}: codes must lie in [0, {size}), got [{s.min()}, {s.max()}]")

        for i, s in enumerate(seqs):
            if s.ndim != 1 or s.size == 0:
                raise DTWError(f"sequence {i}: codes must be a non-empty 1-D array, got shape {s.shape}")
        if HAVE_NUMBA and size is not None:
            parts = [pack_one(s, size) for s in seqs]  # one pass each instead of sort + searches; checks the range
            for i, (s, p) in enumerate(zip(seqs, parts)):
                if not len(p[0]):
                    raise out_of_range(i, s)
            if len(seqs) == 1:  # one query (the search's fixed cost): its arrays as they are, no concatenation
                rv, rl, rd, dv, dc = parts[0]
                return cls(seqs[0], np.array([0, len(seqs[0])], np.int64), rv, rl, np.array([0, len(rv)], np.int64),
                           rd, dv, dc, np.array([0, len(dv)], np.int64))
            runs = [(p[0], p[1]) for p in parts]
            didx = [p[2] for p in parts]
            dists = [(p[3], p[4]) for p in parts]
        else:
            for i, s in enumerate(seqs):
                if size is not None and (s.min() < 0 or s.max() >= size):
                    raise out_of_range(i, s)
            runs = [run_length_encode(s) for s in seqs]
            dists = [distinct_counts(s) for s in seqs]
            didx = [np.searchsorted(d[0], r[0]).astype(np.int64) for r, d in zip(runs, dists)]
        off = lambda parts: np.concatenate(([0], np.cumsum([len(p) for p in parts]))).astype(np.int64)  # noqa: E731
        return cls(
            np.concatenate(seqs), off(seqs),
            np.concatenate([r[0] for r in runs]), np.concatenate([r[1] for r in runs]), off([r[0] for r in runs]),
            np.concatenate(didx),
            np.concatenate([d[0] for d in dists]), np.concatenate([d[1] for d in dists]), off([d[0] for d in dists]),
        )

    def __len__(self) -> int:
        return len(self.code_off) - 1

    @property
    def lengths(self) -> np.ndarray:
        return np.diff(self.code_off)

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in (self.codes, self.code_off, self.run_val, self.run_len, self.run_off,
                                            self.run_didx, self.dist_val, self.dist_cnt, self.dist_off)))

    def sequence(self, i: int) -> np.ndarray:
        return self.codes[self.code_off[i]:self.code_off[i + 1]]

    def arrays(self) -> tuple:
        return (self.codes, self.code_off, self.run_val, self.run_len, self.run_off, self.run_didx,
                self.dist_val, self.dist_cnt, self.dist_off)
