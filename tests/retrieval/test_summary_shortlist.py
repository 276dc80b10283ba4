"""StoryBeam's shortlist with clip summaries (issue 31): ``summary`` of the ``shortlist``
places go to the clips nearest by per-feature mean and spread, the rest to the code
search; the answer is exact float DTW over that union."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.dtw import dtw_features
from retrieval.errors import StoryBeamError
from retrieval.features import STORYBEAM, motion_features
from retrieval.library import SHORTLIST, SUMMARY, MotionIndex, StoryBeamSearcher, clip_summary
from retrieval.dtw.jit import HAVE_NUMBA
from retrieval.search.summary import nearest_not_in, summary_gaps, summary_nearest
from tests.support.synthetic_motion import make_motion, make_skeleton


def _library(n: int = 24, seed: int = 5) -> list[np.ndarray]:
    """Gaits of varied arm swing, knee bend, bounce, tempo and length, with a little noise."""
    rng = np.random.default_rng(seed)
    sk = make_skeleton()
    return [motion_features(make_motion(sk, frames=int(rng.integers(25, 90)), arm_swing=float(rng.uniform(5, 45)),
                                        knee_bend=float(rng.uniform(5, 35)), bounce=float(rng.uniform(0, 0.05)),
                                        period=float(rng.uniform(0.6, 1.4)), phase=float(rng.uniform(0, 1))),
                            "storybeam") + rng.normal(scale=0.02, size=(1, STORYBEAM.dim)) for _ in range(n)]


def test_clip_summary_is_each_columns_mean_then_its_10_to_90_percentile_range():
    x = np.array([[0.0, 1.0], [2.0, 1.0], [4.0, 1.0]])
    assert clip_summary(x) == pytest.approx([2.0, 1.0, 3.2, 0.0])  # percentiles 0.4 and 3.6
    # one glitched frame in 50 moves the spread little (the standard deviation nearly doubles)
    t = np.sin(np.linspace(0, 6, 50))[:, None]
    glitch = t.copy()
    glitch[20] = 8.0
    assert abs(clip_summary(glitch)[1] - clip_summary(t)[1]) < 0.1 * clip_summary(t)[1]
    # the same numbers as numpy's percentiles (linear interpolation), for any length
    rng = np.random.default_rng(2)
    for n in (1, 2, 7, 150):
        f = rng.normal(size=(n, 5))
        lo, hi = np.percentile(f, (10, 90), axis=0)
        assert clip_summary(f) == pytest.approx(np.concatenate([f.mean(axis=0), hi - lo]), abs=1e-12)
    with pytest.raises(StoryBeamError):
        clip_summary(np.zeros((0, 3)))
    assert SUMMARY == 2 and SHORTLIST == 3  # the defaults the notebook measures


@pytest.mark.parametrize("shortlist,summary", [(4, 2), (3, 1), (2, 2), (5, 3)])
def test_search_is_exact_dtw_over_the_code_part_and_the_summary_part(shortlist, summary):
    lib = _library()
    refs = lib[4:]
    s = StoryBeamSearcher.fit(refs, dims=4, shortlist=shortlist, summary=summary)
    assert s.summary == summary and s.summaries.shape == (len(refs), 2 * refs[0].shape[1])
    for q in lib[:4]:
        n_code = max(shortlist - summary, 2)  # k=2 below widens the code part
        res = s.searcher.search([s.quantizer.encode(q)], k=n_code, parallel=False) if n_code else None
        code = [int(i) for i in res.indices[0]]
        gap = np.linalg.norm(np.array([clip_summary(r) for r in refs]) - clip_summary(q), axis=1)
        extra = [int(i) for i in np.argsort(gap, kind="stable") if int(i) not in code][:summary]
        cands = s.shortlist_of(q, 2)
        assert [i for i, _ in cands] == code + extra
        assert all(d is None for _, d in cands[len(code):]) and all(d is not None for _, d in cands[:len(code)])
        brute = sorted((dtw_features(q, refs[i]), i) for i in code + extra)
        hits = s.search(q, k=2)
        assert [h.index for h in hits] == [i for _, i in brute[:2]]
        assert [h.distance for h in hits] == pytest.approx([d for d, _ in brute[:2]], rel=1e-9)


def test_the_summary_finds_what_the_codes_miss():
    """A library where the query's true neighbour has the same codes' *shape* problem: the
    summary part alone (summary = shortlist) still brings the clip with the query's spread."""
    rng = np.random.default_rng(0)
    t = np.linspace(0, 4 * np.pi, 60)
    still = [np.column_stack([np.full(60, 1.0 + 0.01 * i), np.zeros(60)]) + rng.normal(scale=0.01, size=(60, 2))
             for i in range(6)]
    waving = [np.column_stack([np.full(60, 1.0), 0.3 * np.sin(t * (1 + 0.1 * i))]) for i in range(2)]
    lib = still + waving
    q = np.column_stack([np.full(50, 1.0), 0.3 * np.sin(np.linspace(0, 4 * np.pi, 50))])
    s = StoryBeamSearcher.fit(lib, dims=1, shortlist=1, summary=1)
    assert s.search(q, k=1)[0].index in (6, 7)


