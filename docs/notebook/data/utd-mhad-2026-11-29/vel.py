"""Scratch: the clip summary plus each column's mean absolute frame-to-frame change (x fps x w)."""
import sys
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[4]))
import numpy as np
from retrieval.library import load_dataset, StoryBeamSearcher
from retrieval.search import clip_summary
from retrieval.features import get_feature_set
from lab.experiment.evaluation import evaluate
from lab.experiment.matchers import StoryBeamMatcher
data, w = sys.argv[1], float(sys.argv[2])
clips = load_dataset(data, fps=30, feature_set="storybeam")
def summ(f):
    v = np.abs(np.diff(f, axis=0)).mean(axis=0) * 30.0 * w if len(f) > 1 else np.zeros(f.shape[1])
    return np.concatenate([clip_summary(f), v])
class S(StoryBeamSearcher):
    def shortlist_of(self, query, k, codes=None, exclude=None):
        self.summaries_v = getattr(self, "summaries_v", None)
        self.summaries = None
        try:
            out = super().shortlist_of(query, k, codes, exclude)
        finally:
            self.summaries = self.summaries_v
        taken = {i for i, _ in out}
        d = np.linalg.norm(self.summaries_v - summ(query), axis=1)
        add = [int(i) for i in np.argsort(d, kind="stable") if int(i) not in taken][: self.summary]
        return out + [(i, None) for i in add]
class M(StoryBeamMatcher):
    def fit(self, refs):
        b = StoryBeamSearcher.fit([c.features for c in refs], code_columns=get_feature_set("storybeam").code_columns)
        s = S(b.quantizer, b.codes, b.features, b.shortlist, summary=b.summary if b.summary else 2)
        s.summaries_v = np.stack([summ(c.features) for c in refs]); s.summaries = s.summaries_v
        self.searcher = s
        return self
out = []
for split in ("random", "subject"):
    r = evaluate(clips, ["storybeam"], split=split, matcher_factory=lambda n, **kw: M())["storybeam"]
    pc = {c: r.per_class_correct[c] / r.per_class_total[c] for c in r.per_class_total}
    out.append(f"{split} {r.correct / r.total * 100:.2f}" + (f" wave {pc.get('wave', 0)*100:.0f}" if 'wave' in pc else ""))
print(data.split('/')[-1], "vel w", w, " | ".join(out))
