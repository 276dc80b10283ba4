"""The take's frontal features smoothed in time (a Gaussian of SIGMA frames) before the search:
real set and rendered guard (guard.pkl from guard.py)."""
import pickle
import sys
from paths import OUT, REPO
import numpy as np
from scipy.ndimage import gaussian_filter1d
sys.path.insert(0, str(REPO / "docs/notebook/data/act-it-out-2026-11-28i"))
import harness as H
s = H.get_search()
print("fps", s.fps)
feats = H.features(s)
G = pickle.load(open(OUT / "guard.pkl", "rb"))
def sm(f, sig):
    return np.asarray(f) if sig == 0 else gaussian_filter1d(np.asarray(f, float), sig, axis=0, mode="nearest")


SIGMAS = (0, 0.5, 1, 1.5, 2)
right = {sig: [0, 0, 0] for sig in SIGMAS}  # real set, person, kid
for k, (l, f) in feats.items():
    a = [s.search_features(sm(f, sig), k=5)[0].label for sig in SIGMAS]
    for sig, p in zip(SIGMAS, a):
        right[sig][0] += p == l
    if len(set(a)) > 1:
        print(k, l, a)
for x in G:
    a = [s.search_features(sm(x["feat"], sig), k=1, exclude=[x["trial"]])[0].label for sig in SIGMAS]
    for sig, p in zip(SIGMAS, a):
        right[sig][1 if x["variant"] == "person" else 2] += p == x["label"]
    if len(set(a)) > 1:
        print(x["variant"], x["trial"], x["label"], a)
for sig in SIGMAS:
    print(f"sigma {sig} frames at 30 fps: real {right[sig][0]}/54, person {right[sig][1]}/60, kid {right[sig][2]}/60")
