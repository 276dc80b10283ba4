import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
import time  # noqa: F401
from pathlib import Path  # noqa: F401

from harness import features, get_search, load, report, rows  # noqa: F401
import numpy as np  # noqa: F401
from math import comb
s = get_search()
F = features(s)
def trials_per_class(idx):
    t = {}
    for n, l in zip(idx.names, idx.index.labels):
        t.setdefault(l, set()).add(n)
    return {l: len(v) for l, v in t.items()}
TPC = trials_per_class(s); TPC_S = trials_per_class(s.short)
print(TPC, TPC_S)
def emin(ds, n, N):
    """expected min over a random N-subset of n trials whose smallest len(ds) distances are ds (sorted);
    unknown ones are taken at the last known distance."""
    ds = sorted(ds) + [ds[-1] if ds else 9.9] * (n - len(ds))
    N = min(N, n)
    tot = comb(n, N)
    return sum(d * comb(n - i - 1, N - 1) for i, d in enumerate(ds)) / tot
def pred(f, K, N):
    short = len(f) < 2.75 * 30
    tpc = TPC_S if short else TPC
    hits = s.search_features(f, k=K)
    by = {}
    for m in hits: by.setdefault(m.label, []).append(m.distance)
    NN = N if N else min(tpc.values())
    sc = {c: emin(by.get(c, []), tpc[c], NN) for c in tpc}
    return min(sc, key=sc.get)
base = {k: s.search_features(f, k=3)[0].label for k, (l, f) in F.items()}
report("baseline", base, F)
for K in (20, 40):
    for N in (0, 20):
        P = {k: pred(f, K, N) for k, (l, f) in F.items()}
        report(f"balanced K{K} N{N or 'min'}", P, F)
        print("   wrong:", " ".join(f"{k}>{P[k]}" for k, (l, _) in F.items() if P[k] != l))
