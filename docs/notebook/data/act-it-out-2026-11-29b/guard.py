"""The rendered guard's takes (seed 2, 60 trials, person and kid) from the bench's cache
(GUARD_CACHE, as `storybeam bench act-it-out --seed 2 --limit 60 --variants person,kid --cache DIR`):
their features, DTW class distances with the trial left out, into guard.pkl."""
import os
from pathlib import Path
from paths import OUT, REPO
GUARD_CACHE = Path(os.environ.get("GUARD_CACHE", "/work/data/guard/cache"))

import pickle
import numpy as np
from lab.bench.act_it_out import choose_trials, perform_and_track, FPS, WIDTH, HEIGHT
from retrieval.library.dataset import read_labels
from retrieval.library.act_search import ActSearch
data = REPO.parent / "shared/data/cmu"
rows = choose_trials(read_labels(data), 60, 2)
s = ActSearch.build(data, fps=FPS, moves=REPO / "assets/motions/moves")
C = ["walk", "run", "jump", "kick", "dance"]
out = []
for v in ["person", "kid"]:
    for r in rows:
        t = perform_and_track(r, v, 2, GUARD_CACHE)
        f = s.take_features(t["world"], t["image_xy"], t["valid"], FPS, (WIDTH, HEIGHT))
        m = s.search_features(f, k=60, exclude=[r.trial])
        best = {c: min([x.distance for x in m if x.label == c], default=np.inf) for c in C}
        top = s.search_features(f, k=1, exclude=[r.trial])[0].label
        out.append(dict(variant=v, trial=r.trial, label=r.label, feat=f, best=best, top=top))
    print(v, np.mean([o["top"] == o["label"] for o in out if o["variant"] == v]), flush=True)
pickle.dump(out, open(str(OUT / "guard.pkl"), "wb"))
