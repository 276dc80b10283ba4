import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
from harness import get_search
import numpy as np
s = get_search()
names = s.feature_set.names
la, ra = names.index("lankle_height"), names.index("rankle_height")
best = {}
for n, l, f in zip(s.names, s.index.labels, s.index.clip_features):
    f = np.asarray(f, float); a = np.abs(f[:, la] - f[:, ra]).max(); hi = f[:, [la, ra]].max()
    if l == "kick" or a > 2.5:
        b = best.get(n, (l, 0, 0)); best[n] = (l, max(b[1], a), max(b[2], hi))
for n, v in sorted(best.items(), key=lambda x: -x[1][1])[:20]: print(n, v[0], round(v[1], 2), round(v[2], 2))
