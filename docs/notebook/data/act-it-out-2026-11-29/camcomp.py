"""Camera motion subtracted from the cached landmarks: python camflow.py DIR; python camcomp.py DIR."""
import sys, numpy as np
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "act-it-out-2026-11-28i"))
import harness as H
s = H.get_search()
base, comp = {}, {}
for r in H.rows:
    stem = r["file"][:-4]
    w, xy, v, fps, size = H.load(stem)
    sh = np.load(f"{sys.argv[1]}/{stem}.npy")  # camflow.py DIR wrote them
    cum = np.cumsum(sh, 0)[: len(xy)]
    if len(cum) < len(xy): cum = np.vstack([cum, np.repeat(cum[-1:], len(xy) - len(cum), 0)])
    xy2 = xy - cum[:, None, :]
    base[stem] = (r["label"], s.search_features(s.take_features(w, xy, v, fps, size), k=3)[0].label)
    comp[stem] = (r["label"], s.search_features(s.take_features(w, xy2, v, fps, size), k=3)[0].label)
for name, d in (("base", base), ("camera-compensated", comp)):
    ok = sum(a == b for a, b in d.values()); print(name, ok, "/", len(d))
for k in base:
    if base[k][1] != comp[k][1]: print("  ", k, base[k][0], base[k][1], "->", comp[k][1])
