"""Scratch: where the storybeam shortlist loses UTD-MHAD's waves (leave one subject out)."""
import sys
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[4]))
import numpy as np
from retrieval.library import load_dataset
from retrieval.library.storybeam_search import StoryBeamSearcher
from retrieval.search import clip_summary
from retrieval.dtw import dtw_features
data = sys.argv[1]; cls = sys.argv[2]; fs = sys.argv[3] if len(sys.argv) > 3 else "storybeam"
clips = load_dataset(data, fps=30, feature_set=fs)
subs = sorted({c.subject for c in clips})
stats = []
for s in subs:
    lib = [c for c in clips if c.subject != s]
    S = StoryBeamSearcher.fit([c.features for c in lib], code_columns=__import__("retrieval.features", fromlist=["x"]).get_feature_set(fs).code_columns)
    sums = np.stack([clip_summary(c.features) for c in lib])
    for q in [c for c in clips if c.subject == s and c.label == cls]:
        d = np.array([dtw_features(q.features, c.features) for c in lib])
        nn = int(np.argmin(d))
        codes = S.quantizer.encode(q.features)
        res = S.searcher.search([codes], k=len(lib), parallel=False)
        code_rank = list(res.indices[0]).index(nn)
        sd = np.linalg.norm(sums - clip_summary(q.features), axis=1)
        sum_rank = int(np.argsort(sd, kind="stable").tolist().index(nn))
        got = S.search(q.features, 1)[0]
        # first right-class positions
        lab = np.array([c.label for c in lib])
        code_first = next(k for k, i in enumerate(res.indices[0]) if lab[i] == cls)
        sum_first = next(k for k, i in enumerate(np.argsort(sd, kind="stable")) if lab[i] == cls)
        stats.append((q.trial, lib[nn].label, code_rank, sum_rank, lib[got.index].label, code_first, sum_first))
        print(q.trial, "dtwNN", lib[nn].label, f"{d[nn]:.3f}", "codeRank", code_rank, "sumRank", sum_rank, "-> sb", lib[got.index].label,
              f"{got.distance:.3f}", "first-right code/sum", code_first, sum_first)
