import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
from views import build, vset, query
from harness import get_search, features, report, rows
from pathlib import Path
import numpy as np
base = get_search(); F = features(base)
mv = build([0.0, 45.0, 90.0]); qs = vset(np.nan)
Q = {Path(r["file"]).stem: query(qs, Path(r["file"]).stem) for r in rows}
def first_rank(hits, c, depth):
    return next((i for i, m in enumerate(hits) if m.label == c), depth)
for depth in (3, 5, 10):
    P = {}
    for k, (l, f) in F.items():
        a = base.search_features(f, k=depth); b = mv.search_features(Q[k], k=depth)
        labs = {m.label for m in a + b}
        sc = {c: (first_rank(a, c, depth) + first_rank(b, c, depth), c != a[0].label) for c in labs}
        P[k] = min(sc, key=sc.get)
    report(f"ensemble depth {depth}", P, F)
    print("   wrong:", " ".join(f"{k}>{P[k]}" for k, (l, _) in F.items() if P[k] != l))
