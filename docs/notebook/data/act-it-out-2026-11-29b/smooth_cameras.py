"""The act-cameras bench (seed 2, 60 trials, every condition) with the take's features smoothed (sigma 1 frame) or not."""
import numpy as np
from paths import REPO
from scipy.ndimage import gaussian_filter1d
from retrieval.library.act_search import ActSearch
from lab.bench.act_cameras import run_act_cameras_bench
data = REPO.parent / "shared/data/cmu"
s = ActSearch.build(data, fps=30.0, moves=REPO / "assets/motions/moves")
orig = ActSearch.take_features
for sig in [0, 1.0]:
    def tf(self, *a, _sig=sig, **k):
        f = orig(self, *a, **k)
        return f if _sig == 0 else gaussian_filter1d(f, _sig, axis=0, mode="nearest")
    ActSearch.take_features = tf
    for noise in [0.0, 2.0]:
        r = run_act_cameras_bench(data, 60, 2, search=s, noise_px=noise, moves=REPO / "assets/motions/moves")
        accs = {c["condition"]["name"]: round(c["accuracy"], 3) for c in r["conditions"]}
        print(f"sigma {sig} noise {noise}: mean {np.mean(list(accs.values())):.3f} min {min(accs.values()):.3f}", accs, flush=True)
