"""Where the fast exact search spends its time, and what the range-cover bound buys.

Paper protocol's folds (shared CMU clips, 3-fold, n = 6, default 120 fps): every query of
each fold is searched (k = 1, one core) with the range-cover bound on and off, the
variants interleaved query by query so a busy neighbour slows both alike; answers must be
identical. Then one pass times the stages of the default search (packing, the query's
table rows, the envelope bounds, the candidate loop) with the compiled kernels called one
by one.

    .venv/bin/python scripts/profile_fast_search.py [FPS]
"""
from __future__ import annotations

import sys
import time

import numpy as np

from app.bench.retrieval import load_clips
from retrieval.codes import DiffTable
from retrieval.dtw.kernels import numba
from retrieval.experiment import stratified_folds
from retrieval.search.fast import FastSearcher, PackedCodes, SearchStats, _lbs_serial, _query_rows, _refine, warm_up
from retrieval.experiment import stack_frames
from retrieval.codes import Quantizer


def fold_codes(fps: float) -> list[dict]:
    clips, _, note = load_clips(None, fps, progress=False)
    if note:
        print(note)
    parts = stratified_folds([c.label for c in clips], 3, 0)
    out = []
    for qidx in parts:
        ridx = np.setdiff1d(np.arange(len(clips)), qidx)
        qz = Quantizer.fit(stack_frames([clips[i].features for i in ridx]), 6)
        out.append(dict(table=DiffTable.from_ratios(qz.ratios), refs=[qz.encode(clips[i].features) for i in ridx],
                        queries=[qz.encode(clips[i].features) for i in qidx]))
    return out


def compare(folds: list[dict]) -> None:
    variants = {"range bound on (default)": {}, "range bound off": dict(range_bound=False)}
    secs = {v: 0.0 for v in variants}
    stats = {v: SearchStats() for v in variants}
    answers = {v: [] for v in variants}
    for fd in folds:
        searchers = {v: FastSearcher(fd["refs"], fd["table"], **kw) for v, kw in variants.items()}
        for qn, q in enumerate(fd["queries"]):
            names = list(variants)
            for v in names[qn % 2:] + names[:qn % 2]:
                t = time.perf_counter()
                r = searchers[v].search([q], k=1, parallel=False)
                secs[v] += time.perf_counter() - t
                answers[v].append((int(r.indices[0, 0]), float(r.distances[0, 0])))
                s = r.stats
                stats[v].add(np.array([s.candidates, s.pruned, s.abandoned, s.completed, s.range_rejected]))
    a, b = answers.values()
    print(f"identical answers: {a == b}")
    for v in variants:
        s = stats[v]
        print(f"{v:<26} {secs[v]:7.3f} s  pruned {s.pruned}  abandoned {s.abandoned} "
              f"(of which rejected by the range bound {s.range_rejected})  completed {s.completed}  / {s.candidates}")
    on, off = secs.values()
    print(f"speed-up of the range bound: {on and off / on:.2f}x")


def stages(folds: list[dict]) -> None:
    t = dict(pack=0.0, rows=0.0, bounds=0.0, loop=0.0)
    for fd in folds:
        table = fd["table"]
        s = FastSearcher(fd["refs"], table)
        L, LV = s._L, s._LV
        use_rle = s._kernel(max(len(q) for q in fd["queries"]))
        for q in fd["queries"]:
            t0 = time.perf_counter()
            packed = PackedCodes.from_sequences([q], table.size)
            t1 = time.perf_counter()
            R, colmin = _query_rows(packed.dist_val, s._vocab, table.F, table.absdiff, s._shift, s._mask)
            t2 = time.perf_counter()
            lbs = np.empty(len(s.library))
            rowmins = np.empty((len(s.library), len(packed.dist_val)), np.float32)
            _lbs_serial(0, packed.arrays(), L, table.F, table.absdiff, s._shift, s._mask, R, colmin, lbs, rowmins)
            t3 = time.perf_counter()
            _refine(0, packed.arrays(), L, LV, table.F, table.absdiff, s._shift, s._mask, R, lbs, rowmins, colmin, 1, use_rle, -1,
                    np.full(1, -1, np.int64), np.full(1, np.inf), np.zeros(5, np.int64), True, True)
            t4 = time.perf_counter()
            for key, dt in zip(t, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
                t[key] += dt
    total = sum(t.values())
    print("stages of the default search: " + ", ".join(f"{k} {v:.3f} s ({100 * v / total:.0f} %)" for k, v in t.items()))


def main() -> None:
    fps = float(sys.argv[1]) if len(sys.argv) > 1 else 120.0
    numba.set_num_threads(1)
    warm_up()
    folds = fold_codes(fps)
    print(f"{sum(len(f['queries']) for f in folds)} queries, {fps:g} fps")
    compare(folds)
    stages(folds)


if __name__ == "__main__":
    main()
