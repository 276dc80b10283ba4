from paths import OUT

import pickle
import numpy as np
from clf4 import C, R, d, desc, fit, rep, y
dt = pickle.load(open(str(OUT / "dtw.pkl"), "rb"))
kind = "pct+asym"
X = np.array([desc(f, kind) for f in d["lib"] + d["short"]])
Xr = np.array([desc(f, kind) for _, (l, f) in R])
mu, sd = X.mean(0), X.std(0) + 1e-6
Xs, Xrs = (X - mu) / sd, (Xr - mu) / sd
D = np.array([[dt[k]["best"][c] for c in C] for k, _ in R])
rep("dtw class-min", np.argmin(D, 1))
for lam in [1e-2, 3e-2, 1e-1, 3e-1]:
    W, b = fit(Xs, y, lam)
    Z = Xrs @ W + b; logp = Z - np.log(np.exp(Z).sum(1, keepdims=True))
    rep(f"clf lam={lam}", np.argmax(Z, 1))
    for tau in [0.02, 0.05, 0.1]:
        rel = (D - D.min(1, keepdims=True)) / D.min(1, keepdims=True)
        rep(f"  fuse tau={tau}", np.argmax(logp - rel / tau, 1))
    # rank fusion
    rd = np.argsort(np.argsort(D, 1), 1); rc = np.argsort(np.argsort(-Z, 1), 1)
    rep("  rank fusion (dtw ties)", np.argmin(rd + rc + 0.1 * rd, 1))
    for i, (k, _) in enumerate(R):
        if k.startswith("kick"): print("   ", k, C[np.argmax(Z[i])], np.round(np.exp(logp[i]), 2), C[np.argmin(D[i])], np.round(rel[i], 3))
