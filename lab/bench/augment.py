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

from retrieval.errors import StoryBeamError
from retrieval.features import get_feature_set

TIME_SCALE_RANGE = (0.8, 1.25)


def _swap_side(name: str) -> str:
    """"lhand_rshoulder" -> "rhand_lshoulder": swap the l/r prefix of every word."""
    words = []
    for w in name.split("_"):
        if len(w) > 1 and w[0] in "lr" and w[1:] in ("hand", "ankle", "knee", "elbow", "hip", "shoulder", "foot", "toe"):
            w = ("r" if w[0] == "l" else "l") + w[1:]
        words.append(w)
    return "_".join(words)


def mirror_permutation(feature_set: str = "mr17") -> np.ndarray:
    """Column permutation that mirrors a feature matrix left/right."""
    names = get_feature_set(feature_set).names
    index = {n: i for i, n in enumerate(names)}
    perm = []
    for n in names:
        m = _swap_side(n)
        if m not in index:
            raise StoryBeamError(f"feature set {feature_set!r}: no mirror partner {m!r} for feature {n!r}")
        perm.append(index[m])
    return np.array(perm, dtype=np.int64)


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


def time_scale(features: np.ndarray, factor: float) -> np.ndarray:
    """Resample (T, d) features to round(T·factor) frames by linear interpolation."""
    if not factor > 0:
        raise StoryBeamError(f"time-scale factor must be positive, got {factor}")
    x = np.asarray(features, dtype=np.float64)
    n = max(2, int(round(len(x) * factor)))
    src = np.linspace(0.0, len(x) - 1, n)
    lo = np.floor(src).astype(np.int64)
    hi = np.minimum(lo + 1, len(x) - 1)
    t = (src - lo)[:, None]
    return x[lo] * (1 - t) + x[hi] * t


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
