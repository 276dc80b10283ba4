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
from retrieval.library.index import MotionIndex
from retrieval.motion import Motion


def choose_clip(index: MotionIndex, label: str | None = None, query: Motion | None = None,
                exclude: tuple[str, ...] = ()) -> tuple[str, str, float]:
    """(trial, label, distance) chosen from ``index`` (a :class:`~retrieval.library.index.MotionIndex`).

    Method: both questions go through the index's exact fast search restricted to the
    allowed clips (:meth:`MotionIndex.among`: the class's clips, minus ``exclude``) —
    the same answer as searching the whole library and filtering, ties by library order,
    without a DTW against every other clip."""
    if label is None and query is None:
        raise StoryBeamError("choose a motion by class, by a query motion, or both")
    known = sorted(set(index.labels))
    if label is not None and label not in known:
        raise StoryBeamError(f"no {label!r} clips in the motion library (it has: {', '.join(known)})")
    excluded = set(exclude)
    if query is not None:
        allowed = [i for i, (t, lab) in enumerate(zip(index.trials, index.labels))
                   if (label is None or lab == label) and t not in excluded]
        best = index.among(index.encode(query), allowed, k=1)
        if not best:
            raise StoryBeamError(f"no clip left to answer the query for {label!r}")
        return best[0].trial, best[0].label, best[0].distance
    members = [i for i, (t, lab) in enumerate(zip(index.trials, index.labels)) if lab == label and t not in excluded]
    if not members:
        raise StoryBeamError(f"every {label!r} clip is excluded")
    if len(members) == 1:
        return index.trials[members[0]], label, 0.0
    typical = []
    for i in members:
        d = [m.distance for m in index.among(index.codes[i], members, k=len(members), exclude=i)]
        typical.append(float(np.median(d)) if d else np.inf)
    k = int(np.argmin(typical))
    return index.trials[members[k]], label, typical[k]


def clip_path(folder: str | Path, trial: str) -> Path:
    """The motion file of ``trial`` in a labelled folder (its labels.csv ``file`` column)."""
    for row in read_labels(folder):
        if row.trial == trial:
            return row.file
    raise StoryBeamError(f"{folder}: no clip {trial!r} in labels.csv")
