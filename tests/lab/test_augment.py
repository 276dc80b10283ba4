"""lab.bench.augment: feature-space mirroring, time scaling and same-class splicing keep
what they promise -- mirroring swaps exactly the left/right feature pairs, time scaling
interpolates to round(T*factor) frames, a splice keeps a contiguous stretch of at least
half of each part, and a derived take is made of its own class's frames only."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from lab.bench import augment
from lab.bench.augment import TIME_SCALE_RANGE, augmented_take, mirror, mirror_permutation, splice, time_scale
from retrieval.errors import StoryBeamError
from retrieval.features import get_feature_set
from retrieval.library import act_search

NAMES = list(get_feature_set("mr17").names)


def _col(name: str) -> int:
    return NAMES.index(name)


# ----------------------------------------------------------------------------- mirroring


def test_mirror_permutation_swaps_left_and_right_pairs_and_keeps_symmetric_features():
    perm = mirror_permutation("mr17")
    assert sorted(perm.tolist()) == list(range(len(NAMES)))  # a permutation
    assert np.array_equal(perm[perm], np.arange(len(NAMES)))  # mirroring twice is the identity
    for left, right in [("lhand_head", "rhand_head"), ("lhand_rshoulder", "rhand_lshoulder"),
                        ("lankle_lhip", "rankle_rhip"), ("lankle_height", "rankle_height"),
                        ("lhand_above_head", "rhand_above_head")]:
        assert perm[_col(left)] == _col(right) and perm[_col(right)] == _col(left)
    for symmetric in ("hand_hand", "ankle_ankle", "knee_knee", "elbow_elbow", "hips_height"):
        assert perm[_col(symmetric)] == _col(symmetric)


def test_mirror_exchanges_the_columns_of_every_frame():
    x = np.arange(5 * len(NAMES), dtype=float).reshape(5, len(NAMES))
    m = mirror(x)
    assert m.shape == x.shape
    assert np.array_equal(m[:, _col("lhand_head")], x[:, _col("rhand_head")])
    assert np.array_equal(m[:, _col("hand_hand")], x[:, _col("hand_hand")])
    assert np.array_equal(mirror(m), x)


def test_mirror_negates_the_turning_rate():
    names = list(augment.get_feature_set("storybeam").names)
    h = names.index("heading_rate")
    x = np.random.default_rng(3).normal(size=(7, len(names)))
    m = mirror(x, "storybeam")
    assert np.array_equal(m[:, h], -x[:, h])  # a left turn mirrored is a right turn
    assert np.array_equal(m[:, names.index("lhand_head")], x[:, names.index("rhand_head")])
    assert np.array_equal(mirror(m, "storybeam"), x)


def test_derived_takes_are_the_scale_librarys_stream():
    from lab.bench.scale_library import derived_takes

    rng = np.random.default_rng(0)
    sources = [SimpleNamespace(label=lab, fps=30.0, features=rng.normal(size=(40 + 5 * i, len(NAMES))))
               for i, lab in enumerate(["walk", "run", "walk", "jump"])]
    takes = list(derived_takes(sources, min_clips=12, min_hours=0.001, seed=4))
    assert len(takes) >= 12 and sum(len(f) for _, f in takes) >= 0.001 * 3600 * 30
    again = list(derived_takes(sources, min_clips=20, min_hours=0.001, seed=4))
    assert [lab for lab, _ in again[:len(takes)]] == [lab for lab, _ in takes]  # a prefix of a bigger one
    assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(takes, again))


def test_a_feature_without_a_mirror_partner_is_an_error(monkeypatch):
    # mirror_permutation lives with the act index's augmentation (retrieval.library.act_search)
    monkeypatch.setattr(act_search, "get_feature_set", lambda name: SimpleNamespace(names=["hand_hand", "lhand_head"]))
    with pytest.raises(StoryBeamError, match="rhand_head"):
        mirror_permutation("lopsided")


# ----------------------------------------------------------------------------- time scaling


@pytest.mark.parametrize("factor", [0.8, 1.0, 1.25, 2.0])
def test_time_scale_resamples_to_the_scaled_length_by_linear_interpolation(factor):
    t = np.arange(40, dtype=float)
    x = np.stack([t, 3 * t + 1], axis=1)  # linear in time: interpolation reproduces it exactly
    y = time_scale(x, factor)
    n = int(round(40 * factor))
    assert y.shape == (n, 2)
    expected_t = np.linspace(0, 39, n)
    assert np.allclose(y[:, 0], expected_t) and np.allclose(y[:, 1], 3 * expected_t + 1)
    assert np.array_equal(y[[0, -1]], x[[0, -1]])  # the performance starts and ends where it did


def test_time_scale_keeps_at_least_two_frames_and_refuses_non_positive_factors():
    assert time_scale(np.ones((3, 4)), 0.01).shape == (2, 4)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(StoryBeamError):
            time_scale(np.ones((10, 2)), bad)


# ----------------------------------------------------------------------------- splicing


def test_splice_keeps_a_contiguous_stretch_of_at_least_half_of_each_part():
    parts = [np.full((n, 1), 1000.0 * k) + np.arange(n)[:, None] for k, n in enumerate((20, 7, 33), start=1)]
    for seed in range(20):
        out = splice(parts, np.random.default_rng(seed))[:, 0]
        for k, part in enumerate(parts, start=1):
            piece = out[(out >= 1000 * k) & (out < 1000 * (k + 1))]
            assert len(piece) >= max(2, int(len(part) * 0.5))
            assert np.all(np.diff(piece) == 1), "a part's frames must stay contiguous and in order"
        # the parts follow each other in the given order
        assert np.all(np.diff(out // 1000) >= 0)


def test_splice_is_reproducible_from_the_generator_seed():
    parts = [np.random.default_rng(1).normal(size=(30, 3)), np.random.default_rng(2).normal(size=(25, 3))]
    a = splice(parts, np.random.default_rng(7))
    b = splice(parts, np.random.default_rng(7))
    assert np.array_equal(a, b)


# ----------------------------------------------------------------------------- derived takes


def _class_clips(value: float, n_clips: int = 3, frames: int = 30) -> list[np.ndarray]:
    """Clips whose every feature is ``value`` except lhand_head (+1) and rhand_head (+2),
    so a take's class and mirroring can be read off its frames."""
    clips = []
    for _ in range(n_clips):
        x = np.full((frames, len(NAMES)), value)
        x[:, _col("lhand_head")] = value + 1
        x[:, _col("rhand_head")] = value + 2
        clips.append(x)
    return clips


def test_augmented_take_uses_only_its_class_and_is_mirrored_about_half_the_time():
    by_class = {"walk": _class_clips(0.0), "kick": _class_clips(10.0)}
    mirrored = 0
    takes = 60
    for seed in range(takes):
        x = augmented_take(by_class, "kick", np.random.default_rng(seed), max_parts=4)
        assert x.shape[1] == len(NAMES)
        assert np.all((x >= 10.0) & (x <= 12.0)), "frames of another class leaked into the take"
        # 1..4 parts of 30 frames, each keeping >= 15, then scaled by 0.8..1.25
        assert round(15 * TIME_SCALE_RANGE[0]) <= len(x) <= round(4 * 30 * TIME_SCALE_RANGE[1])
        left, right = x[0, _col("lhand_head")], x[0, _col("rhand_head")]
        assert {left, right} == {11.0, 12.0}
        mirrored += left == 12.0
    assert 0.25 * takes < mirrored < 0.75 * takes
