"""Time StoryBeamSearcher.search(q, k=1) per query on bandai2 leave-one-style-out, one core.
Run with PYTHONPATH=<side's repo>. Prints total us/query (median over rounds)."""
import sys, time, json, numpy as np
from retrieval.library import load_dataset, StoryBeamSearcher
data = sys.argv[1]; rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 3
clips = load_dataset(data, fps=30.0, feature_set="storybeam")
subjects = sorted({c.subject for c in clips})
folds = []
for s in subjects:
    ref = [c for c in clips if c.subject != s]; qs = [c for c in clips if c.subject == s]
    folds.append((StoryBeamSearcher.fit([c.features for c in ref], 6), qs, ref))
ans = []
for srch, qs, ref in folds:  # warm-up + answers
    for q in qs:
        h = srch.search(q.features, k=1)[0]; ans.append((q.trial, ref[h.index].trial, round(h.distance, 9)))
per = []
for r in range(rounds):
    t0 = time.perf_counter(); n = 0
    for srch, qs, _ in folds:
        for q in qs:
            srch.search(q.features, k=1); n += 1
    per.append((time.perf_counter() - t0) / n * 1e6)
acc = np.mean([next(c.label for c in clips if c.trial == a) == next(c.label for c in clips if c.trial == b) for a, b, _ in ans])
print(json.dumps({"us_per_query": per, "median": float(np.median(per)), "queries": n, "acc": float(acc),
                  "answers_hash": hash(tuple(ans)) & 0xffffffff}))
