from paths import OUT

import pickle
import numpy as np
from retrieval.features.frontal import FRONTAL
d = pickle.load(open(str(OUT / "lib.pkl"), "rb"))
N = d["colnames"]
def stats(f):
    f = FRONTAL.relative_to_segment(np.asarray(f, dtype=np.float64))
    ah = np.maximum(f[:, 12], f[:, 13]); dh = np.abs(f[:, 12] - f[:, 13])
    hips = f[:, 14]
    return dict(maxank=ah.max(), p95dh=np.percentile(dh, 95), maxdh=dh.max(), hipr=np.ptp(hips),
                maxaa=f[:, 1].max(), p90aa=np.percentile(f[:,1],90), hand=np.percentile(f[:,0],90), vel=np.percentile(np.abs(np.diff(f[:,12]-f[:,13])),95)*24)
for k, (l, f) in d["real"].items():
    if l in ("kick", "run", "walk"):
        print(k, " ".join(f"{a}={b:.2f}" for a, b in stats(f).items()))
print("--- library")
import collections
agg = collections.defaultdict(list)
for f, l, n in zip(d["lib"], d["labels"], d["names"]):
    agg[l].append(list(stats(f).values()))
keys = list(stats(d["lib"][0]).keys())
for l, v in agg.items():
    v = np.array(v); print(l, len(v), " ".join(f"{k}={np.percentile(v[:,i],10):.2f}/{np.median(v[:,i]):.2f}/{np.percentile(v[:,i],90):.2f}" for i, k in enumerate(keys)))
for f, l, n in zip(d["lib"], d["labels"], d["names"]):
    if l == "kick" and not n.startswith("m_"): print(n, " ".join(f"{a}={b:.2f}" for a, b in stats(f).items()))
