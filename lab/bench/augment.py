"""Honest augmentation of labelled clips in *feature space*, for scale tests.

The shared CMU set has 205 clips (987 s); CMU's whole database is about 2 600 clips /
9 hours. To test search speed at that size without new recordings we derive clips from the
shared ones — and say so wherever the numbers are reported. Three transformations, each
keeping the class label meaningful:

* **mirroring** — left and right swapped: the MR17 features come in left/right pairs
  (``lhand_head`` ↔ ``rhand_head`` …), so a mirrored performance is the same frames with
  those columns exchanged (symmetric features such as ``hand_hand`` stay put);
* **time scaling** by a factor in [0.8, 1.25] — linear interpolation of every feature
  (a faster or slower performance of the same motion);
* **subject mixing** — a *take* spliced from 1–4 clips of the same class (possibly from
  different subjects), each cut at random points, as a longer unsegmented recording.

Working on features (not on motions) keeps a 9-hour build to seconds on 2 cores: no forward
kinematics is repeated.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from retrieval.features import get_feature_set
from retrieval.library import mirror_permutation, time_scale  # the act index's augmentation uses them too

TIME_SCALE_RANGE = (0.8, 1.25)
__all__ = ["TIME_SCALE_RANGE", "MIRROR_NEGATED", "augmented_take", "mirror", "mirror_permutation", "splice", "time_scale"]


#: Features whose sign flips in a mirror image (a left turn becomes a right turn).
MIRROR_NEGATED = ("heading_rate",)


def mirror(features: np.ndarray, feature_set: str = "mr17") -> np.ndarray:
    """The features of the left/right mirror image: sided columns swapped
    (:func:`mirror_permutation`), signed ones (:data:`MIRROR_NEGATED`) negated."""
    out = np.asarray(features)[:, mirror_permutation(feature_set)]
    signed = [i for i, n in enumerate(get_feature_set(feature_set).names) if n in MIRROR_NEGATED]
    if signed:
        out[:, signed] = -out[:, signed]
    return out


def splice(parts: Sequence[np.ndarray], rng: np.random.Generator, min_keep: float = 0.5) -> np.ndarray:
    """One take from several clips of the same class: each part keeps a random contiguous
    stretch of at least ``min_keep`` of its frames."""
    out = []
    for p in parts:
        n = len(p)
        keep = int(rng.integers(max(2, int(n * min_keep)), n + 1))
        start = int(rng.integers(0, n - keep + 1))
        out.append(np.asarray(p)[start:start + keep])
    return np.concatenate(out, axis=0)


def augmented_take(by_class: dict[str, list[np.ndarray]], label: str, rng: np.random.Generator,
                   max_parts: int = 4, feature_set: str = "mr17") -> np.ndarray:
    """A derived take of ``label``: splice 1..max_parts same-class clips, time-scale it,
    mirror it with probability 1/2."""
    pool = by_class[label]
    parts = [pool[int(i)] for i in rng.integers(0, len(pool), int(rng.integers(1, max_parts + 1)))]
    x = splice(parts, rng)
    x = time_scale(x, float(rng.uniform(*TIME_SCALE_RANGE)))
    if rng.random() < 0.5:
        x = mirror(x, feature_set)
    return x
