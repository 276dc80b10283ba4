"""Scratch: hands columns in the summary and the re-rank only; codes on the base 18 columns."""
import sys
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[4]))
import numpy as np
from retrieval.features import register_feature_set, storybeam_feature_set
from retrieval.library import load_dataset, StoryBeamSearcher
from retrieval.codes import Quantizer
from lab.experiment.evaluation import evaluate
from lab.experiment.matchers import StoryBeamMatcher

data, w = sys.argv[1], float(sys.argv[2]); mode = sys.argv[3]  # mode: codes18 | all
name = f"sbh{w:g}"
register_feature_set(storybeam_feature_set(name=name, hands_weight=w))
clips = load_dataset(data, fps=30, feature_set=name)
BASE = 18

class S(StoryBeamSearcher):
    def shortlist_of(self, query, k, codes=None, exclude=None):
        return super().shortlist_of(query, k, self.quantizer.encode(np.ascontiguousarray(query[:, :BASE])), exclude)

class M(StoryBeamMatcher):
    def fit(self, refs):
        feats = [c.features for c in refs]
        q = Quantizer.fit(np.concatenate([f[:, :BASE] for f in feats]), self.dims)
        self.searcher = S(q, [q.encode(np.ascontiguousarray(f[:, :BASE])) for f in feats], feats, self.shortlist,
                          None, "auto", summary=self.summary)
        return self

def factory(n, **kw):
    kw.pop("seed", None); kw.pop("forbes_clusters", None)
    return M(dims=kw.get("dims", 6)) if mode == "codes18" else StoryBeamMatcher(dims=kw.get("dims", 6))

out = []
for split in ("random", "subject"):
    r = evaluate(clips, ["storybeam"], split=split, matcher_factory=factory)["storybeam"]
    acc = r.correct / r.total
    pc = {c: r.per_class_correct[c] / r.per_class_total[c] for c in r.per_class_total}
    out.append(f"{split} {acc*100:.2f} (min {min(pc.values())*100:.0f} {min(pc, key=pc.get)})")
print(data.split('/')[-1], w, mode, " | ".join(out))
