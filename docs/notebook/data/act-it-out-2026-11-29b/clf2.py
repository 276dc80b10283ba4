from paths import OUT

import pickle
import numpy as np
from retrieval.features.frontal import FRONTAL
d = pickle.load(open(str(OUT / "lib.pkl"), "rb"))
C = ["walk", "run", "jump", "kick", "dance"]
def desc(f):
    f = FRONTAL.relative_to_segment(np.asarray(f, dtype=np.float64))
    v = np.diff(f, axis=0) * 24.0 if len(f) > 1 else np.zeros((1, f.shape[1]))
    parts = [f.mean(0), f.std(0), np.percentile(f, 10, 0), np.percentile(f, 90, 0),
             np.abs(v).mean(0), np.percentile(np.abs(v), 90, 0)]
    a = f[:, 12] - f[:, 13]; kk = f[:, 8] - f[:, 9]
    parts.append(np.array([np.abs(a).max(), np.percentile(np.abs(a), 90), np.abs(kk).max(),
                           np.percentile(np.abs(kk), 90), np.std(a), np.std(kk)]))
    return np.concatenate(parts)
X = np.array([desc(f) for f in d["lib"]] + [desc(f) for f in d["short"]])
y = np.array([C.index(l) for l in d["labels"] + d["slabels"]])
subj = np.array(d["subjects"] + [None] * len(d["short"]))
R = [(k, C.index(l), desc(f)) for k, (l, f) in d["real"].items()]
Xr = np.array([r[2] for r in R]); yr = np.array([r[1] for r in R])
mu, sd = X.mean(0), X.std(0) + 1e-6
def fit(X, y, lam=1e-2, iters=600, lr=0.5):
    n, p = X.shape; W = np.zeros((p, 5)); b = np.zeros(5)
    cw = len(y) / (5 * np.bincount(y, minlength=5)); sw = cw[y]
    Y = np.eye(5)[y]
    for it in range(iters):
        Z = X @ W + b; Z -= Z.max(1, keepdims=True); P = np.exp(Z); P /= P.sum(1, keepdims=True)
        G = (P - Y) * sw[:, None] / n
        W -= lr * (X.T @ G + lam * W); b -= lr * G.sum(0)
    return W, b
def rep(name, pred):
    per = " ".join(f"{c} {np.sum((pred == i) & (yr == i))}/{np.sum(yr == i)}" for i, c in enumerate(C))
    print(f"{name:28s} {np.sum(pred == yr)}/{len(yr)}  {per}")
Xs = (X - mu) / sd; Xrs = (Xr - mu) / sd
for lam in [1e-3, 1e-2, 3e-2, 1e-1, 3e-1]:
    W, b = fit(Xs, y, lam)
    rep(f"softmax lam={lam}", np.argmax(Xrs @ W + b, 1))
# kNN in descriptor space
for k in [1, 5, 15]:
    D = ((Xrs[:, None, :] - Xs[None]) ** 2).sum(-1)
    idx = np.argsort(D, 1)[:, :k]
    pred = np.array([np.bincount(y[i], minlength=5).argmax() for i in idx])
    rep(f"knn k={k}", pred)
