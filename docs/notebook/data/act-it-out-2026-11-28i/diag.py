import sys; sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
import time  # noqa: F401
from pathlib import Path  # noqa: F401

from harness import features, get_search, load, report, rows  # noqa: F401
import numpy as np  # noqa: F401
s = get_search()
F = features(s)
names = s.feature_set.names
la, ra, hp = names.index("lankle_height"), names.index("rankle_height"), names.index("hips_height")
print(names)
rows_ = []
for k, (l, f) in F.items():
    # heights are weighted? features are raw values (weights applied in distance?)
    a = f[:, [la, ra]]
    hi = a.max(axis=1); lo = a.min(axis=1)
    asym = hi - lo
    i = int(np.argmax(asym))
    rows_.append((l, k, round(float(asym.max()), 2), round(float(lo[i]), 2), round(float(np.percentile(lo, 90)), 2), round(float(f[:, hp].max() - np.median(f[:, hp])), 2)))
for r in sorted(rows_): print(*r)
