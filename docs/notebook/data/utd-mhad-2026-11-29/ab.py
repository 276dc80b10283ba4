"""Scratch: in-process A/B of the storybeam search time, old set (no hands) vs new, per query interleaved."""
import sys, time
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[4]))
import numpy as np
from retrieval.library import load_dataset, StoryBeamSearcher
from retrieval.features import get_feature_set
from lab.experiment.evaluation import stratified_folds, subject_folds
data, split = sys.argv[1], sys.argv[2]
sets = ["storybeam-no-hands", "storybeam"]
C = {fs: load_dataset(data, fps=30, feature_set=fs) for fs in sets}
labels = [c.label for c in C[sets[0]]]
parts = stratified_folds(labels, 3, 0) if split == "random" else subject_folds([c.subject for c in C[sets[0]]])
tot = {fs: [] for fs in sets}
for qidx in parts:
    ref = np.setdiff1d(np.arange(len(labels)), qidx)
    S = {fs: StoryBeamSearcher.fit([C[fs][i].features for i in ref], code_columns=get_feature_set(fs).code_columns) for fs in sets}
    for fs in sets: S[fs].search(C[fs][qidx[0]].features)
    for q in qidx:
        ts = {fs: [] for fs in sets}
        for rep in range(7):
            for fs in (sets if rep % 2 else sets[::-1]):
                f = C[fs][q].features
                t0 = time.process_time(); S[fs].search(f); ts[fs].append(time.process_time() - t0)
        for fs in sets: tot[fs].append(np.median(ts[fs]))
a, b = (sum(tot[fs]) for fs in sets)
print(data.split('/')[-1], split, f"no-hands {a:.3f} s  hands {b:.3f} s  ratio {b/a:.3f}")
