import sys
from paths import OUT

import pickle
import numpy as np
from scipy.optimize import minimize
from retrieval.features.frontal import FRONTAL
d = pickle.load(open(str(OUT / "lib.pkl"), "rb"))
C = ["walk", "run", "jump", "kick", "dance"]
def desc(f, kind="pct+asym"):
    f = FRONTAL.relative_to_segment(np.asarray(f, dtype=np.float64))
    parts = [np.percentile(f, p, 0) for p in [5, 25, 50, 75, 95]]
    a = f[:, 12] - f[:, 13]; kk = f[:, 8] - f[:, 9]
    if "asym" in kind:
        parts.append(np.array([np.percentile(np.abs(a), 95), np.percentile(np.abs(kk), 95), np.abs(a).max(), np.abs(kk).max()]))
    return np.concatenate(parts)
def fit(X, y, lam):
    n, p = X.shape
    cw = len(y) / (5 * np.bincount(y, minlength=5)); sw = cw[y]; Y = np.eye(5)[y]
    def fg(w):
        W = w[:p * 5].reshape(p, 5); b = w[p * 5:]
        Z = X @ W + b; Z -= Z.max(1, keepdims=True); lse = np.log(np.exp(Z).sum(1, keepdims=True))
        L = -(sw * (Y * (Z - lse)).sum(1)).sum() / n + 0.5 * lam * (W ** 2).sum()
        P = np.exp(Z - lse); G = (P - Y) * sw[:, None] / n
        return L, np.concatenate([(X.T @ G + lam * W).ravel(), G.sum(0)])
    r = minimize(fg, np.zeros(p * 5 + 5), jac=True, method="L-BFGS-B", options=dict(maxiter=3000))
    return r.x[:p * 5].reshape(p, 5), r.x[p * 5:]
y = np.array([C.index(l) for l in d["labels"] + d["slabels"]])
names = np.array(d["names"] + d["snames"])
subj = np.array(d["subjects"] + d["subjects"][:0] + [None] * len(d["short"]))
R = list(d["real"].items()); yr = np.array([C.index(l) for _, (l, f) in R])
def rep(name, pred, yt=yr):
    per = " ".join(f"{c} {np.sum((pred == i) & (yt == i))}/{np.sum(yt == i)}" for i, c in enumerate(C))
    print(f"{name:34s} {np.sum(pred == yt)}/{len(yt)}  {per}", flush=True)
if __name__ == "__main__":
    kind = sys.argv[1] if len(sys.argv) > 1 else "pct+asym"
    X = np.array([desc(f, kind) for f in d["lib"] + d["short"]])
    Xr = np.array([desc(f, kind) for _, (l, f) in R])
    mu, sd = X.mean(0), X.std(0) + 1e-6
    Xs, Xrs = (X - mu) / sd, (Xr - mu) / sd
    # library-side choice of lambda: leave one trial's windows out, 5 folds by trial name
    trials = np.array([n.split("@")[0] for n in names])
    ut = np.unique(trials); rng = np.random.default_rng(0); fold = dict(zip(ut, rng.integers(0, 5, len(ut))))
    fv = np.array([fold[t] for t in trials])
    for lam in [1e-3, 1e-2, 3e-2, 1e-1, 3e-1, 1.0]:
        pr = np.empty(len(y), int)
        for k in range(5):
            W, b = fit(Xs[fv != k], y[fv != k], lam); pr[fv == k] = np.argmax(Xs[fv == k] @ W + b, 1)
        bal = np.mean([np.mean(pr[y == i] == i) for i in range(5)])
        W, b = fit(Xs, y, lam)
        P = np.argmax(Xrs @ W + b, 1)
        print(f"lam={lam}: library 5-fold balanced {bal:.3f}", end="  ")
        rep("real", P)
