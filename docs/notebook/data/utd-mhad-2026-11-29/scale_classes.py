import sys
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[4]))
import numpy as np
from lab.bench.scale_library import derived_takes
from lab.experiment import stratified_folds
from retrieval.library import load_dataset, StoryBeamSearcher
from retrieval.features import get_feature_set
from retrieval.dtw import dtw_features
fs, sl, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
clips = load_dataset("../shared/data/cmu", fps=30, feature_set=fs)
parts = stratified_folds([c.label for c in clips], 3, 0)
qidx = list(parts[0]); refs = [clips[i] for i in np.setdiff1d(np.arange(len(clips)), qidx)]
lib, labels = [], []
for label, f in derived_takes(refs, 2600, 9.0, 0, feature_set=fs):
    lib.append(np.ascontiguousarray(f, dtype=np.float64)); labels.append(label)
S = StoryBeamSearcher.fit(lib, shortlist=sl, code_columns=get_feature_set(fs).code_columns)
same = same_cls = right_sb = right_ex = 0
rng = np.random.default_rng(0)
pick = rng.choice(len(qidx), n, replace=False)
for k in pick:
    q = clips[qidx[k]]
    h = S.search(q.features)[0]
    d = np.array([dtw_features(q.features, r) for r in lib]); b = int(np.argmin(d))
    same += h.index == b; same_cls += labels[h.index] == labels[b]
    right_sb += labels[h.index] == q.label; right_ex += labels[b] == q.label
print(fs, sl, f"{n} queries: same clip {same}, same class {same_cls}, right class storybeam {right_sb} / exact {right_ex}")
