from paths import OUT
import pickle
import numpy as np
from clf4 import C, R, d, desc, fit, names, rep, y
G = pickle.load(open(str(OUT / "guard.pkl"), "rb"))
dt = pickle.load(open(str(OUT / "dtw.pkl"), "rb"))
kind = "pct+asym"
X = np.array([desc(f, kind) for f in d["lib"] + d["short"]])
mu, sd = X.mean(0), X.std(0) + 1e-6
Xs = (X - mu) / sd
trial_of = np.array([n.split("@")[0] for n in names])
trials = sorted({g["trial"] for g in G})
Xr = (np.array([desc(f, kind) for _, (l, f) in R]) - mu) / sd
Dr = np.array([[dt[k]["best"][c] for c in C] for k, _ in R])
def pick(Z, D, n, m):
    order = np.argsort(D)
    keep = [c for c in order[:n] if D[c] <= D[order[0]] * (1 + m)]
    return max(keep, key=lambda c: Z[c])
for lam in [0.1, 0.3]:
    W, b = fit(Xs, y, lam)
    models = {t: fit(Xs[trial_of != t], y[trial_of != t], lam) for t in trials}
    for n in [2, 3]:
        for m in [0.02, 0.05, 0.1, 1.0]:
            pr = np.array([pick(Xr[i] @ W + b, Dr[i], n, m) for i in range(len(R))])
            g_ok = {"person": [], "kid": []}
            for g in G:
                Wt, bt = models[g["trial"]]
                z = ((desc(g["feat"], kind) - mu) / sd) @ Wt + bt
                D = np.array([g["best"][c] for c in C])
                g_ok[g["variant"]].append(C[pick(z, D, n, m)] == g["label"])
            print(f"lam={lam} top{n} margin {m}: guard person {np.mean(g_ok['person']):.3f} kid {np.mean(g_ok['kid']):.3f}", end=" | ")
            rep("real", pr)
