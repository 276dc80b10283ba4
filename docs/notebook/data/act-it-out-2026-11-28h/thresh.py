"""Throwaway: the long-take limit (in windows) on three libraries; real clips x1 (and tiled for the main one)."""
import numpy as np, collections
from pathlib import Path
from lab.bench.act_videos import read_video_labels, track_clip, pose_code_key
from retrieval.library import ActSearch
import retrieval.library.act_search as act
rows = read_video_labels(Path('/work/data/act_real')); key = pose_code_key()
libs = {'main': ActSearch.build(Path('../shared/data/cmu'), moves=Path('assets/motions/moves')),
        'cmu': ActSearch.build(Path('../shared/data/cmu')), 'app': ActSearch.build(Path('assets/motions'))}
T = [(label, track_clip(v, Path('/work/data/act_real_cache'), key)) for v, label in rows]
for name, search in libs.items():
    F = [(l, search.take_features(t['world'], t['image_xy'], t['valid'], t['fps'], tuple(t['image_size']))) for l, t in T]
    for lim in (1.25, 1.5, 2.0, 1e9):
        act.LONG_TAKE_WINDOWS = lim
        acc = collections.Counter()
        for label, f in F:
            for rep in ((1, 2, 3) if name == 'main' else (1,)):
                acc[rep] += search.search_features(np.concatenate([f] * rep), k=1)[0].label == label
        print(name, lim, dict(acc), flush=True)
