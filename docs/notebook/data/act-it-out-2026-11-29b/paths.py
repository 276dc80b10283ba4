"""Where this round's scripts find the repository and keep their pickles
(clf.py writes lib.pkl, dtw_scores.py dtw.pkl, guard.py guard.pkl; ACT_CLF_DIR, default /tmp/act-clf)."""
import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[3]
OUT = Path(os.environ.get("ACT_CLF_DIR", "/tmp/act-clf"))
OUT.mkdir(parents=True, exist_ok=True)
for p in (str(REPO), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)
