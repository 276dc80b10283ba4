"""Throwaway: long takes searched as windows; aggregation variants, on real clips tiled x1..x3."""
import sys, numpy as np, collections
from pathlib import Path
from lab.bench.act_videos import read_video_labels, track_clip, pose_code_key
from retrieval.library import ActSearch
from retrieval.library.act_search import WINDOW_SECONDS
search = ActSearch.build(Path('../shared/data/cmu'), moves=Path('assets/motions/moves'))
rows = read_video_labels(Path('/work/data/act_real')); key = pose_code_key()
fps = search.fps; W = int(round(WINDOW_SECONDS * fps)); LONG = float(sys.argv[1]) if len(sys.argv) > 1 else 1.25
K = 5
def variants(f):
    if len(f) <= LONG * W:
        h = search.search_features(f, k=1)[0].label
        return {v: h for v in ('whole', 'nearest', 'vote', 'sumcls', 'meanrank')}
    whole = search.search_features(f, k=1)[0].label
    starts = list(range(0, len(f) - W + 1, W // 2))
    if starts[-1] != len(f) - W: starts.append(len(f) - W)
    per = [search.search_features(f[s:s + W], k=K) for s in starts]
    nearest = min((m[0] for m in per), key=lambda m: m.distance).label
    votes = collections.Counter(m[0].label for m in per)
    top = max(votes.values()); tied = [c for c, n in votes.items() if n == top]
    vote = min((m[0] for m in per if m[0].label in tied), key=lambda m: m.distance).label
    cls = collections.defaultdict(float)
    classes = {m.label for p in per for m in p}
    for p in per:
        worst = p[-1].distance
        for c in classes:
            ds = [m.distance for m in p if m.label == c]
            cls[c] += min(ds) if ds else worst * 1.1
    sumcls = min(cls, key=cls.get)
    rk = collections.defaultdict(float)
    for p in per:
        seen = {}
        for i, m in enumerate(p):
            seen.setdefault(m.label, i)
        for c in classes: rk[c] += seen.get(c, K)
    meanrank = min(rk, key=lambda c: (rk[c], cls[c]))
    return {'whole': whole, 'nearest': nearest, 'vote': vote, 'sumcls': sumcls, 'meanrank': meanrank}
acc = collections.defaultdict(int); n = collections.defaultdict(int)
for video, label in rows:
    t = track_clip(video, Path('/work/data/act_real_cache'), key)
    f = search.take_features(t['world'], t['image_xy'], t['valid'], t['fps'], tuple(t['image_size']))
    line = [video.name, label, f'{len(f)/fps:.1f}s']
    for rep in (1, 2, 3):
        r = variants(np.concatenate([f] * rep))
        for v, a in r.items():
            acc[(rep, v)] += a == label; n[(rep, v)] += 1
        line.append(','.join(f'{v[0]}{"+" if a == label else "-"}' for v, a in r.items()))
    print(' '.join(line), flush=True)
for rep in (1, 2, 3):
    print(rep, {v: acc[(rep, v)] for v in ('whole', 'nearest', 'vote', 'sumcls', 'meanrank')}, n[(rep, 'whole')])
