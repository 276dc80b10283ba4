import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
import time  # noqa: F401
from pathlib import Path  # noqa: F401

from harness import features, get_search, load, report, rows  # noqa: F401
import numpy as np  # noqa: F401
s = get_search()
F = features(s)
def class_scales(idx, depth=20, stride=1):
    d = {}
    feats = idx.index.clip_features
    for i in range(0, len(idx.index), stride):
        lab = idx.index.labels[i]; trial = idx.names[i]
        hits = idx._search_whole(np.asarray(feats[i], float), depth, {trial})
        same = next((m.distance for m in hits if m.label == lab), None)
        anyd = hits[0].distance if hits else None
        d.setdefault(lab, []).append((same, anyd))
    out = {}
    for lab, v in d.items():
        same = [a for a, _ in v if a is not None]
        out[lab] = (float(np.median(same)), len(same), len(v), float(np.median([b for _, b in v])))
    return out
t0 = time.time()
sc_long = class_scales(s, stride=2); sc_short = class_scales(s.short, stride=3)
print("scales", time.time() - t0); print(sc_long); print(sc_short)
import pickle; pickle.dump((sc_long, sc_short), open("/tmp/act_scales.pkl", "wb"))
def pred(f, power):
    idx_short = len(f) < 2.75 * 30
    sc = sc_short if idx_short else sc_long
    hits = s.search_features(f, k=20)
    return min(hits, key=lambda m: m.distance / sc[m.label][0] ** power).label
base = {k: s.search_features(f, k=3)[0].label for k, (l, f) in F.items()}
report("baseline", base, F)
for p in (0.5, 1.0):
    P = {k: pred(f, p) for k, (l, f) in F.items()}
    report(f"class-scaled p{p}", P, F)
    print("   wrong:", " ".join(f"{k}>{P[k]}" for k, (l, _) in F.items() if P[k] != l))
