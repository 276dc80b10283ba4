"""Scratch: hands columns in the clip summary only (codes and re-rank on the 18)."""
import sys
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[4]))
import numpy as np
from retrieval.library import load_dataset, StoryBeamSearcher
from retrieval.search import clip_summary
from lab.experiment.evaluation import evaluate
from lab.experiment.matchers import StoryBeamMatcher
data = sys.argv[1]
clips = load_dataset(data, fps=30, feature_set="storybeam")
B = 18
class S(StoryBeamSearcher):
    def search(self, query, k=1, codes=None, exclude=None):
        q = np.ascontiguousarray(query, dtype=np.float64)
        return self.rerank(np.ascontiguousarray(q[:, :B]), self.shortlist_of(q, k, self.quantizer.encode(np.ascontiguousarray(q[:, :B])), exclude), k)
class M(StoryBeamMatcher):
    def fit(self, refs):
        base = StoryBeamSearcher.fit([np.ascontiguousarray(c.features[:, :B]) for c in refs], summary=2)
        s = S(base.quantizer, base.codes, [np.ascontiguousarray(c.features[:, :B]) for c in refs], 4, summary=2)
        s.summaries = np.stack([clip_summary(c.features) for c in refs])
        self.searcher = s
        return self
out = []
for split in ("random", "subject"):
    r = evaluate(clips, ["storybeam"], split=split, matcher_factory=lambda n, **kw: M())["storybeam"]
    out.append(f"{split} {r.correct / r.total * 100:.2f}")
print(data.split('/')[-1], "summary-only hands", " | ".join(out))
