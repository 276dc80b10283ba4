import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
import time  # noqa: F401
from pathlib import Path  # noqa: F401

from harness import features, get_search, load, report, rows  # noqa: F401
import numpy as np  # noqa: F401
s = get_search()
F = features(s)
sh = s.short
def slide(f, idx, w, hop, rule):
    n = len(f)
    if n <= w * 1.1:
        return idx._search_whole(f, 5, ())[0].label
    starts = list(range(0, n - w + 1, hop))
    if starts[-1] != n - w: starts.append(n - w)
    ans = [idx._search_whole(f[a:a + w], 5, ()) for a in starts]
    if rule == "min":
        return min((a[0] for a in ans), key=lambda m: m.distance).label
    if rule == "rank":
        labs = {m.label for a in ans for m in a}
        sc = {c: sum(next((i for i, m in enumerate(a) if m.label == c), 5) for a in ans) for c in labs}
        return min(sc, key=sc.get)
    if rule == "rel":  # each window's top answer weighted by its margin relative to that window's 5th
        sc = {}
        for a in ans:
            sc[a[0].label] = sc.get(a[0].label, 0) + (a[-1].distance - a[0].distance) / a[-1].distance
        return max(sc, key=sc.get)
for w_s, hop in [(2.0, 10), (2.0, 5), (1.5, 10)]:
    w = int(w_s * 30)
    for rule in ("min", "rank", "rel"):
        idx = sh
        p = {k: slide(f, idx, w, hop, rule) for k, (l, f) in F.items()}
        report(f"short w{w_s} hop{hop} {rule}", p, F)
