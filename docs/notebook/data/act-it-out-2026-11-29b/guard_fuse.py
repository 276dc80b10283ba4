from paths import OUT

import pickle
import numpy as np
from clf4 import C, d, desc, fit, names, y
G = pickle.load(open(str(OUT / "guard.pkl"), "rb"))
kind = "pct+asym"
X = np.array([desc(f, kind) for f in d["lib"] + d["short"]])
mu, sd = X.mean(0), X.std(0) + 1e-6
Xs = (X - mu) / sd
trial_of = np.array([n.split("@")[0] for n in names])
print("names sample", names[:3], names[-3:])
trials = sorted({g["trial"] for g in G})
combos = [(lam, tau) for lam in [0.03, 0.1, 0.3] for tau in [0.02, 0.05, 0.1, None]]
res = {c: {"person": [], "kid": []} for c in combos}
models = {}
for lam in [0.03, 0.1, 0.3]:
    for t in trials:
        keep = trial_of != t
        models[(lam, t)] = fit(Xs[keep], y[keep], lam)
    print("fitted", lam, flush=True)
for g in G:
    xq = (desc(g["feat"], kind) - mu) / sd
    D = np.array([g["best"][c] for c in C]); rel = (D - D.min()) / D.min()
    for lam, tau in combos:
        W, b = models[(lam, g["trial"])]
        Z = xq @ W + b; logp = Z - np.log(np.exp(Z).sum())
        p = np.argmax(logp) if tau is None else np.argmax(logp - rel / tau)
        res[(lam, tau)][g["variant"]].append(C[p] == g["label"])
print("dtw top:", {v: np.mean([g["top"] == g["label"] for g in G if g["variant"] == v]) for v in ["person", "kid"]})
for c in combos:
    print(c, {v: round(float(np.mean(r)), 3) for v, r in res[c].items()})
# per class, kid and person, for the classifier alone and one fused setting
from collections import Counter
for (lam, tau) in [(0.3, None), (0.3, 0.05)]:
    for v in ["person", "kid"]:
        cnt = Counter(); tot = Counter()
        for g in G:
            if g["variant"] != v: continue
            xq = (desc(g["feat"], kind) - mu) / sd
            D = np.array([g["best"][c] for c in C]); rel = (D - D.min()) / D.min()
            W, b = models[(lam, g["trial"])]; Z = xq @ W + b; logp = Z - np.log(np.exp(Z).sum())
            p = np.argmax(logp) if tau is None else np.argmax(logp - rel / tau)
            tot[g["label"]] += 1; cnt[(g["label"], C[p])] += 1
        print(lam, tau, v, {c: f"{cnt[(c, c)]}/{tot[c]}" for c in C}, "misses:", {k: n for k, n in cnt.items() if k[0] != k[1]})
    dt = Counter((g["label"], g["top"]) for g in G if g["variant"] == "kid")
print("dtw kid", {c: dt[(c, c)] for c in C}, {k: n for k, n in dt.items() if k[0] != k[1]})
