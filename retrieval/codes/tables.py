"""Compact, exact replacements for the seed's 4ⁿ×4ⁿ code-distance table.

The seed's table (:func:`full_table`) holds
``D[u, v] = float32(Σ_i c_i · w(|g_i(u) − g_i(v)|))`` for every pair of codes: 64 MiB at
n = 6. But ``D[u, v]`` depends on ``u`` and ``v`` only through the vector of per-component
level differences ``d_i = |g_i(u) − g_i(v)|`` ∈ {0..3}ⁿ — 4ⁿ possible vectors, not 16ⁿ
pairs. Two layouts use that:

* **difference table** (:class:`DiffTable`, the default of the fast search): ``F[d]`` for
  every packed difference vector ``d`` (4ⁿ float32 — 16 KiB at n = 6), plus a small
  ``absdiff`` table that packs the level differences of two half-codes (4ᵏ×4ᵏ uint8 with
  k = ⌈n/2⌉ — 4 KiB at n = 6). ``D[u, v] = F[absdiff[u_lo, v_lo] | absdiff[u_hi, v_hi] << 2k]``.
  ``F`` is *literally* row 0 of the seed's table (``|0 − g| = g``) computed with the same
  float64 operations in the same order, so every value is bit-identical: 20 KiB in all.
* **component table** (:class:`ComponentTable`): the n×4×4 per-component weights
  ``c_i · w(|a − b|)`` in float64 (768 bytes at n = 6); a look-up sums them in the seed's
  order and rounds to float32, again bit-identical, at n look-ups per cell. Kept as an
  ablation and for hardware with tiny caches.

The seed's full table stays available (``layout="full"``) as the reference mode.

One interface for all of them: :func:`make_table` builds any layout from the contribution
ratios, :func:`table_lookup` reads ``D[a, b]`` from any of them (the full array, a
:class:`SplitTable`, a :class:`DiffTable` or a :class:`ComponentTable`), and
:func:`table_bytes` says what a layout costs before it is built. Every layout gives the
same float values for the same ratios.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from retrieval.errors import QuantizerError

#: Weight of a level difference of 0, 1, 2, 3 (times c_i).
LEVEL_WEIGHTS = np.array([0.0, 1.0, 4.0, 16.0])

#: Largest n for which one full 4ⁿ×4ⁿ table is built (4⁶² float32 = 64 MiB).
MAX_FULL_DIMS = 6

#: Largest n supported at all (codes must fit int32 and split tables stay small).
MAX_DIMS = 12


LAYOUTS = ("diff", "component", "full")


def full_table(ratios: np.ndarray) -> np.ndarray:
    """The 4ⁿ×4ⁿ float32 table D for contribution ratios ``c`` (length n)."""
    c = np.asarray(ratios, dtype=np.float64)
    level_diff = np.abs(np.arange(4)[:, None] - np.arange(4)[None, :])
    w = LEVEL_WEIGHTS[level_diff]  # (4, 4) weights of one component
    # Component i occupies bits 2(i-1)..2i-1, so adding a component as the new highest
    # digit is a Kronecker sum: D_i[(h, l), (h', l')] = c_i w[h, h'] + D_{i-1}[l, l'].
    table = np.zeros((1, 1))
    for ci in c:
        m = table.shape[0]
        table = ((ci * w)[:, None, :, None] + table[None, :, None, :]).reshape(4 * m, 4 * m)
    return table.astype(np.float32)


@dataclass
class SplitTable:
    """D as two exact parts: ``low`` over components 1..k and ``high`` over k+1..n, so
    ``D[m, q] = low[m & mask, q & mask] + high[m >> 2k, q >> 2k]``."""

    low: np.ndarray
    high: np.ndarray
    low_dims: int

    @property
    def nbytes(self) -> int:
        return self.low.nbytes + self.high.nbytes

    def lookup(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """D[a, b] elementwise (broadcasting), in float64 summed low + high."""
        mask = (1 << (2 * self.low_dims)) - 1
        shift = 2 * self.low_dims
        a = np.asarray(a, dtype=np.int64)
        b = np.asarray(b, dtype=np.int64)
        return self.low[a & mask, b & mask].astype(np.float64) + self.high[a >> shift, b >> shift]


def code_table(ratios: np.ndarray, max_full_dims: int = MAX_FULL_DIMS) -> np.ndarray | SplitTable:
    """A full table for n ≤ ``max_full_dims``, otherwise an exact :class:`SplitTable`."""
    c = np.asarray(ratios, dtype=np.float64)
    n = len(c)
    if not 1 <= n <= MAX_DIMS:
        raise QuantizerError(f"number of dimensions must be 1..{MAX_DIMS}, got {n}")
    if n <= max_full_dims:
        return full_table(c)
    k = (n + 1) // 2
    return SplitTable(full_table(c[:k]), full_table(c[k:]), k)


def table_lookup(table: "np.ndarray | SplitTable | DiffTable | ComponentTable", a: np.ndarray,
                 b: np.ndarray) -> np.ndarray:
    """``D[a, b]`` elementwise (broadcasting) as float64, for every form of the table: the
    seed's full array, or a :class:`SplitTable`, :class:`DiffTable` or
    :class:`ComponentTable` (which answer through their own ``lookup``). All forms give
    the same values for the same ratios."""
    if isinstance(table, np.ndarray):
        return table[np.asarray(a), np.asarray(b)].astype(np.float64)
    return table.lookup(a, b)


def difference_table(ratios: np.ndarray) -> np.ndarray:
    """``F[d]`` = the seed's distance for the packed level-difference vector ``d`` (float32,
    length 4ⁿ). Same Kronecker fold as :func:`~retrieval.codes.quantizer.full_table`, restricted to
    its first row, so ``F == full_table(ratios)[0]`` bit for bit."""
    c = np.asarray(ratios, dtype=np.float64)
    if not 1 <= len(c) <= MAX_DIMS:
        raise QuantizerError(f"number of dimensions must be 1..{MAX_DIMS}, got {len(c)}")
    row = np.zeros(1)
    for ci in c:  # new highest digit h: entry (h, l) = c_i·w[0, h] + row[l], as full_table does
        row = ((ci * LEVEL_WEIGHTS)[:, None] + row[None, :]).reshape(-1)
    return row.astype(np.float32)


def absdiff_table(k: int) -> np.ndarray:
    """(4ᵏ, 4ᵏ) table of packed per-component level differences of two k-component codes."""
    size = 4**k
    codes = np.arange(size, dtype=np.int64)
    g = (codes[:, None] >> (2 * np.arange(k))) & 3  # (size, k) levels
    diff = np.abs(g[:, None, :] - g[None, :, :])  # (size, size, k)
    packed = (diff << (2 * np.arange(k))).sum(axis=2)
    return packed.astype(np.uint8 if k <= 4 else np.uint16)


@dataclass
class DiffTable:
    """The exact 20 KiB (n = 6) replacement of the seed's table; see the module docstring."""

    F: np.ndarray  # (4ⁿ,) float32
    absdiff: np.ndarray  # (4ᵏ, 4ᵏ) uint8/uint16
    low_dims: int  # k: components in the low half (the high half has n − k ≤ k)
    n: int

    @classmethod
    def from_ratios(cls, ratios: np.ndarray) -> "DiffTable":
        n = len(ratios)
        k = (n + 1) // 2
        return cls(difference_table(ratios), absdiff_table(k), k, n)

    @property
    def nbytes(self) -> int:
        return int(self.F.nbytes + self.absdiff.nbytes)

    @property
    def size(self) -> int:
        return 4**self.n

    def lookup(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``D[a, b]`` elementwise (broadcasting) as float64 — same values as the full table."""
        a = np.asarray(a, dtype=np.int64)
        b = np.asarray(b, dtype=np.int64)
        shift = 2 * self.low_dims
        mask = (1 << shift) - 1
        d = self.absdiff[a & mask, b & mask].astype(np.int64) | (self.absdiff[a >> shift, b >> shift].astype(np.int64) << shift)
        return self.F[d].astype(np.float64)


def component_table(ratios: np.ndarray) -> np.ndarray:
    """(n, 4, 4) float64 per-component weights ``c_i · w(|a − b|)``."""
    c = np.asarray(ratios, dtype=np.float64)
    level_diff = np.abs(np.arange(4)[:, None] - np.arange(4)[None, :])
    return c[:, None, None] * LEVEL_WEIGHTS[level_diff][None, :, :]


def component_lookup(comp: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``D[a, b]`` from a :func:`component_table`: the float64 sum in the seed's order
    (component 1 first), rounded to float32 — bit-identical to the full table."""
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    total = np.zeros(np.broadcast(a, b).shape)
    for i in range(comp.shape[0]):
        total = total + comp[i][(a >> (2 * i)) & 3, (b >> (2 * i)) & 3]
    return total.astype(np.float32).astype(np.float64)


@dataclass
class ComponentTable:
    """The n×4×4 per-component weights (see the module docstring), behind the same
    ``lookup``/``nbytes`` interface as :class:`DiffTable`."""

    weights: np.ndarray  # (n, 4, 4) float64

    @classmethod
    def from_ratios(cls, ratios: np.ndarray) -> "ComponentTable":
        return cls(component_table(ratios))

    @property
    def n(self) -> int:
        return int(self.weights.shape[0])

    @property
    def nbytes(self) -> int:
        return int(self.weights.nbytes)

    def lookup(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``D[a, b]`` elementwise as float64, bit-identical to the full table."""
        return component_lookup(self.weights, a, b)


def make_table(ratios: np.ndarray, layout: str = "diff") -> "np.ndarray | DiffTable | ComponentTable":
    """The code-distance table for contribution ratios ``ratios`` in one of
    :data:`LAYOUTS`: ``"diff"`` (the search's default, 20 KiB at n = 6), ``"component"``
    (768 B, n look-ups per cell) or ``"full"`` (the seed's 4ⁿ×4ⁿ float32 array, n ≤
    :data:`MAX_FULL_DIMS`). Read any of them with :func:`table_lookup`."""
    n = len(np.asarray(ratios))
    if not 1 <= n <= MAX_DIMS:
        raise QuantizerError(f"number of dimensions must be 1..{MAX_DIMS}, got {n}")
    if layout == "diff":
        return DiffTable.from_ratios(ratios)
    if layout == "component":
        return ComponentTable.from_ratios(ratios)
    if layout == "full":
        if n > MAX_FULL_DIMS:
            raise QuantizerError(f"the full table at n = {n} would take {table_bytes('full', n)} bytes; "
                                 f"use layout 'diff' (or n ≤ {MAX_FULL_DIMS})")
        return full_table(ratios)
    raise QuantizerError(f"unknown table layout {layout!r} (choose from {', '.join(LAYOUTS)})")


def table_bytes(layout: str, n: int) -> int:
    """Bytes of the distance structure of a layout at n components (no allocation)."""
    if layout == "full":
        return 4 * 16**n
    if layout == "component":
        return 8 * 16 * n
    if layout == "diff":
        k = (n + 1) // 2
        return 4 * 4**n + (1 if k <= 4 else 2) * 16**k
    raise QuantizerError(f"unknown table layout {layout!r} (choose from {', '.join(LAYOUTS)})")


def reference_table(ratios: np.ndarray) -> np.ndarray:
    """The seed's full table (reference mode), re-exported for symmetry."""
    return full_table(ratios)
