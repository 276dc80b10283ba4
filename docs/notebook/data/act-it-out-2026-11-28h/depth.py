import numpy as np, collections, time
from pathlib import Path
from lab.bench.act_videos import read_video_labels, track_clip, pose_code_key
from retrieval.library import ActSearch
import retrieval.library.act_search as act
search = ActSearch.build(Path('../shared/data/cmu'), moves=Path('assets/motions/moves'))
rows = read_video_labels(Path('/work/data/act_real')); key = pose_code_key()
F = []
for video, label in rows:
    t = track_clip(video, Path('/work/data/act_real_cache'), key)
    F.append((label, search.take_features(t['world'], t['image_xy'], t['valid'], t['fps'], tuple(t['image_size']))))
search.search_features(F[0][1], k=1)
for depth in (2, 3, 5, 8):
    act.LONG_DEPTH = depth
    acc = collections.Counter(); ms = []
    for label, f in F:
        for rep in (1, 2, 3):
            q = np.concatenate([f] * rep); t0 = time.perf_counter()
            h = search.search_features(q, k=3); dt = (time.perf_counter() - t0) * 1e3
            if rep == 1 and len(f) > 1.25 * 105: ms.append(dt)
            acc[rep] += h[0].label == label
    print(depth, dict(acc), 'long x1 ms median', round(float(np.median(ms)), 1), flush=True)
