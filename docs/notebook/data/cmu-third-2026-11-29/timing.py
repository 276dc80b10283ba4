"""find() time, codes-only identity shortlist (before) against codes + summary (now), interleaved, one core."""
import sys, time, glob, numpy as np
sys.path.insert(0, "/work/main")
from retrieval.library.index import MotionIndex
from retrieval.library import storybeam_search as S
from retrieval.motion import load_motion
idx = MotionIndex.build("../shared/data/cmu")
sb = idx._storybeam
files = sorted(glob.glob("/work/data/cmu-third/*/*.bvh")) + sorted(glob.glob("/work/data/cmu-other/rig/*.bvh"))[:60]
qs = [np.asarray(idx.features(load_motion(f)), dtype=np.float32).astype(np.float64) for f in files]
before = S.StoryBeamSearcher.fit([S.centre(f) for f in sb.features], sb.quantizer.n, sb.shortlist, sb.band, sb.backend, sb.mode, summary=0)
now = sb.identity_searcher()
for s in (before, now):
    s.search(S.centre(qs[0]), 1)
tb, tn = [], []
for rep in range(3):
    for q in qs:
        c = S.centre(q)
        t0 = time.perf_counter(); before.search(c, 1); t1 = time.perf_counter(); now.search(c, 1); t2 = time.perf_counter()
        tb.append(t1 - t0); tn.append(t2 - t1)
tb, tn = np.array(tb) * 1e3, np.array(tn) * 1e3
print(f"{len(qs)} queries x 3: before median {np.median(tb):.3f} ms p95 {np.percentile(tb,95):.3f}; "
      f"now median {np.median(tn):.3f} ms p95 {np.percentile(tn,95):.3f}; ratio of medians {np.median(tn)/np.median(tb):.2f}")
