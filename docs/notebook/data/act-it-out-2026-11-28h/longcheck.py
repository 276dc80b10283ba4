"""Throwaway: the product's search_features on real clips tiled x1..x3."""
import numpy as np, collections
from pathlib import Path
from lab.bench.act_videos import read_video_labels, track_clip, pose_code_key
from retrieval.library import ActSearch
search = ActSearch.build(Path('../shared/data/cmu'), moves=Path('assets/motions/moves'))
rows = read_video_labels(Path('/work/data/act_real')); key = pose_code_key()
acc = collections.Counter(); per = collections.Counter()
for video, label in rows:
    t = track_clip(video, Path('/work/data/act_real_cache'), key)
    f = search.take_features(t['world'], t['image_xy'], t['valid'], t['fps'], tuple(t['image_size']))
    out = []
    for rep in (1, 2, 3):
        h = search.search_features(np.concatenate([f] * rep), k=3)
        acc[rep] += h[0].label == label; out.append(h[0].label)
        if rep == 1: per[label] += h[0].label == label
    print(video.name, label, f'{len(f)/search.fps:.1f}s', out, flush=True)
print(dict(acc), dict(per))
