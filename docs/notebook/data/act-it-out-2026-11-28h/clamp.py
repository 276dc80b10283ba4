"""Throwaway: query features clamped to the library's per-feature range (percentiles)."""
import numpy as np, collections
from pathlib import Path
from lab.bench.act_videos import read_video_labels, track_clip, pose_code_key
from retrieval.library import ActSearch
import retrieval.library.act_search as A
search = ActSearch.build(Path('../shared/data/cmu'), moves=Path('assets/motions/moves'))
rows = read_video_labels(Path('/work/data/act_real')); key = pose_code_key()
allf = np.concatenate(search.index.clip_features)
print('feature count', allf.shape, [n for n in search.feature_set.names] if hasattr(search.feature_set,'names') else '')
takes = []
for video, label in rows:
    t = track_clip(video, Path('/work/data/act_real_cache'), key)
    takes.append((video.name, label, search.take_features(t['world'], t['image_xy'], t['valid'], t['fps'], tuple(t['image_size']))))
orig = ActSearch.search_features
for p in [None, 100, 99.9, 99.5, 99]:
    if p is not None:
        lo, hi = np.percentile(allf, 100 - p, axis=0), np.percentile(allf, p, axis=0)
        slo, shi = lo, hi
        if search.short is not None:
            sf = np.concatenate(search.short.index.clip_features); slo, shi = np.percentile(sf, 100 - p, axis=0), np.percentile(sf, p, axis=0)
    per = collections.Counter(); tot = 0; wrong = []
    for name, label, f in takes:
        g = f if p is None else np.clip(f, slo if len(f) < A.SHORT_TAKE_SECONDS * search.fps else lo, shi if len(f) < A.SHORT_TAKE_SECONDS * search.fps else hi)
        h = search.search_features(g, k=1)[0]
        ok = h.label == label; tot += ok; per[label] += ok
        if not ok: wrong.append(f'{name}->{h.label}')
    print(p, tot, dict(per), wrong, flush=True)
