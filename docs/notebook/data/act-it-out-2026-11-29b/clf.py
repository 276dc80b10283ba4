"""Experiment: a discriminative classifier over window descriptors, trained on the act library."""
import sys
from paths import OUT, REPO

import pickle, time
import numpy as np
sys.path.insert(0, str(REPO / "docs/notebook/data/act-it-out-2026-11-28i"))
import harness as H
from retrieval.features.frontal import FRONTAL
CACHE = OUT / "lib.pkl"
if CACHE.exists():
    d = pickle.load(open(CACHE, "rb"))
else:
    t = time.time()
    s = H.get_search()
    print("built", time.time() - t, len(s.index))
    feats = H.features(s)
    d = dict(lib=[np.asarray(f) for f in s.index.clip_features], labels=list(s.index.labels), names=s.names,
             subjects=s.subjects,
             short=[np.asarray(f) for f in s.short.index.clip_features], slabels=list(s.short.index.labels), snames=s.short.names,
             real={k: (l, np.asarray(f)) for k, (l, f) in feats.items()}, colnames=FRONTAL.names)
    pickle.dump(d, open(CACHE, "wb"))
print(len(d["lib"]), d["lib"][0].shape, d["colnames"])
from collections import Counter
print(Counter(d["labels"]))
print({k: (l, f.shape) for k, (l, f) in list(d["real"].items())[:5]})
