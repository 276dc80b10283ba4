import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
import time  # noqa: F401
from pathlib import Path  # noqa: F401

from harness import features, get_search, load, report, rows  # noqa: F401
import numpy as np  # noqa: F401
import pickle
s = get_search()
F = features(s)
sc_long, sc_short = pickle.load(open("/tmp/act_scales.pkl", "rb"))
H = {k: s.search_features(f, k=20) for k, (l, f) in F.items()}
for p in (0.1, 0.15, 0.2, 0.3):
    P = {}
    for k, (l, f) in F.items():
        sc = sc_short if len(f) < 2.75 * 30 else sc_long
        P[k] = min(H[k], key=lambda m: m.distance / sc[m.label][0] ** p).label
    report(f"class-scaled p{p}", P, F)
