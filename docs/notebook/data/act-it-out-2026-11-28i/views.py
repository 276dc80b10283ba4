"""Multi-view library experiment: query as seen (no turn, depth dropped) vs library seen from yaw views."""
import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
from dataclasses import dataclass, replace
import numpy as np
import time  # noqa: F401
from pathlib import Path  # noqa: F401

from harness import REPO, features, get_search, load, report, rows  # noqa: F401
from retrieval.features.frontal import FRONTAL, FrontalFeatureSet, face_camera, measured_rest
from retrieval.features.relational import FeatureSet, register_feature_set
from retrieval.library.dataset import load_dataset
from retrieval.library.act_search import ActSearch, resample_positions
from retrieval.motion.landmarks import landmarks_to_positions

@dataclass(frozen=True)
class ViewSet(FrontalFeatureSet):
    view: float = 0.0      # degrees from facing; nan = as seen (no turn)
    def from_positions(self, pos, joint_map, body_size, fps=None, rest=None):
        pos = np.asarray(pos, dtype=np.float64)
        if np.isnan(self.view):
            out = pos.copy()
        else:
            out = face_camera(pos, joint_map, keep_depth=True)
            a = np.radians(self.view); c, s = np.cos(a), np.sin(a)
            out = out @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T
        out[..., 2] = 0.0
        return self.relative_to_segment(FeatureSet.from_positions(self, out, joint_map, body_size, fps, rest))

def vset(v):
    name = "frontal_view_" + ("seen" if np.isnan(v) else f"{v:g}")
    return register_feature_set(ViewSet(name=name, specs=FRONTAL.specs, normalise=FRONTAL.normalise,
                                        description="exp", relative=FRONTAL.relative,
                                        floor_percentile=FRONTAL.floor_percentile, view=v))

def build(views, data=REPO.parent / "shared" / "data" / "cmu", moves=REPO / "assets" / "motions" / "moves"):
    clips = []
    for v in views:
        fs = vset(v).name
        cs = load_dataset(data, fps=30.0, feature_set=fs, cache=False)
        held = {c.trial for c in cs}
        cs += [c for c in load_dataset(moves, fps=30.0, feature_set=fs, cache=False) if c.trial not in held]
        clips += [replace(c, trial=f"{c.trial}~{v:g}") for c in cs]
    return ActSearch.from_clips(clips)

def query(f_set, stem):
    w, xy, v, fps, size = load(stem)
    pos, jm, leg = landmarks_to_positions(w, xy, v, size, fps)
    pos = resample_positions(pos, fps, 30.0)
    return f_set.from_positions(pos, jm, leg, 30.0, measured_rest(pos, jm))

if __name__ == "__main__":
    for tag, views, qv in [("views0,45,90 seen", [0.0, 45.0, 90.0], np.nan),
                           ("views0,30,60,90 seen", [0.0, 30.0, 60.0, 90.0], np.nan),
                           ("view0 seen", [0.0], np.nan)]:
        t0 = time.time(); s = build(views); bt = time.time() - t0
        qs = vset(qv)
        F = {Path(r["file"]).stem: (r["label"], query(qs, Path(r["file"]).stem)) for r in rows}
        t0 = time.time()
        P = {k: s.search_features(f, k=3)[0].label for k, (l, f) in F.items()}
        st = (time.time() - t0) / len(F)
        report(tag, P, F); print(f"   build {bt:.0f}s windows {len(s.index)} search {st*1e3:.1f} ms/take")
        wrong = [k for k, (l, _) in F.items() if P[k] != l]; print("   wrong:", " ".join(f"{k}>{P[k]}" for k in wrong))
