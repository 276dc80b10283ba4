import sys
from paths import OUT, REPO

import pickle
import numpy as np
sys.path.insert(0, str(REPO / "docs/notebook/data/act-it-out-2026-11-28i"))
import harness as H
s = H.get_search()
feats = H.features(s)
C = ["walk", "run", "jump", "kick", "dance"]
out = {}
for k, (l, f) in feats.items():
    m = s.search_features(f, k=60)
    best = {c: min([x.distance for x in m if x.label == c], default=np.inf) for c in C}
    out[k] = dict(label=l, best=best, top=s.search_features(f, k=5)[0].label)
pickle.dump(out, open(str(OUT / "dtw.pkl"), "wb"))
print(sum(v["top"] == v["label"] for v in out.values()), {k: v["top"] for k, v in out.items() if k.startswith("kick")})
