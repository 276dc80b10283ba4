"""PCA, 2-bit levels, integer codes and the code-distance table (seed steps 2–5)."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.codes import (
    LAYOUTS, PCA, Quantizer, QuantizerError, SplitTable, code_table, full_table, levels, make_table, pack_codes,
    table_bytes, table_lookup, unpack_codes,
)


def test_levels_use_mu_sigma_thresholds_with_inclusive_lower_bounds():
    mu, sigma = np.array([1.0]), np.array([2.0])  # thresholds -1, 1, 3
    a = np.array([[-1.5], [-1.0], [0.0], [1.0], [2.9], [3.0], [10.0]])
    assert levels(a, mu, sigma)[:, 0].tolist() == [0, 1, 1, 2, 2, 3, 3]


def test_codes_put_component_one_in_the_lowest_bits():
    g = np.array([[3, 0, 0], [0, 1, 0], [1, 2, 3], [3, 3, 3]])
    assert pack_codes(g).tolist() == [3, 4, 1 + 2 * 4 + 3 * 16, 63]
    assert np.array_equal(unpack_codes(pack_codes(g), 3), g)


def test_table_values_symmetry_and_zero_diagonal():
    c = np.array([0.5, 0.3])
    t = full_table(c)
    assert t.shape == (16, 16) and t.dtype == np.float32
    assert np.array_equal(t, t.T)
    assert np.all(np.diag(t) == 0)
    # code 0 = levels (0,0); code 3 + 1*4 = levels (3,1): w(3)*c1 + w(1)*c2 = 16*.5 + .3
    assert t[0, 3 + 4] == pytest.approx(16 * 0.5 + 0.3)
    # levels (1,2) vs (3,0): w(2)*c1 + w(2)*c2
    assert t[1 + 2 * 4, 3] == pytest.approx(4 * 0.5 + 4 * 0.3)


def test_split_table_equals_full_table():
    c = np.array([0.3, 0.2, 0.15, 0.1, 0.08])
    full = full_table(c)
    split = code_table(c, max_full_dims=3)
    assert isinstance(split, SplitTable)
    a, b = np.meshgrid(np.arange(4**5), np.arange(4**5), indexing="ij")
    assert np.allclose(table_lookup(split, a, b), full, atol=1e-6)


def test_pca_finds_the_dominant_axis_and_ratios():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(4000, 3)) * np.array([5.0, 1.0, 0.2])
    pca = PCA.fit(x)
    assert abs(pca.components[0, 0]) > 0.99
    assert pca.ratios.sum() == pytest.approx(1.0)
    assert pca.ratios[0] == pytest.approx(25 / 26.04, abs=0.02)


def test_quantizer_codes_cover_the_four_levels_evenly_enough():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(20000, 17))
    q = Quantizer.fit(x, 2)
    g = q.levels(x)
    # Gaussian coefficients: P(<μ−σ) ≈ 0.159, P(μ−σ..μ) ≈ 0.341
    frac = np.bincount(g[:, 0], minlength=4) / len(g)
    assert np.allclose(frac, [0.159, 0.341, 0.341, 0.159], atol=0.02)
    codes = q.encode(x)
    assert codes.min() >= 0 and codes.max() < 16
    # encode is levels + pack_codes, written with fewer numpy calls: the same codes
    assert codes.dtype == np.int32 and np.array_equal(codes, pack_codes(g))
    q6 = Quantizer.fit(x, 6)
    on_thresholds = q6.pca.mean + (q6.mu + q6.sigma) @ q6.pca.components[:6]  # coefficients at μ+σ exactly (to rounding)
    for frames in (x[:500], on_thresholds[None, :]):
        assert np.array_equal(q6.encode(frames), pack_codes(q6.levels(frames)))
    assert q.cumulative_ratio == pytest.approx(q.pca.ratios[:2].sum())


def test_quantizer_round_trips_through_arrays_and_rejects_bad_input():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(500, 5))
    q = Quantizer.fit(x, 3)
    q2 = Quantizer.from_arrays(q.to_arrays())
    assert np.array_equal(q.encode(x), q2.encode(x))
    with pytest.raises(QuantizerError):
        Quantizer.fit(x, 6)
    with pytest.raises(QuantizerError):
        q.encode(np.zeros((4, 7)))


@pytest.mark.parametrize("layout", ["diff", "component", "full"])
def test_every_table_layout_answers_the_seed_values_through_one_interface(layout):
    assert layout in LAYOUTS
    rng = np.random.default_rng(3)
    c = np.sort(rng.dirichlet(np.ones(5)))[::-1]
    table = make_table(c, layout)
    a = rng.integers(0, 4**5, size=(300,))
    b = rng.integers(0, 4**5, size=(300,))
    want = full_table(c)[a, b].astype(np.float64)
    got = table_lookup(table, a, b)
    assert got.dtype == np.float64
    assert np.array_equal(got, want)  # bit for bit
    assert np.array_equal(table_lookup(table, a[:, None], b[None, :20]), full_table(c)[a[:, None], b[None, :20]])
    assert table.nbytes == table_bytes(layout, 5)


def test_make_table_rejects_what_it_cannot_build():
    with pytest.raises(QuantizerError, match="unknown table layout"):
        make_table(np.array([0.5, 0.5]), "sparse")
    with pytest.raises(QuantizerError, match="full table at n = 7"):
        make_table(np.full(7, 1 / 7), "full")
    with pytest.raises(QuantizerError, match="1..12"):
        make_table(np.array([]), "diff")
