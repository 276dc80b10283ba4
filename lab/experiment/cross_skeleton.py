"""Cross-skeleton checks: the same trials on another skeleton, matched by name.

A folder of "other-skeleton" files holds trials of the library converted to another
character (another joint set, proportions, rest pose, up axis, units): either a
``labels.csv`` (the library's columns) or motion files named by trial (``07_01.bvh``).
Each file is matched to the library's row of the same trial name; names the library
does not hold are listed, not guessed.

* :func:`skeleton_identity` — each other-skeleton trial is a clip query against the whole
  library (as loaded): is its own trial first? For storybeam's "find this clip" ranking
  (:meth:`StoryBeamSearcher.find`, ``storybeam search --find``) and its class ranking
  (:meth:`StoryBeamSearcher.search`, ``storybeam search --query``).
* :func:`pose_identity` — frames at ¼, ½ and ¾ of each trial are ``storybeam search
  --pose FILE:FRAME`` queries (:class:`~retrieval.library.PoseSearch`, the same
  :meth:`~retrieval.library.PoseSearch.motion_pose` row as the command): the top clip's
  class and trial. With other-skeleton files the trial itself is in the library (the
  question: does the pose find its own frame's clip across skeletons?); without, the
  poses come from the library's own files and their trial is left out (the question:
  does a single posture find its class?).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.features import get_feature_set
from retrieval.library import (
    POSE_FEATURE_SET,
    Clip,
    LabelRow,
    PoseSearch,
    StoryBeamSearcher,
    clip_from_motion,
    read_labels,
)
from retrieval.motion import Motion, load_motion

#: Where in each trial :func:`pose_identity` takes its poses (fractions of the frames).
POSE_FRACTIONS = (0.25, 0.5, 0.75)

Progress = Callable[[int, int], None] | None


@dataclass(frozen=True)
class OtherTrial:
    """One trial of the other skeleton: its name, file (and ASF skeleton for AMC)."""

    trial: str
    file: Path
    skeleton: Path | None = None

    def load(self) -> Motion:
        return load_motion(self.file, self.skeleton) if self.skeleton else load_motion(self.file)


def other_skeleton_trials(folder: str | Path) -> list[OtherTrial]:
    """The trials of an other-skeleton folder: its ``labels.csv`` rows when it has one,
    else every motion file directly in it, named by its stem; sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise StoryBeamError(f"--skeleton-from {folder}: not a folder")
    if (folder / "labels.csv").is_file():
        return sorted((OtherTrial(r.trial, r.file, r.skeleton) for r in read_labels(folder)), key=lambda t: t.trial)
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() == ".bvh")
    if not files:
        raise StoryBeamError(f"--skeleton-from {folder}: no labels.csv and no .bvh files in it (an AMC file "
                             "needs its ASF: list it in a labels.csv)")
    return [OtherTrial(p.stem, p) for p in files]


def match_by_name(rows: Sequence[LabelRow], others: Sequence[OtherTrial]) -> tuple[list[tuple[int, OtherTrial]], list[str]]:
    """(library position, other trial) for every other trial the library holds by name,
    and the names it does not hold."""
    where = {r.trial: i for i, r in enumerate(rows)}
    pairs = [(where[o.trial], o) for o in others if o.trial in where]
    if not pairs:
        raise StoryBeamError(f"--skeleton-from: none of its {len(others)} trial names "
                             f"({', '.join(o.trial for o in others[:5])}{', ...' if len(others) > 5 else ''}) "
                             "is a trial of --data")
    return pairs, [o.trial for o in others if o.trial not in where]


def skeleton_identity(rows: Sequence[LabelRow], clips: Sequence[Clip], others: Sequence[OtherTrial], fps: float,
                      feature_set: str, dims: int, shortlist: int, progress: Progress = None) -> dict:
    """Each other-skeleton trial as a query against the whole library (see the module
    docstring): same trial first by find and by the class ranking, the misses (what was
    found instead) and the names not in the library."""
    pairs, unmatched = match_by_name(rows, others)
    sb = StoryBeamSearcher.fit([c.features for c in clips], dims, shortlist,
                               code_columns=get_feature_set(feature_set).code_columns)
    found = top = 0
    misses = []
    for n, (i, other) in enumerate(pairs):
        q = clip_from_motion(other.load(), other.trial, clips[i].label, fps, feature_set).features
        f = sb.find(q, k=1)[0].index
        s = sb.search(q, k=1)[0].index
        found += f == i
        top += s == i
        if f != i or s != i:
            misses.append({"trial": other.trial, "label": clips[i].label, "find": clips[f].trial,
                           "search": clips[s].trial})
        if progress is not None:
            progress(n + 1, len(pairs))
    return {"trials": len(pairs), "find_top1": found / len(pairs), "search_top1": top / len(pairs),
            "misses": misses, "not_in_library": unmatched}


def _pose_rows(search: PoseSearch, motion: Motion) -> list[tuple[int, np.ndarray]]:
    """(file frame, features) at :data:`POSE_FRACTIONS` of ``motion``."""
    out = []
    for frac in POSE_FRACTIONS:
        frame = int(round(frac * (motion.n_frames - 1)))
        out.append((frame, search.motion_pose(motion, frame)))
    return out


def pose_identity(rows: Sequence[LabelRow], pose_clips: Sequence[Clip], others: Sequence[OtherTrial] | None,
                  dims: int, feature_set: str = POSE_FEATURE_SET, progress: Progress = None) -> dict:
    """Poses at ¼, ½, ¾ of each trial as pose-search queries (see the module docstring):
    the share whose top clip has the trial's class and (with ``others``) is the trial
    itself; every miss with its file frame and what was found. ``pose_clips`` are the
    library's clips in ``feature_set`` (the pose search's)."""
    search = PoseSearch.from_clips(pose_clips, dims, feature_set=feature_set)
    if others is None:
        pairs = [(i, OtherTrial(r.trial, r.file, r.skeleton)) for i, r in enumerate(rows)]
        unmatched: list[str] = []
    else:
        pairs, unmatched = match_by_name(rows, others)
    same_class = same_trial = total = 0
    misses = []
    per_class: dict[str, list[int]] = {}
    for n, (i, other) in enumerate(pairs):
        label = pose_clips[i].label
        motion = other.load()
        for frame, q in _pose_rows(search, motion):
            hit = search.search(q, k=1, exclude=other.trial if others is None else None)[0]
            total += 1
            ok_class = hit.label == label
            same_class += ok_class
            same_trial += hit.trial == other.trial
            per_class.setdefault(label, []).append(int(ok_class))
            if not ok_class or (others is not None and hit.trial != other.trial):
                misses.append({"trial": other.trial, "label": label, "frame": frame, "found": hit.trial,
                               "found_label": hit.label, "found_frame": hit.frame})
        if progress is not None:
            progress(n + 1, len(pairs))
    out = {"poses": total, "trials": len(pairs), "fractions": list(POSE_FRACTIONS),
           "same_class": same_class / total,
           "per_class": {c: float(np.mean(v)) for c, v in sorted(per_class.items())},
           "trial_left_out": others is None, "misses": misses, "not_in_library": unmatched}
    if others is not None:
        out["same_trial"] = same_trial / total
    return out