def test_exclude_and_a_large_summary_never_return_the_excluded_or_a_duplicate():
    lib = _library()
    s = StoryBeamSearcher.fit(lib, dims=4, shortlist=4, summary=4)  # the summary ranking alone
    for i in range(6):
        cands = [j for j, _ in s.shortlist_of(lib[i], 1, exclude=i)]
        assert i not in cands and len(set(cands)) == len(cands)
        assert s.search(lib[i], k=1, exclude=i)[0].index != i
        assert s.search(lib[i], k=1)[0].index == i  # a clip finds itself at distance 0


def test_summary_zero_is_the_code_shortlist_and_negative_is_refused():
    lib = _library()
    s = StoryBeamSearcher.fit(lib[4:], dims=4, shortlist=4, summary=0)
    assert s.summaries is None and all(d is not None for _, d in s.shortlist_of(lib[0], 1))
    with pytest.raises(StoryBeamError, match="summary"):
        StoryBeamSearcher.fit(lib[4:], dims=4, summary=-1)
    # built directly (act it out's searcher), a searcher keeps the codes alone
    direct = StoryBeamSearcher(s.quantizer, s.codes, s.features, 4)
    assert direct.summary == 0


def test_the_index_keeps_its_summary_across_save_and_load(tmp_path):
    from retrieval.library import Clip  # deferred: test-local

    lib = _library(12)
    clips = [Clip(f"t{i}", "walk" if i % 2 else "run", f, None, 30.0) for i, f in enumerate(lib)]
    idx = MotionIndex.from_clips(clips, dims=4, method="storybeam", feature_set="storybeam")
    assert idx.summary == SUMMARY and idx._storybeam.summary == SUMMARY
    back = MotionIndex.load(idx.save(tmp_path / "ix"))
    assert back.summary == SUMMARY
    for f in lib[:3]:
        assert [m.trial for m in back.query(f, k=3)] == [m.trial for m in idx.query(f, k=3)]


def test_nearest_not_in_is_a_stable_argsort_without_the_taken():
    """The partition-based pick equals the whole stable argsort, ties included (integer
    gaps make many), whatever is taken and however many are asked for."""
    rng = np.random.default_rng(1)
    for t in range(3000):
        n = int(rng.integers(1, 30))
        gap = rng.integers(0, 5, size=n).astype(float) if t % 2 else rng.random(n)
        taken = set(rng.choice(n, size=int(rng.integers(0, n + 1)), replace=False).tolist())
        k = int(rng.integers(0, 6))
        want = [int(i) for i in np.argsort(gap, kind="stable") if int(i) not in taken][:k]
        assert nearest_not_in(gap, taken, k) == want


@pytest.mark.skipif(not HAVE_NUMBA, reason="the compiled summary shortlist needs numba")
def test_the_compiled_summary_shortlist_equals_numpys_bit_for_bit():
    """One compiled call gives numpy's summary distances exactly (mean, interpolated
    percentiles, pairwise-summed norm) and so the same pick, ties by position included:
    summary widths below, at and past numpy's 8-way unrolling, odd frame counts, a single
    frame, repeated values and libraries with identical summaries."""
    rng = np.random.default_rng(5)
    for t in range(400):
        d = int(rng.choice([1, 3, 4, 7, 9, 18, 31, 64]))
        frames = int(rng.integers(1, 250)) if t % 5 else int(rng.integers(1, 4))
        q = rng.normal(size=(frames, d)) * rng.uniform(0.01, 100)
        if t % 3 == 0:
            q = np.round(q)  # repeated values in every column
        m = int(rng.integers(1, 60))
        summaries = np.stack([clip_summary(rng.normal(size=(int(rng.integers(1, 40)), d))) for _ in range(m)])
        if t % 4 == 0:
            summaries[m // 2:] = summaries[0]  # ties by distance
        gap = np.linalg.norm(summaries - clip_summary(q), axis=1)
        assert np.array_equal(summary_gaps(summaries, q), gap)
        taken = set(rng.choice(m, size=int(rng.integers(0, m)), replace=False).tolist())
        n = int(rng.integers(1, 6))
        want = nearest_not_in(gap, taken, n)
        assert summary_nearest(summaries, q, taken, n) == want
        assert summary_nearest(summaries, q, taken, n, compiled=False) == want


def test_the_summary_shortlist_names_a_query_of_the_wrong_width():
    summaries = np.stack([clip_summary(np.ones((5, 3)))])
    with pytest.raises(StoryBeamError, match="summary shortlist"):
        summary_nearest(summaries, np.ones((5, 4)), set(), 1)
