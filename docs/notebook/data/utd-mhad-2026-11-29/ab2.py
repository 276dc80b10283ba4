"""Scratch: in-process A/B/C of the storybeam search time over configurations (set, shortlist, summary),
every query by every configuration interleaved, 7 runs, median per query, summed (process CPU time)."""
import sys, time
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parents[4]))
import numpy as np
from retrieval.library import load_dataset, StoryBeamSearcher
from retrieval.features import get_feature_set
from lab.experiment.evaluation import stratified_folds, subject_folds
data, split = sys.argv[1], sys.argv[2]
configs = [("storybeam-no-hands", 4, 0), ("storybeam-no-hands", 4, 2), ("storybeam", 4, 2), ("storybeam", 3, 2)]
C = {fs: load_dataset(data, fps=30, feature_set=fs) for fs in {c[0] for c in configs}}
first = C[configs[0][0]]
labels = [c.label for c in first]
parts = stratified_folds(labels, 3, 0) if split == "random" else subject_folds([c.subject for c in first])
tot = {c: [] for c in configs}
correct = {c: 0 for c in configs}
for qidx in parts:
    ref = np.setdiff1d(np.arange(len(labels)), qidx)
    S = {c: StoryBeamSearcher.fit([C[c[0]][i].features for i in ref], shortlist=c[1], summary=c[2],
                                  code_columns=get_feature_set(c[0]).code_columns) for c in configs}
    for c in configs: S[c].search(C[c[0]][qidx[0]].features)
    for q in qidx:
        ts = {c: [] for c in configs}
        for rep in range(7):
            order = configs if rep % 2 else configs[::-1]
            for c in order:
                f = C[c[0]][q].features
                t0 = time.process_time(); h = S[c].search(f); ts[c].append(time.process_time() - t0)
                if rep == 0: correct[c] += labels[ref[h[0].index]] == labels[q]
        for c in configs: tot[c].append(np.median(ts[c]))
base = sum(tot[configs[0]])
for c in configs:
    print(Path(data).name, split, c, f"{sum(tot[c]):.3f} s  x{sum(tot[c]) / base:.3f}  acc {correct[c] / len(labels) * 100:.2f}")
