from paths import OUT

import pickle
import numpy as np
from retrieval.features.frontal import FRONTAL
d = pickle.load(open(str(OUT / "lib.pkl"), "rb"))
C = ["walk", "run", "jump", "kick", "dance"]
rng = np.random.default_rng(0)
def desc(f, kind):
    f = FRONTAL.relative_to_segment(np.asarray(f, dtype=np.float64))
    ps = [5, 25, 50, 75, 95] if "pct" in kind else [10, 90]
    parts = [np.percentile(f, p, 0) for p in ps]
    if "std" in kind: parts.append(f.std(0))
    a = f[:, 12] - f[:, 13]; kk = f[:, 8] - f[:, 9]
    if "asym" in kind:
        parts.append(np.array([np.percentile(np.abs(a), 95), np.percentile(np.abs(kk), 95), np.abs(a).max(), np.abs(kk).max()]))
    if "vel" in kind:
        from scipy.ndimage import gaussian_filter1d
        g = gaussian_filter1d(f, 2.0, axis=0)
        v = np.abs(np.diff(g, axis=0)) * 24
        parts += [v.mean(0), np.percentile(v, 90, 0)]
    return np.concatenate(parts)
def fit(X, y, lam, iters=1500, lr=0.5):
    n, p = X.shape; W = np.zeros((p, 5)); b = np.zeros(5)
    cw = len(y) / (5 * np.bincount(y, minlength=5)); sw = cw[y]; Y = np.eye(5)[y]
    for it in range(iters):
        Z = X @ W + b; Z -= Z.max(1, keepdims=True); P = np.exp(Z); P /= P.sum(1, keepdims=True)
        G = (P - Y) * sw[:, None] / n
        W -= lr * (X.T @ G + lam * W); b -= lr * G.sum(0)
    return W, b
y = np.array([C.index(l) for l in d["labels"] + d["slabels"]])
R = list(d["real"].items()); yr = np.array([C.index(l) for _, (l, f) in R])
def rep(name, pred):
    per = " ".join(f"{c} {np.sum((pred == i) & (yr == i))}/{np.sum(yr == i)}" for i, c in enumerate(C))
    print(f"{name:34s} {np.sum(pred == yr)}/{len(yr)}  {per}", flush=True)
for kind in ["p", "pct", "pct+std", "pct+asym", "pct+std+asym", "pct+std+asym+vel"]:
    X = np.array([desc(f, kind) for f in d["lib"] + d["short"]])
    Xr = np.array([desc(f, kind) for _, (l, f) in R])
    mu, sd = X.mean(0), X.std(0) + 1e-6
    for lam in [1e-2, 1e-1, 3e-1]:
        W, b = fit((X - mu) / sd, y, lam)
        rep(f"{kind} lam={lam}", np.argmax(((Xr - mu) / sd) @ W + b, 1))
