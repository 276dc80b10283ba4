"""Scratch: one code version's storybeam search time (its defaults), median of 7 per query, summed."""
import sys, time
root, data, split = sys.argv[1], sys.argv[2], sys.argv[3]
sys.path.insert(0, root)
import numpy as np
from retrieval.library import load_dataset, StoryBeamSearcher
from lab.experiment import stratified_folds, subject_folds
clips = load_dataset(data, fps=30, feature_set="storybeam")
labels = [c.label for c in clips]
parts = stratified_folds(labels, 3, 0) if split == "random" else subject_folds([c.subject for c in clips])
tot = 0.0
for qidx in parts:
    ref = np.setdiff1d(np.arange(len(labels)), qidx)
    S = StoryBeamSearcher.fit([clips[i].features for i in ref])
    S.search(clips[qidx[0]].features)
    for q in qidx:
        ts = []
        for rep in range(7):
            t0 = time.process_time(); S.search(clips[q].features); ts.append(time.process_time() - t0)
        tot += np.median(ts)
print(root, data.split("/")[-1], split, f"{tot:.4f}", clips[0].features.shape[1])
