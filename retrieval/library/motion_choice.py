"""Turn a story's motion choice into a clip: a named clip, or a class ("walk", "jump")
answered from the motion index.

A child picks *what* the character does (walk, run, jump, dance, kick), not which
capture; the app may also hand over a motion to imitate. :func:`choose_clip` answers:

* with a query motion: the nearest indexed clip of the wanted class (the research's
  retrieval, restricted to the class);
* with a class only: the class's most typical clip — the one with the smallest median
  code-DTW distance to the other clips of its class — so a plain "walk" is an ordinary
  walk, not the stealthy one.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.library.dataset import read_labels
from retrieval.motion import Motion


def choose_clip(index, label: str | None = None, query: Motion | None = None, exclude: tuple[str, ...] = ()) -> tuple[str, str, float]:
    """(trial, label, distance) chosen from ``index`` (a :class:`retrieval.library.index.MotionIndex`)."""
    if label is None and query is None:
        raise StoryBeamError("choose a motion by class, by a query motion, or both")
    known = sorted(set(index.labels))
    if label is not None and label not in known:
        raise StoryBeamError(f"no {label!r} clips in the motion library (it has: {', '.join(known)})")
    if query is not None:
        for m in index.query(query, k=len(index)):
            if (label is None or m.label == label) and m.trial not in exclude:
                return m.trial, m.label, m.distance
        raise StoryBeamError(f"no clip left to answer the query for {label!r}")
    members = [t for t, lab in zip(index.trials, index.labels) if lab == label and t not in exclude]
    if not members:
        raise StoryBeamError(f"every {label!r} clip is excluded")
    if len(members) == 1:
        return members[0], label, 0.0
    typical = []
    for t in members:
        d = [m.distance for m in index.similar_to(t, k=len(index)) if m.label == label and m.trial in members]
        typical.append(float(np.median(d)) if d else np.inf)
    k = int(np.argmin(typical))
    return members[k], label, typical[k]


def clip_path(folder: str | Path, trial: str) -> Path:
    """The motion file of ``trial`` in a labelled folder (its labels.csv ``file`` column)."""
    for row in read_labels(folder):
        if row.trial == trial:
            return row.file
    raise StoryBeamError(f"{folder}: no clip {trial!r} in labels.csv")
