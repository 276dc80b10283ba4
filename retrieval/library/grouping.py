"""A library that groups itself: unsupervised clusters of clips, so clips imported without
labels have a place to be browsed.

Method:

* **Descriptor** (:func:`clip_descriptor`) — one vector per clip from two blocks:
  *kinetic* — from the clip's kinetic energy per body part over time
  (:func:`retrieval.features.kinetic_energy`, five parts): per part the log of the mean
  energy, the log of its standard deviation over time (steady vs bursty), its share of the
  body's total, and the fraction of frames where it carries the most energy of all parts;
  *codes* — the clip's 2-bit frame codes as the index already holds them: for each PCA
  component the fraction of frames at each of its four levels (what postures the clip
  spends its time in).
* **Scaling** (:func:`descriptor_matrix`) — every column is standardised over the library
  (zero mean, unit variance; a constant column is left at 0) and each block divided by the
  square root of its width, so both blocks weigh the same in the distance whatever their
  sizes.
* **Clustering** (:func:`group`) — Ward's agglomerative clustering
  (:func:`scipy.cluster.hierarchy.linkage`) on the scaled descriptors, cut into ``K``
  clusters (:func:`scipy.cluster.hierarchy.fcluster`, ``maxclust``).
* **Choice of K** (the stated criterion) — when not given, the ``K`` in
  ``[min(k_min, n − 1), min(k_max, n − 1)]`` (default 4..12) with the largest mean
  silhouette (:func:`silhouette`, Rousseeuw 1987, Euclidean on the scaled descriptors);
  ties go to the smaller ``K``. Labels are never used to choose. The lower end is there
  because the silhouette alone likes to split a few outliers off a small library (the
  bundled 37 clips: K = 2, a group of 35 clips and one of 2), and fewer than four groups
  do not help a child browse.
* **Names** — a group is named by its members' most common label when any member has one
  (ties: alphabetical), else it has no name and the app shows a picture of its
  *representative*, the member with the smallest summed distance to the others (medoid).

Against labels, :func:`purity` (each cluster counted as its most common label) and
:func:`adjusted_rand_index` (Hubert & Arabie 1985) score a grouping.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial.distance import pdist, squareform
from scipy.special import comb

from retrieval.codes import unpack_codes
from retrieval.errors import DatasetError, StoryBeamError
from retrieval.features import BODY_PARTS, kinetic_energy
from retrieval.library.dataset import LabelRow, load_dataset, read_labels
from retrieval.library.index import MotionIndex
from retrieval.motion import load_motion, resample

#: Smallest and largest K the silhouette criterion tries by default.
K_MIN = 4
K_MAX = 12
_EPS = 1e-6


def clip_descriptor(energy: np.ndarray, codes: np.ndarray, dims: int) -> tuple[np.ndarray, np.ndarray]:
    """The (kinetic, codes) blocks of one clip's descriptor (module docstring):
    ``energy`` (T, parts) kinetic energy, ``codes`` (T',) the clip's codes with ``dims``
    components."""
    e = np.asarray(energy, dtype=np.float64)
    if e.ndim != 2 or e.shape[0] == 0 or e.shape[1] != len(BODY_PARTS):
        raise StoryBeamError(f"kinetic energy must be (frames, {len(BODY_PARTS)}), got {e.shape}")
    mean = e.mean(axis=0)
    share = mean / max(float(mean.sum()), _EPS)
    top = np.bincount(e.argmax(axis=1), minlength=e.shape[1]) / e.shape[0]
    kinetic = np.concatenate([np.log(mean + _EPS), np.log(e.std(axis=0) + _EPS), share, top])
    c = np.asarray(codes)
    if c.ndim != 1 or c.size == 0:
        raise StoryBeamError(f"codes must be a non-empty 1-D array, got shape {c.shape}")
    levels = unpack_codes(c, dims)  # (T', dims) in 0..3
    hist = np.stack([(levels == v).mean(axis=0) for v in range(4)], axis=1).reshape(-1)
    return kinetic, hist


def descriptor_matrix(blocks: Sequence[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """(n, D) scaled descriptors of n clips from their :func:`clip_descriptor` blocks."""
    if not blocks:
        raise StoryBeamError("no clips to group")
    parts = []
    for b in range(2):
        m = np.stack([blk[b] for blk in blocks]).astype(np.float64)
        sd = m.std(axis=0)
        z = np.divide(m - m.mean(axis=0), sd, out=np.zeros_like(m), where=sd > 1e-12)
        parts.append(z / np.sqrt(m.shape[1]))
    return np.concatenate(parts, axis=1)


def silhouette(x: np.ndarray, labels: np.ndarray) -> float:
    """Mean silhouette of a clustering (Euclidean): for each point, ``(b − a) / max(a, b)``
    with ``a`` its mean distance to the rest of its cluster and ``b`` the smallest mean
    distance to another cluster; 0 for a point alone in its cluster. Needs 2 ≤ K < n."""
    labels = np.asarray(labels)
    ids = np.unique(labels)
    n = len(labels)
    if not 2 <= len(ids) < n:
        raise StoryBeamError(f"a silhouette needs 2 <= clusters < points, got {len(ids)} clusters of {n}")
    d = squareform(pdist(np.asarray(x, dtype=np.float64)))
    member = labels[None, :] == ids[:, None]  # (K, n)
    sums = d @ member.T  # (n, K): summed distance of each point to each cluster
    sizes = member.sum(axis=1)
    own = np.searchsorted(ids, labels)
    own_size = sizes[own]
    a = np.divide(sums[np.arange(n), own], own_size - 1, out=np.zeros(n), where=own_size > 1)
    other = sums / sizes[None, :]
    other[np.arange(n), own] = np.inf
    b = other.min(axis=1)
    s = np.divide(b - a, np.maximum(a, b), out=np.zeros(n), where=np.maximum(a, b) > 0)
    s[own_size == 1] = 0.0
    return float(s.mean())


def purity(clusters: Sequence, labels: Sequence[str]) -> float:
    """Fraction of clips whose label is their cluster's most common label."""
    if len(clusters) != len(labels) or not len(labels):
        raise StoryBeamError("purity needs as many cluster ids as labels, at least one")
    per: dict = {}
    for c, lab in zip(clusters, labels):
        per.setdefault(c, Counter())[lab] += 1
    return sum(cnt.most_common(1)[0][1] for cnt in per.values()) / len(labels)


def adjusted_rand_index(clusters: Sequence, labels: Sequence[str]) -> float:
    """Adjusted Rand index of two partitions (1: identical, about 0: chance), from their
    contingency table: ``(Σ C(n_ij, 2) − E) / (½(Σ C(a_i, 2) + Σ C(b_j, 2)) − E)`` with
    ``E = Σ C(a_i, 2) · Σ C(b_j, 2) / C(n, 2)``; 1 when both partitions are trivial."""
    if len(clusters) != len(labels) or not len(labels):
        raise StoryBeamError("the adjusted Rand index needs as many cluster ids as labels, at least one")
    _, ci = np.unique(np.asarray(clusters, dtype=object).astype(str), return_inverse=True)
    _, li = np.unique(np.asarray(labels, dtype=object).astype(str), return_inverse=True)
    table = np.zeros((ci.max() + 1, li.max() + 1), dtype=np.int64)
    np.add.at(table, (ci, li), 1)
    pairs = comb(table, 2).sum()
    rows, cols = comb(table.sum(axis=1), 2).sum(), comb(table.sum(axis=0), 2).sum()
    expected = rows * cols / comb(len(ci), 2) if len(ci) > 1 else 0.0
    top = 0.5 * (rows + cols) - expected
    if top == 0:
        return 1.0
    return float((pairs - expected) / top)


@dataclass(frozen=True)
class Group:
    """One group: library ``members`` (positions), its ``name`` (most common label, or
    None: show a picture of ``representative``, the medoid's trial)."""

    number: int
    members: tuple[int, ...]
    trials: tuple[str, ...]
    name: str | None
    representative: str


@dataclass(frozen=True)
class Grouping:
    """A clustering of a library: ``clusters[i]`` is clip i's group number (0..k−1),
    ``scores`` the silhouette of each K tried (empty when K was given)."""

    k: int
    clusters: np.ndarray
    groups: tuple[Group, ...]
    scores: dict[int, float]


def group(x: np.ndarray, trials: Sequence[str], labels: Sequence[str] | None = None, k: int | None = None,
          k_max: int = K_MAX, k_min: int = K_MIN) -> Grouping:
    """Ward clusters of the scaled descriptors ``x`` (n, D), ``k`` of them or as many as
    the silhouette criterion chooses (module docstring); groups numbered by size, largest
    first (ties by their first member)."""
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    if n != len(trials) or (labels is not None and len(labels) != n):
        raise StoryBeamError("descriptors, trials and labels differ in length")
    if n < 3:
        raise StoryBeamError(f"grouping needs at least 3 clips, got {n}")
    tree = linkage(x, method="ward")
    scores: dict[int, float] = {}
    if k is None:
        if not 2 <= k_min <= k_max:
            raise StoryBeamError(f"the K range must satisfy 2 <= k_min <= k_max, got {k_min}..{k_max}")
        for kk in range(min(k_min, n - 1), min(k_max, n - 1) + 1):
            cut = fcluster(tree, kk, criterion="maxclust")
            if len(np.unique(cut)) == kk:
                scores[kk] = silhouette(x, cut)
        if not scores:
            raise StoryBeamError("no K in the range splits these clips")
        k = max(scores, key=lambda kk: (scores[kk], -kk))
    elif not 1 <= k <= n:
        raise StoryBeamError(f"K must lie in [1, {n}], got {k}")
    cut = fcluster(tree, k, criterion="maxclust")
    order = sorted(np.unique(cut), key=lambda c: (-(cut == c).sum(), int(np.argmax(cut == c))))
    clusters = np.empty(n, dtype=np.int64)
    d = squareform(pdist(x))
    groups = []
    for number, c in enumerate(order):
        members = tuple(int(i) for i in np.flatnonzero(cut == c))
        clusters[list(members)] = number
        medoid = members[int(np.argmin(d[np.ix_(members, members)].sum(axis=1)))]
        named = Counter(labels[i] for i in members if labels[i]) if labels is not None else Counter()
        name = min(named, key=lambda lab: (-named[lab], lab)) if named else None
        groups.append(Group(number, members, tuple(trials[i] for i in members), name, trials[medoid]))
    return Grouping(int(k), clusters, tuple(groups), scores)


def load_energies(folder: str | Path, fps: float = 30.0, rows: Sequence[LabelRow] | None = None,
                  progress: Callable[[int, int], None] | None = None) -> list[np.ndarray]:
    """Kinetic energy per body part of every clip of a labelled folder, resampled to
    ``fps``, in labels.csv order."""
    rows = list(rows) if rows is not None else read_labels(folder)
    out = []
    for i, r in enumerate(rows):
        try:
            motion = load_motion(r.file, r.skeleton) if r.skeleton else load_motion(r.file)
            if abs(motion.fps - fps) > 1e-9:
                motion = resample(motion, fps)
            out.append(kinetic_energy(motion))
        except StoryBeamError as exc:
            raise DatasetError(f"trial {r.trial} ({r.file}): {exc}") from exc
        if progress is not None:
            progress(i + 1, len(rows))
    return out


@dataclass(frozen=True)
class FolderGrouping:
    """:func:`group_folder`'s answer: the grouping, the folder's trials and labels (in
    labels.csv order) and the scaled descriptors it was made from (to cut again)."""

    grouping: Grouping
    trials: tuple[str, ...]
    labels: tuple[str, ...]
    descriptors: np.ndarray


def group_folder(folder: str | Path, fps: float = 30.0, dims: int = 6, k: int | None = None, k_max: int = K_MAX,
                 progress: Callable[[int, int], None] | None = None, k_min: int = K_MIN) -> FolderGrouping:
    """Group every clip of a labelled folder: its codes from a :class:`MotionIndex` built at
    ``fps`` with ``dims`` components, its kinetic energy from the motion files, then
    :func:`group`. The labels name the groups; they never choose them."""
    rows = read_labels(folder)
    clips = load_dataset(folder, fps=fps, rows=rows)
    index = MotionIndex.from_clips(clips, dims)
    energies = load_energies(folder, fps, rows, progress)
    x = descriptor_matrix([clip_descriptor(e, c, index.dims) for e, c in zip(energies, index.codes)])
    trials, labels = tuple(index.trials), tuple(index.labels)
    return FolderGrouping(group(x, trials, labels, k, k_max, k_min), trials, labels, x)
