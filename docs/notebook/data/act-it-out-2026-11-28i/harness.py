"""Experiment harness: ActSearch built once, cached landmarks of the real set, variants."""
# Landmarks: the bench cache (storybeam bench act-it-out --videos /work/data/act_real --cache /work/data/act_real_cache).
import csv, glob, sys
from pathlib import Path
import numpy as np
REPO = Path(__file__).resolve().parents[4]
sys.path.insert(0, str(REPO))
from retrieval.library.act_search import ActSearch
from lab.bench.act_videos import pose_code_key

VID = Path("/work/data/act_real")
rows = list(csv.DictReader(open(VID / "labels.csv")))
key = pose_code_key()

def load(stem):
    f = sorted(glob.glob(f"/work/data/act_real_cache/videos/{stem}-*-{key}.npz"))
    import json
    z = np.load(f[-1])
    meta = json.loads(str(z["meta_json"]))
    return z["world"], z["image_xy"], z["valid"], meta["fps"], tuple(meta["image_size"])

def get_search(data=REPO.parent / "shared" / "data" / "cmu", moves=REPO / "assets" / "motions" / "moves"):
    return ActSearch.build(data, moves=moves)

def features(search):
    out = {}
    for r in rows:
        stem = Path(r["file"]).stem
        w, xy, v, fps, size = load(stem)
        out[stem] = (r["label"], search.take_features(w, xy, v, fps, size))
    return out

def report(name, preds, feats):
    classes = ["walk", "run", "jump", "kick", "dance"]
    ok = {c: [0, 0] for c in classes}
    for stem, (lab, _) in feats.items():
        ok[lab][1] += 1; ok[lab][0] += preds[stem] == lab
    tot = sum(v[0] for v in ok.values())
    print(f"{name:30s} {tot}/{len(feats)} " + " ".join(f"{c} {ok[c][0]}/{ok[c][1]}" for c in classes)
          + " | old47 " + str(sum(preds[s] == l for s, (l, _) in feats.items() if not (s.startswith('kick') and int(s[4:]) > 5))))
