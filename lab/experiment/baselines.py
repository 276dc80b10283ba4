"""The research's two baselines, as matchers (see :mod:`lab.experiment.matchers`).

* :class:`ExactDTWMatcher` — plain DTW on the real-valued 17-D features with Euclidean
  frame distance (the accuracy ceiling the quantised method is judged against).
* :class:`ForbesFiumeMatcher` — after Forbes & Fiume (SCA 2005) as the research used it:
  frames live in a *weighted-PCA pose space* of joint positions; the reference frames are
  clustered (k-means), a query frame is quantised to its nearest cluster with a k-d tree,
  and DTW runs over cluster ids with a precomputed cluster-to-cluster distance matrix —
  the same table-look-up kernel as the proposed method, with a different quantiser.

The pose vectors come from :func:`retrieval.features.pose_frames`.
"""
from __future__ import annotations

import warnings
from typing import Sequence

import numpy as np
from scipy.cluster.vq import kmeans2
from scipy.spatial import cKDTree

from retrieval.dtw import dtw_codes, dtw_features
from lab.experiment.matchers import MatcherError, stack_frames
from retrieval.library import Clip


def kmeans_pp_seeds(x: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding (D² sampling), vectorised over points: scipy's own ``minit="++"``
    takes about a minute for k = 1024 on 20 000 frames, this takes well under a second."""
    seeds = np.empty((k, x.shape[1]))
    seeds[0] = x[rng.integers(len(x))]
    d2 = ((x - seeds[0]) ** 2).sum(axis=1)
    for i in range(1, k):
        total = d2.sum()
        j = rng.choice(len(x), p=d2 / total) if total > 0 else rng.integers(len(x))
        seeds[i] = x[j]
        d2 = np.minimum(d2, ((x - seeds[i]) ** 2).sum(axis=1))
    return seeds


class ExactDTWMatcher:
    """Plain DTW on the 17-D features (Euclidean frame cost). Nothing to build."""

    name = "dtw"

    def __init__(self, band: int | None = None, backend: str = "auto"):
        self.band = band
        self.backend = backend
        self.references: list[np.ndarray] = []

    def fit(self, references: Sequence[Clip]) -> "ExactDTWMatcher":
        self.references = [np.ascontiguousarray(c.features, dtype=np.float64) for c in references]
        return self

    def distances(self, query: Clip) -> np.ndarray:
        q = np.ascontiguousarray(query.features, dtype=np.float64)
        return np.array([dtw_features(q, r, self.band, self.backend) for r in self.references])


class ForbesFiumeMatcher:
    """Weighted-PCA pose space + k-means clusters + k-d tree + cluster-distance DTW.

    ``clusters`` is k (the research compared it at a size like the proposed method's 4ⁿ
    table); ``variance`` is the share of pose variance the PCA keeps.
    """

    name = "forbes"

    def __init__(self, clusters: int = 1024, variance: float = 0.95, band: int | None = None,
                 backend: str = "auto", seed: int = 0, iterations: int = 20):
        self.clusters = clusters
        self.variance = variance
        self.band = band
        self.backend = backend
        self.seed = seed
        self.iterations = iterations
        self.mean = self.axes = self.centroids = self.table = None
        self.tree: cKDTree | None = None
        self.reference_codes: list[np.ndarray] = []

    def _project(self, pose: np.ndarray) -> np.ndarray:
        return (pose - self.mean) @ self.axes.T

    def fit(self, references: Sequence[Clip]) -> "ForbesFiumeMatcher":
        if any(c.pose is None for c in references):
            raise MatcherError("Forbes–Fiume needs pose vectors; build clips with poses")
        x = stack_frames([c.pose for c in references])
        self.mean = x.mean(axis=0)
        _, s, vt = np.linalg.svd(x - self.mean, full_matrices=False)
        ratios = s**2 / np.sum(s**2)
        keep = int(np.searchsorted(np.cumsum(ratios), self.variance) + 1)
        self.axes = vt[:keep]
        y = self._project(x)
        k = int(min(self.clusters, len(np.unique(y, axis=0))))
        start = kmeans_pp_seeds(y, k, np.random.default_rng(self.seed))
        with warnings.catch_warnings():  # an emptied cluster keeps its seed: harmless here
            warnings.simplefilter("ignore", UserWarning)
            centroids, _ = kmeans2(y, start, iter=self.iterations, minit="matrix")
        self.centroids = centroids
        self.tree = cKDTree(centroids)
        diff = centroids[:, None, :] - centroids[None, :, :]
        self.table = np.sqrt((diff**2).sum(axis=2)).astype(np.float32)
        self.reference_codes = [self.encode(c.pose) for c in references]
        return self

    def encode(self, pose: np.ndarray) -> np.ndarray:
        if self.tree is None:
            raise MatcherError("Forbes–Fiume matcher used before fit()")
        _, ids = self.tree.query(self._project(pose))
        return ids.astype(np.int32)

    def distances(self, query: Clip) -> np.ndarray:
        codes = self.encode(query.pose)
        return np.array([dtw_codes(codes, r, self.table, self.band, self.backend) for r in self.reference_codes])
