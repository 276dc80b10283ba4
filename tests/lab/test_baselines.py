"""The research's baselines (lab/experiment/baselines.py): exact DTW on features and
Forbes–Fiume (weighted-PCA pose space, k-means++ / k-means clusters, k-d tree, cluster DTW),
each checked against a brute-force reference."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.dtw import dtw_codes, dtw_features
from lab.experiment import ExactDTWMatcher, ForbesFiumeMatcher, MatcherError, kmeans_pp_seeds
from retrieval.library import Clip, clip_from_motion
from tests.support.synthetic_motion import make_motion, make_skeleton


def brute_dtw(x: np.ndarray, y: np.ndarray) -> float:
    """Textbook DTW, Euclidean frame cost, normalised by len(x) + len(y)."""
    n, m = len(x), len(y)
    d = np.full((n + 1, m + 1), np.inf)
    d[0, 0] = 0.0
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            cost = float(np.linalg.norm(x[i - 1] - y[j - 1]))
            d[i, j] = cost + min(d[i - 1, j], d[i, j - 1], d[i - 1, j - 1])
    return d[n, m] / (n + m)


def _random_clips(rng, count=5, width=17, pose_width=12) -> list[Clip]:
    clips = []
    for i in range(count):
        t = int(rng.integers(8, 20))
        walk = np.cumsum(rng.normal(size=(t, width)), axis=0)
        pose = np.cumsum(rng.normal(size=(t, pose_width)), axis=0)
        clips.append(Clip(f"c{i}", f"label{i % 2}", walk, pose, 30.0))
    return clips


@pytest.fixture(scope="module")
def gait_clips() -> list[Clip]:
    """Synthetic gait clips with real features and pose vectors, two styles."""
    sk = make_skeleton()
    clips = []
    for i, (arm, knee) in enumerate([(10, 10), (12, 12), (45, 30), (50, 35)]):
        motion = make_motion(sk, frames=45, arm_swing=arm, knee_bend=knee, phase=0.3 * i)
        clips.append(clip_from_motion(motion, f"t{i}", "calm" if arm < 30 else "big", pose=True))
    return clips


# --- k-means++ seeding ------------------------------------------------------------------


def test_kmeans_pp_seeds_are_distinct_data_points():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(300, 4))
    seeds = kmeans_pp_seeds(x, 25, np.random.default_rng(1))
    assert seeds.shape == (25, 4)
    hits = [np.flatnonzero((x == s).all(axis=1)) for s in seeds]
    assert all(len(h) == 1 for h in hits)  # every seed is a row of x
    assert len({int(h[0]) for h in hits}) == 25  # D² sampling never re-picks a chosen point
    again = kmeans_pp_seeds(x, 25, np.random.default_rng(1))
    assert np.array_equal(seeds, again)  # reproducible from the generator


def test_kmeans_pp_picks_every_distinct_point_when_k_equals_their_number():
    """With exactly k distinct points (each repeated), a chosen point has weight 0, so the
    k seeds are the k distinct points whatever the draws."""
    distinct = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 7.0], [3.0, 3.0]])
    x = np.repeat(distinct, [10, 1, 3, 6], axis=0)
    for seed in range(5):
        seeds = kmeans_pp_seeds(x, 4, np.random.default_rng(seed))
        assert sorted(map(tuple, seeds)) == sorted(map(tuple, distinct))


def test_kmeans_pp_on_identical_points_still_returns_data_points():
    x = np.ones((6, 3))
    assert np.array_equal(kmeans_pp_seeds(x, 3, np.random.default_rng(0)), np.ones((3, 3)))


# --- exact DTW --------------------------------------------------------------------------


def test_exact_dtw_distances_equal_the_textbook_dtw_against_each_reference():
    rng = np.random.default_rng(2)
    refs = _random_clips(rng)
    query = _random_clips(rng, count=1)[0]
    m = ExactDTWMatcher().fit(refs)
    got = m.distances(query)
    assert got.shape == (len(refs),)
    want = [brute_dtw(query.features, r.features) for r in refs]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    for backend in ("numpy", "auto"):
        same = ExactDTWMatcher(backend=backend).fit(refs).distances(query)
        np.testing.assert_allclose(same, [dtw_features(query.features, r.features, None, backend) for r in refs])


def test_exact_dtw_band_is_passed_to_the_kernel():
    rng = np.random.default_rng(3)
    refs = _random_clips(rng)
    query = _random_clips(rng, count=1)[0]
    banded = ExactDTWMatcher(band=2).fit(refs).distances(query)
    np.testing.assert_allclose(banded, [dtw_features(query.features, r.features, 2) for r in refs])
    assert np.all(banded >= ExactDTWMatcher().fit(refs).distances(query) - 1e-12)  # a band only constrains


def test_exact_dtw_finds_a_clip_itself_at_distance_zero(gait_clips):
    m = ExactDTWMatcher().fit(gait_clips)
    for i, clip in enumerate(gait_clips):
        d = m.distances(clip)
        assert d[i] == 0.0 and int(np.argmin(d)) == i


# --- Forbes–Fiume -----------------------------------------------------------------------


def test_forbes_fiume_encode_maps_each_centroid_to_itself(gait_clips):
    m = ForbesFiumeMatcher(clusters=16, seed=1).fit(gait_clips)
    k = len(m.centroids)
    assert k == 16
    axes = m.axes
    np.testing.assert_allclose(axes @ axes.T, np.eye(len(axes)), atol=1e-9)  # orthonormal PCA axes
    poses = m.mean + m.centroids @ axes  # each centroid, back in pose space
    assert np.array_equal(m.encode(poses), np.arange(k))


def test_forbes_fiume_encode_is_the_nearest_centroid(gait_clips):
    m = ForbesFiumeMatcher(clusters=12, seed=0).fit(gait_clips)
    frames = np.concatenate([c.pose for c in gait_clips])
    y = (frames - m.mean) @ m.axes.T
    brute = np.argmin(((y[:, None, :] - m.centroids[None]) ** 2).sum(axis=2), axis=1)
    codes = m.encode(frames)
    assert codes.dtype == np.int32
    # ties (equidistant centroids) may break either way: compare distances, not ids
    d = lambda ids: np.linalg.norm(y - m.centroids[ids], axis=1)
    np.testing.assert_allclose(d(codes), d(brute), atol=1e-9)


def test_forbes_fiume_table_is_the_centroid_distance_matrix(gait_clips):
    m = ForbesFiumeMatcher(clusters=10, seed=0).fit(gait_clips)
    c = m.centroids
    want = np.array([[np.linalg.norm(a - b) for b in c] for a in c])
    np.testing.assert_allclose(m.table, want, rtol=1e-6, atol=1e-6)
    assert m.table.dtype == np.float32 and np.all(np.diag(m.table) == 0)


def test_forbes_fiume_distances_are_cluster_dtw_and_zero_to_an_identical_clip(gait_clips):
    m = ForbesFiumeMatcher(clusters=16, seed=2).fit(gait_clips)
    for i, clip in enumerate(gait_clips):
        d = m.distances(clip)
        assert d[i] == 0.0
        codes = m.encode(clip.pose)
        np.testing.assert_allclose(d, [dtw_codes(codes, r, m.table) for r in m.reference_codes])
    assert all(np.array_equal(m.encode(c.pose), r) for c, r in zip(gait_clips, m.reference_codes))


def test_forbes_fiume_keeps_the_requested_share_of_variance(gait_clips):
    frames = np.concatenate([c.pose for c in gait_clips])
    s = np.linalg.svd(frames - frames.mean(axis=0), compute_uv=False)
    cumulative = np.cumsum(s**2) / np.sum(s**2)
    for variance in (0.5, 0.9, 0.99):
        m = ForbesFiumeMatcher(clusters=8, variance=variance).fit(gait_clips)
        keep = len(m.axes)
        assert cumulative[keep - 1] >= variance - 1e-12  # enough axes ...
        assert keep == 1 or cumulative[keep - 2] < variance  # ... and no more than needed


def test_forbes_fiume_caps_clusters_at_the_distinct_frames():
    rng = np.random.default_rng(4)
    pose = np.repeat(rng.normal(size=(5, 6)), 4, axis=0)  # 5 distinct frames
    clip = Clip("a", "x", np.zeros((20, 17)), pose, 30.0)
    m = ForbesFiumeMatcher(clusters=64, variance=0.999).fit([clip])
    assert len(m.centroids) == 5


def test_forbes_fiume_needs_poses_and_a_fit():
    with pytest.raises(MatcherError, match="needs pose vectors"):
        ForbesFiumeMatcher().fit([Clip("a", "x", np.zeros((5, 17)), None, 30.0)])
    unfitted = ForbesFiumeMatcher()
    with pytest.raises(MatcherError, match="before fit"):
        unfitted.encode(np.zeros((3, 54)))
    with pytest.raises(MatcherError, match="before fit"):
        unfitted.distances(Clip("a", "x", np.zeros((5, 17)), np.zeros((5, 54)), 30.0))
    with pytest.raises(MatcherError, match="no reference clips"):
        ForbesFiumeMatcher().fit([])
