import sys
from paths import OUT, REPO
import pickle
import numpy as np
sys.path.insert(0, str(REPO / "docs/notebook/data/act-it-out-2026-11-28i"))
import harness as H
s = H.get_search()
feats = H.features(s)
C = ["walk", "run", "jump", "kick", "dance"]
nonkick = sorted({n for n, l in zip(s.short.names, s.short.index.labels) if l != "kick"})
fps = s.fps
out = {}
for k, (l, f) in feats.items():
    whole = s.search_features(f, k=5)
    w = int(round(2.0 * fps)); step = int(round(fps / 3))
    best = np.inf
    for st in list(range(0, max(1, len(f) - w + 1), step)):
        m = s.short._search_whole(f[st:st + w], 1, nonkick)
        if m: best = min(best, m[0].distance)
    out[k] = dict(label=l, top=whole[0].label, d=whole[0].distance, kick=best)
    print(k, l, whole[0].label, round(whole[0].distance, 3), round(best, 3), round(best / whole[0].distance, 3), flush=True)
pickle.dump(out, open(str(OUT / "kickwin.pkl"), "wb"))
