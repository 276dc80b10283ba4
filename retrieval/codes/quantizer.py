"""PCA and 2-bit quantisation of feature frames into integer codes, and the code-distance
table — exactly as the research describes (see docs/seed-method.md, steps 2–5).

* PCA over all frames of the reference clips; keep the top ``n`` components; ``c_i`` is
  component i's contribution ratio (its eigenvalue over the sum of all eigenvalues).
* With ``a_ji`` frame j's coefficient on component i and ``μ_i``, ``σ_i`` that
  coefficient's mean and standard deviation over the reference frames:
  ``g_ji = 0`` if ``a < μ−σ``; 1 if ``μ−σ ≤ a < μ``; 2 if ``μ ≤ a < μ+σ``; 3 if ``a ≥ μ+σ``.
* ``m_j = Σ_i g_ji · 4^(i−1)`` (component 1 in the lowest two bits).
* ``D[m, k] = Σ_i w(|g_i(m) − g_i(k)|) · c_i`` with ``w = (0, 1, 4, 16)``: a 4ⁿ×4ⁿ float32
  table, symmetric with a zero diagonal.

Memory: the full table has 16ⁿ float32 entries — 64 MiB at n = 6 but 1 GiB at n = 7. Because
D is a sum over components, it splits exactly into a table over the low components plus
one over the high ones; :func:`code_table` returns such a :class:`SplitTable` above
``max_full_dims`` (the research also split its n = 7 table). The DTW kernels accept both.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from retrieval.codes.tables import MAX_DIMS, MAX_FULL_DIMS, SplitTable, code_table
from retrieval.errors import QuantizerError


@dataclass
class PCA:
    """Principal axes of a set of frames. ``components`` (d, d) rows are axes, sorted by
    decreasing ``variances``; ``ratios`` are the contribution ratios (sum to 1)."""

    mean: np.ndarray
    components: np.ndarray
    variances: np.ndarray

    @classmethod
    def fit(cls, frames: np.ndarray) -> "PCA":
        x = np.asarray(frames, dtype=np.float64)
        if x.ndim != 2 or x.shape[0] < 2:
            raise QuantizerError(f"PCA needs a (frames, dims) array with at least 2 frames, got {x.shape}")
        mean = x.mean(axis=0)
        cov = np.cov(x - mean, rowvar=False).reshape(x.shape[1], x.shape[1])
        vals, vecs = np.linalg.eigh(cov)
        order = np.argsort(vals)[::-1]
        vals = np.clip(vals[order], 0.0, None)
        vecs = vecs[:, order].T
        # Fix each axis's sign (largest-magnitude entry positive) so refits are reproducible.
        flip = np.sign(vecs[np.arange(len(vecs)), np.abs(vecs).argmax(axis=1)])
        vecs *= np.where(flip == 0, 1.0, flip)[:, None]
        return cls(mean, vecs, vals)

    @property
    def ratios(self) -> np.ndarray:
        total = self.variances.sum()
        return self.variances / total if total > 0 else np.zeros_like(self.variances)

    def project(self, frames: np.ndarray, n: int) -> np.ndarray:
        """(T, d) frames -> (T, n) coefficients on the top ``n`` axes."""
        x = np.asarray(frames, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != self.mean.shape[0]:
            raise QuantizerError(f"expected frames of width {self.mean.shape[0]}, got shape {x.shape}")
        return (x - self.mean) @ self.components[:n].T


def levels(coeffs: np.ndarray, mu: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """2-bit levels g (T, n) in {0,1,2,3} with the thresholds μ−σ, μ, μ+σ (lower bound
    inclusive, as in the research)."""
    a = np.asarray(coeffs, dtype=np.float64)
    g = (a >= mu - sigma).astype(np.int64) + (a >= mu) + (a >= mu + sigma)
    return g


def pack_codes(g: np.ndarray) -> np.ndarray:
    """Levels (T, n) -> codes m_j = Σ_i g_ji 4^(i−1) as int32."""
    g = np.asarray(g, dtype=np.int64)
    weights = 4 ** np.arange(g.shape[1], dtype=np.int64)
    return (g @ weights).astype(np.int32)


def unpack_codes(codes: np.ndarray, n: int) -> np.ndarray:
    """Codes -> levels (..., n): the inverse of :func:`pack_codes`."""
    c = np.asarray(codes, dtype=np.int64)[..., None]
    return (c >> (2 * np.arange(n))) & 3


@dataclass
class Quantizer:
    """A fitted PCA + 2-bit quantiser with ``n`` kept components. ``columns``: when set,
    the codes see only the frames' first ``columns`` features (the PCA is fitted on those;
    its axes carry zero weight on the rest, so a full-width frame projects as its first
    columns alone), None for all of them."""

    pca: PCA
    n: int
    mu: np.ndarray
    sigma: np.ndarray
    columns: int | None = None

    @classmethod
    def fit(cls, reference_frames: np.ndarray, n: int, columns: int | None = None) -> "Quantizer":
        """Fit on the reference frames only (queries must not leak into μ, σ or the axes);
        ``columns``: code only the first that many features (see the class)."""
        x = np.asarray(reference_frames, dtype=np.float64)
        if x.ndim != 2:
            raise QuantizerError(f"reference frames must be (frames, dims), got {x.shape}")
        if columns is not None and not 1 <= columns <= x.shape[1]:
            raise QuantizerError(f"columns must be 1..{x.shape[1]} for {x.shape[1]}-D features, got {columns}")
        width = x.shape[1] if columns is None else columns
        if not 1 <= n <= min(width, MAX_DIMS):
            raise QuantizerError(f"n must be 1..{min(width, MAX_DIMS)} for {width}-D features, got {n}")
        pca = PCA.fit(x[:, :width])
        if width < x.shape[1]:
            # the same axes over the full width, with zero weight on the uncoded columns (whose
            # mean then never matters)
            extra = x.shape[1] - width
            pca = PCA(np.pad(pca.mean, (0, extra)), np.pad(pca.components, ((0, 0), (0, extra))), pca.variances)
        a = pca.project(x, n)
        return cls(pca, n, a.mean(axis=0), a.std(axis=0), columns)

    @property
    def ratios(self) -> np.ndarray:
        """Contribution ratios c_1..c_n of the kept components."""
        return self.pca.ratios[: self.n]

    @property
    def cumulative_ratio(self) -> float:
        return float(self.ratios.sum())

    def levels(self, frames: np.ndarray) -> np.ndarray:
        return levels(self.pca.project(frames, self.n), self.mu, self.sigma)

    def encode(self, frames: np.ndarray) -> np.ndarray:
        """(T, d) features -> (T,) int32 codes in [0, 4ⁿ)."""
        return pack_codes(self.levels(frames))

    def table(self, max_full_dims: int = MAX_FULL_DIMS) -> np.ndarray | SplitTable:
        return code_table(self.ratios, max_full_dims)

    def to_arrays(self, prefix: str = "q_") -> dict[str, np.ndarray]:
        """Arrays for saving in an .npz (see :meth:`from_arrays`)."""
        return {
            f"{prefix}mean": self.pca.mean,
            f"{prefix}components": self.pca.components,
            f"{prefix}variances": self.pca.variances,
            f"{prefix}mu": self.mu,
            f"{prefix}sigma": self.sigma,
            f"{prefix}n": np.array(self.n),
        } | ({} if self.columns is None else {f"{prefix}columns": np.array(self.columns)})

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "q_") -> "Quantizer":
        pca = PCA(arrays[f"{prefix}mean"], arrays[f"{prefix}components"], arrays[f"{prefix}variances"])
        columns = int(arrays[f"{prefix}columns"]) if f"{prefix}columns" in arrays else None
        return cls(pca, int(arrays[f"{prefix}n"]), arrays[f"{prefix}mu"], arrays[f"{prefix}sigma"], columns)
