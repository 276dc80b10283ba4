"""StoryBeam's own retrieval: the turning-rate feature, features that agree across
skeletons, the code-shortlist + float-DTW re-ranking against brute force, the early
abandoning kernel, and the leave-one-subject-out protocol."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from retrieval.animation import BodyProportions, canonical_skeleton, retarget
from retrieval.dtw import dtw_features
from retrieval.search import clip_summary
from lab.experiment import evaluate, subject_folds
from lab.experiment.evaluation import EvaluationError
from retrieval.features import MR17, STORYBEAM, get_feature_set, heading_rate, motion_features
from retrieval.codes import Quantizer
from retrieval.errors import QuantizerError, StoryBeamError
from retrieval.library import (
    Clip,
    MotionIndex,
    StoryBeamSearcher,
    clip_from_motion,
    dtw_features_abandon,
    dtw_features_abandon_t,
    dtw_features_many,
)
from retrieval.library.storybeam_search import centre
from retrieval.motion import Joint, Motion, Skeleton, axis_rotation, load_motion, resample, save_bvh
from retrieval.motion.body import JointMapError
from tests.support.synthetic_motion import make_motion, make_skeleton

ASSETS = Path(__file__).resolve().parents[2] / "assets" / "motions"


def _turning(motion: Motion, degrees_per_second: float) -> Motion:
    """``motion`` with its root yawed about the vertical at a constant rate."""
    t = np.arange(motion.n_frames) / motion.fps
    yaw = axis_rotation("y", np.radians(degrees_per_second) * t)
    rot = motion.rotations.copy()
    rot[:, 0] = yaw @ rot[:, 0]
    return Motion(motion.skeleton, rot, motion.root_translation.copy(), motion.fps, "turning")


# ------------------------------------------------------------------ the feature set
#: The turning rate's column (after MR17's 17; the hand columns follow it).
TURN = STORYBEAM.names.index("heading_rate")

def test_storybeam_set_is_mr17_plus_turning_rate():
    fs = get_feature_set("storybeam")
    assert fs is STORYBEAM and fs.dim == MR17.dim + 5 and fs.needs_fps and not MR17.needs_fps
    assert fs.specs[: MR17.dim] == MR17.specs and fs.names[TURN] == "heading_rate" and TURN == MR17.dim
    m = make_motion(make_skeleton())
    f = motion_features(m, "storybeam")
    # MR17's pairs on the canonical body (issue 31), bit for bit; not the file's own MR17
    assert fs.body == "canonical"
    np.testing.assert_array_equal(f[:, : MR17.dim], motion_features(m, replace(MR17, body="canonical")))
    assert np.abs(f[:, : MR17.dim] - motion_features(m)).max() > 0.01


@pytest.mark.parametrize("rate", [-60.0, 45.0])
def test_heading_rate_measures_a_turn_with_its_sign(rate):
    m = _turning(make_motion(make_skeleton(), frames=120, arm_swing=0, knee_bend=0), rate)
    turn = motion_features(m, "storybeam")[:, TURN] / STORYBEAM.specs[TURN].weight
    inner = turn[35:-35]  # away from the smoothing's edges (4 σ = 30 frames)
    # positive = counter-clockwise seen from above (a left turn for a Z-forward body)
    np.testing.assert_allclose(inner, np.radians(rate), rtol=1e-3)
    straight = motion_features(make_motion(make_skeleton(), frames=120), "storybeam")[:, TURN]
    assert np.abs(straight).max() < 1e-9


def test_heading_rate_is_invariant_to_size_units_up_axis_heading_and_frame_rate():
    base = _turning(make_motion(make_skeleton(1.0), frames=120), 40.0)
    others = [
        _turning(make_motion(make_skeleton(0.6), frames=120), 40.0),            # smaller body
        _turning(make_motion(make_skeleton(1.0), frames=120, heading_deg=120), 40.0),  # faces elsewhere
    ]
    fb = motion_features(base, "storybeam")
    for o in others:
        np.testing.assert_allclose(motion_features(o, "storybeam"), fb, atol=1e-9)
    # a rate, not a per-frame step: at 60 fps the same turn reads the same rad/s
    fast = _turning(make_motion(make_skeleton(1.0), frames=240, fps=60.0), 40.0)
    inner = motion_features(fast, "storybeam")[60:-60, TURN]
    np.testing.assert_allclose(inner, fb[35:-35, TURN].mean(), rtol=1e-3)


def test_heading_rate_needs_the_frame_rate():
    m = make_motion(make_skeleton())
    from retrieval.features import FeatureError
    from retrieval.motion import canonical_joint_map, positions

    with pytest.raises(FeatureError, match="frame rate"):
        STORYBEAM.from_positions(positions(m), canonical_joint_map(m.skeleton), 1.0)
    assert heading_rate(np.zeros((1, 4, 3)), [0, 1, 2, 3], 30.0).shape == (1,)


# ------------------------------------------------------------------ two skeletons
#: Tolerances for the same motion retargeted onto two bodies. Same proportions at another
#: size: identical up to rounding. Different proportions (a child with longer shins,
#: shorter arms, wider shoulders): the retarget copies bone *directions*, so distances
#: between limbs change with the limbs' relative lengths; measured on the bundled walk
#: the largest difference is below these bounds (leg lengths; rad/s for the turn).
SAME_SHAPE_ATOL = 1e-6
OTHER_SHAPE_ATOL = 0.25
OTHER_SHAPE_MEAN = 0.06
TURN_ATOL = 0.05


def test_same_motion_on_two_skeletons_gives_the_same_features(tmp_path):
    walk = load_motion(ASSETS / "bvh" / "02_01.bvh")
    adult = canonical_skeleton(BodyProportions(), 1.8, "adult")
    small = canonical_skeleton(BodyProportions(), 1.1, "small")
    child = canonical_skeleton(BodyProportions(thigh=0.23, shin=0.26, upper_arm=0.15, forearm=0.14,
                                               shoulder_half_width=0.12, hip_half_width=0.07), 1.3, "child")
    feats = {}
    for sk in (adult, small, child):
        moved = retarget(walk, sk)
        # through StoryBeam's BVH writer and reader, at another frame rate
        back = load_motion(save_bvh(resample(moved, 50.0), tmp_path / f"{sk.name}.bvh"))
        feats[sk.name] = clip_from_motion(back, sk.name, "", 30.0, "storybeam").features
    a, s, c = feats["adult"], feats["small"], feats["child"]
    assert a.shape == s.shape == c.shape
    np.testing.assert_allclose(s, a, atol=SAME_SHAPE_ATOL)
    assert np.abs(np.delete(c - a, TURN, axis=1)).max() < OTHER_SHAPE_ATOL
    assert np.abs(np.delete(c - a, TURN, axis=1)).mean() < OTHER_SHAPE_MEAN
    assert np.abs(c - a)[:, TURN].max() < TURN_ATOL
    # and the source motion on its own (CMU) skeleton agrees with its retargeted copy
    src = clip_from_motion(walk, "src", "", 30.0, "storybeam").features
    n = min(len(src), len(a))  # 50 fps -> 30 fps may drop the last frame
    assert np.abs(src[:n] - a[:n])[:, TURN].max() < TURN_ATOL


def test_unmappable_skeleton_is_refused_naming_the_missing_joints():
    names = ["Hips", "Spine", "Neck", "Head", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot"]
    parents = [-1, 0, 1, 2, 0, 4, 5, 0, 7, 8]
    joints = [Joint(n, p, np.array([0.0, 10.0 * (i > 0), 0.0]), [], "ZYX") for i, (n, p) in enumerate(zip(names, parents))]
    sk = Skeleton(joints, metres_per_unit=0.01, up_axis="y", name="armless")
    m = Motion(sk, np.tile(np.eye(3), (5, len(joints), 1, 1)), np.zeros((5, 3)), 30.0)
    with pytest.raises(JointMapError) as err:
        clip_from_motion(m, "armless", "", 30.0, "storybeam")
    for missing in ("left_shoulder", "left_hand", "right_elbow", "left_toe"):
        assert missing in str(err.value)
    assert "armless" in str(err.value)


# ------------------------------------------------------------------ the search
def _library(n: int = 24, seed: int = 3) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    walk = motion_features(make_motion(make_skeleton(), frames=240), "storybeam")
    out = []
    for i in range(n):
        s = int(rng.integers(0, 120))
        x = walk[s:s + int(rng.integers(25, 90))].copy()
        x += rng.normal(scale=0.05, size=x.shape) * (1 + i % 3)
        out.append(x)
    return out


@pytest.mark.parametrize("backend", ["auto", "numpy"])
def test_rerank_kernel_equals_dtw_below_the_limit_and_abandons_above(backend):
    rng = np.random.default_rng(1)
    abandoned = 0
    for t in range(60):
        x, y = rng.normal(size=(int(rng.integers(1, 30)), 3)), rng.normal(size=(int(rng.integers(1, 30)), 3))
        band = None if t % 2 else int(rng.integers(0, 4))
        d = dtw_features(x, y, band)
        assert dtw_features_abandon(x, y, np.inf, band, backend) == d
        assert dtw_features_abandon(x, y, d, band, backend) == d  # a tie is never abandoned
        low = dtw_features_abandon(x, y, 0.7 * d, band, backend)
        assert low in (d, np.inf)
        abandoned += low == np.inf
    assert abandoned > 30  # the bound does fire


def test_rerank_kernel_numpy_path_is_bit_identical_to_the_compiled_one():
    pytest.importorskip("numba")
    rng = np.random.default_rng(4)
    for t in range(40):
        x, y = rng.normal(size=(int(rng.integers(1, 40)), 18)), rng.normal(size=(int(rng.integers(1, 40)), 18))
        band = None if t % 2 else int(rng.integers(0, 4))
        assert dtw_features_abandon(x, y, np.inf, band, "numba") == dtw_features_abandon(x, y, np.inf, band, "numpy")


def test_no_band_row_kernel_is_bit_identical_to_the_per_cell_kernel():
    """Without a band the compiled path runs the row-vectorised kernel; a band wider than
    both clips runs the per-cell one over the same cells: same distances bit for bit, the
    same abandoning decisions."""
    pytest.importorskip("numba")
    rng = np.random.default_rng(5)
    for t in range(80):
        # any width (three dimensions per pass, then the rest) and odd or even row counts
        # (rows are taken two at a time, the last one alone)
        dims = (18, 17, 1, 2, 4)[t % 5]
        x = rng.normal(size=(int(rng.integers(1, 120)), dims))
        y = rng.normal(size=(int(rng.integers(1, 120)), dims)) + rng.uniform(-0.5, 0.5)
        wide = len(x) + len(y)
        d = dtw_features_abandon(x, y, np.inf, wide, "numba")
        assert dtw_features_abandon(x, y, np.inf, None, "numba") == d
        assert dtw_features_abandon(x, y, np.inf, None, "numba") == dtw_features(x, y)
        y_t = np.ascontiguousarray(y.T)
        assert dtw_features_abandon(x, y, np.inf, None, "numba", y_t) == d
        assert dtw_features_abandon(x, y, 0.8 * d, None, "numba", y_t) == dtw_features_abandon(x, y, 0.8 * d, wide, "numba")
        for f in (0.5, 0.9, 1.0):
            assert dtw_features_abandon(x, y, f * d, None, "numba") == dtw_features_abandon(x, y, f * d, wide, "numba")
            # the re-ranking's unchecked entry (arrays checked once per query): the same results
            assert dtw_features_abandon_t(x, y_t, f * d) == dtw_features_abandon(x, y, f * d, None, "numba", y_t)
        assert dtw_features_abandon_t(x, y_t) == d


def test_many_at_once_numpy_rerank_is_bit_identical_pair_by_pair():
    """The tablet's re-ranking sweeps every candidate at once (padded, grouped by length,
    laid out by anti-diagonal): each distance equals the per-pair numpy DTW bit for bit —
    with and without a band, with groups forced small, with lengths far apart."""
    rng = np.random.default_rng(11)
    for t in range(60):
        dims = int(rng.integers(1, 8))
        x = rng.normal(size=(int(rng.integers(1, 30)), dims))
        ys = [rng.normal(size=(int(rng.integers(1, 70)), dims)) for _ in range(int(rng.integers(1, 8)))]
        for band in (None, 0, 3):
            got = dtw_features_many(x, ys, band, max_bytes=int(rng.choice([1 << 10, 64 << 20])))
            want = [dtw_features_abandon(x, y, np.inf, band, "numpy") for y in ys]
            assert got.tolist() == want
            assert want == [dtw_features(x, y, band, "numpy") for y in ys]
    assert dtw_features_many(np.zeros((3, 2)), []).shape == (0,)
    with pytest.raises(StoryBeamError):
        dtw_features_many(np.zeros((3, 2)), [np.zeros((4, 2)), np.zeros((4, 3))])


@pytest.mark.parametrize("shortlist", [2, 6])
def test_numpy_search_answers_as_the_compiled_one(shortlist):
    """The tablet's path (numpy: codes, bounds and the all-at-once re-ranking) returns the
    compiled path's clips, in order, at the same distances bit for bit."""
    pytest.importorskip("numba")
    lib = _library()
    fast = StoryBeamSearcher.fit(lib[4:], dims=4, shortlist=shortlist, backend="numba")
    slow = StoryBeamSearcher.fit(lib[4:], dims=4, shortlist=shortlist, backend="numpy")
    for q in lib[:4]:
        a, b = fast.search(q, k=3), slow.search(q, k=3)
        assert [(h.index, h.distance) for h in a] == [(h.index, h.distance) for h in b]


def test_shortlist_mode_runs_by_default_and_exact_on_request():
    lib = _library()
    runs = StoryBeamSearcher.fit(lib[4:], dims=4)
    exact = StoryBeamSearcher.fit(lib[4:], dims=4, mode="exact")
    assert runs.searcher.mode == "runs" and exact.searcher.mode == "exact"
    assert StoryBeamSearcher.fit(lib[4:], dims=4, band=5).searcher.mode == "exact"  # runs has no band
    for q in lib[:4]:  # either shortlist is re-ranked by the same exact float DTW
        for s in (runs, exact):
            h = s.search(q, k=1)[0]
            assert h.distance == dtw_features(q, lib[4 + h.index])


@pytest.mark.parametrize("shortlist", [1, 3, 8])
def test_search_is_exact_float_dtw_over_the_code_shortlist(shortlist):
    lib = _library()
    s = StoryBeamSearcher.fit(lib[4:], dims=4, shortlist=shortlist, summary=0)  # the codes alone
    for q in lib[:4]:
        codes = s.quantizer.encode(q)
        res = s.searcher.search([codes], k=max(shortlist, 2), parallel=False)  # k=2 widens a shortlist of 1
        cands = [int(i) for i in res.indices[0]]
        brute = sorted((dtw_features(q, lib[4 + i]), i) for i in cands)
        hits = s.search(q, k=2)
        assert [h.index for h in hits] == [i for _, i in brute[:2]]
        assert [h.distance for h in hits] == pytest.approx([d for d, _ in brute[:2]], rel=1e-9)


def test_search_with_the_whole_library_shortlisted_is_exact_dtw():
    lib = _library()
    s = StoryBeamSearcher.fit(lib[3:], dims=4, shortlist=len(lib))
    for q in lib[:3]:
        exact = np.array([dtw_features(q, r) for r in lib[3:]])
        hits = s.search(q, k=5)
        assert [h.index for h in hits] == list(np.argsort(exact, kind="stable")[:5])
    # a clip finds itself first, at distance 0, and exclude leaves it out
    s2 = StoryBeamSearcher.fit(lib, dims=4, shortlist=4)
    for i in range(len(lib)):
        top = s2.search(lib[i], k=1)[0]
        assert top.index == i and top.distance == 0.0
        assert s2.search(lib[i], k=1, exclude=i)[0].index != i


def test_centre_removes_each_columns_clip_mean():
    x = np.arange(12.0).reshape(4, 3) ** 2
    assert np.allclose(centre(x), x - x.mean(axis=0))
    assert np.allclose(centre(x).mean(axis=0), 0.0)
    assert np.allclose(centre(x + np.array([1.0, -2.0, 5.0])), centre(x))


@pytest.mark.parametrize("shortlist,summary", [(1, 0), (3, 0), (8, 0), (4, 2), (3, 1)])
def test_find_is_exact_centred_dtw_over_the_centred_shortlist(shortlist, summary):
    """find's candidates: the ``shortlist`` code-nearest clips of the centred codes, plus
    ``summary`` more by the centred summaries; exact centred DTW ranks them."""
    lib = _library()
    s = StoryBeamSearcher.fit(lib[4:], dims=4, shortlist=shortlist, summary=summary)
    ident = s.identity_searcher()
    assert ident is s.identity_searcher()  # built once
    summaries = np.stack([clip_summary(centre(f)) for f in lib[4:]])
    for q in lib[:4]:
        res = ident.searcher.search([ident.quantizer.encode(centre(q))], k=max(shortlist, 2), parallel=False)
        cands = [int(i) for i in res.indices[0]]
        gaps = np.linalg.norm(summaries - clip_summary(centre(q)), axis=1)
        cands += [int(i) for i in np.argsort(gaps, kind="stable") if int(i) not in cands][:summary]
        brute = sorted((dtw_features(centre(q), centre(lib[4 + i])), i) for i in cands)
        hits = s.find(q, k=2)
        assert [h.index for h in hits] == [i for _, i in brute[:2]]
        assert [h.distance for h in hits] == pytest.approx([d for d, _ in brute[:2]], rel=1e-9)


def test_find_keeps_every_code_candidate_and_adds_the_summary_ones():
    """The summary places come on top of the code shortlist, never instead of it: a clip
    the centred codes shortlist is still a candidate, and the clip whose centred spreads
    are nearest the query's is one too, however far its codes (issue 31: a Daz-figure
    conversion of CMU 10_02, ranked below four other soccer kicks by the codes alone)."""
    lib = _library()
    s = StoryBeamSearcher.fit(lib[4:], dims=4, shortlist=4, summary=2)
    codes_only = StoryBeamSearcher.fit(lib[4:], dims=4, shortlist=4, summary=0).identity_searcher()
    ident = s.identity_searcher()
    summaries = np.stack([clip_summary(centre(f)) for f in lib[4:]])
    added = 0
    for q in lib[:4] + [f + np.random.default_rng(1).normal(scale=0.3, size=f.shape) for f in lib[4:10]]:
        cq = centre(q)
        code_cands = {i for i, _ in codes_only.shortlist_of(cq, 1)}
        cands = {i for i, _ in ident.shortlist_of(cq, 1)}
        assert code_cands <= cands and len(cands) == 6
        nearest = int(np.argmin(np.linalg.norm(summaries - clip_summary(cq), axis=1)))
        assert nearest in cands
        added += nearest not in code_cands
    assert added  # the data holds queries whose spread-nearest clip the codes miss


def test_find_sees_through_a_per_clip_offset_where_the_class_ranking_does_not():
    """A clip comes back from another skeleton shifted by a per-clip offset; a near-duplicate
    (another take) sits closer to the shifted copy than the clip itself by raw DTW. The class
    ranking answers the near-duplicate, find answers the clip itself at centred distance 0."""
    lib = _library()
    offset = np.linspace(0.2, -0.2, lib[0].shape[1])
    twin = lib[5] + offset + np.random.default_rng(9).normal(scale=0.01, size=lib[5].shape)
    library = lib + [twin]
    s = StoryBeamSearcher.fit(library, dims=4, shortlist=len(library))
    query = lib[5] + offset
    assert s.search(query, k=1)[0].index == len(library) - 1  # raw DTW: the twin
    top = s.find(query, k=1)[0]
    assert top.index == 5 and top.distance == pytest.approx(0.0, abs=1e-12)
    assert s.find(query, k=1, exclude=5)[0].index != 5
    with pytest.raises(StoryBeamError, match="find"):
        s.find(query[:, :3])


def test_motion_index_find_uses_the_identity_ranking_on_storybeam_indexes():
    lib = _library(12)
    clips = [Clip(f"c{i}", "walk", f, None, 30.0) for i, f in enumerate(lib)]
    idx = MotionIndex.from_clips(clips, dims=4, feature_set="storybeam", method="storybeam")
    for i in (0, 7):
        shifted = lib[i] + 0.3
        top = idx.find(shifted, k=3)
        expect = idx._storybeam.find(np.asarray(shifted, dtype=np.float32).astype(np.float64), k=3)
        assert [m.trial for m in top] == [f"c{h.index}" for h in expect]
        assert top[0].trial == f"c{i}"
    quant = MotionIndex.from_clips(clips, dims=4, feature_set="storybeam", method="quantized")
    assert [m.trial for m in quant.find(lib[3], k=2)] == [m.trial for m in quant.query(lib[3], k=2)]


# ------------------------------------------------------------------ the protocols
def _clips() -> list[Clip]:
    lib = _library(30)
    return [Clip(f"t{i}", "ab"[i % 2], f, None, 30.0, subject=f"s{i % 5}") for i, f in enumerate(lib)]


def test_subject_folds_leave_one_group_out():
    subjects = ["b", "a", "b", "c", "a"]
    folds = subject_folds(subjects)
    assert [f.tolist() for f in folds] == [[1, 4], [0, 2], [3]]
    with pytest.raises(EvaluationError, match="subject"):
        subject_folds(["a", "", "b"])
    with pytest.raises(EvaluationError, match="2 subject groups"):
        subject_folds(["a", "a"])


def test_subject_split_never_answers_from_the_query_subject():
    clips = _clips()
    subject = {c.trial: c.subject for c in clips}
    res = evaluate(clips, ["storybeam", "dtw-storybeam", "dtw"], dims=4, split="subject")
    for r in res.values():
        assert r.total == len(clips)
        assert all(subject[q] != subject[a] for q, a in r.predictions.items())
        assert sum(sum(row.values()) for row in r.confusion.values()) == len(clips)


def test_seed_methods_see_only_the_mr17_columns():
    clips = _clips()
    narrow = [Clip(c.trial, c.label, c.features[:, : MR17.dim], None, 30.0, subject=c.subject) for c in clips]
    wide = evaluate(clips, ["dtw", "dtw-storybeam"], folds=3)
    seed = evaluate(narrow, ["dtw"], folds=3)
    assert wide["dtw"].predictions == seed["dtw"].predictions
    # and the turning column matters to dtw-storybeam: its distances differ from dtw's
    q, r = clips[0].features, clips[1].features
    assert dtw_features(q, r) != dtw_features(q[:, : MR17.dim], r[:, : MR17.dim])


def test_seed_methods_can_keep_the_seeds_own_features():
    """With the storybeam features on the canonical body, the seed's methods are given
    the file's own MR17 (``seed_clips``, as ``storybeam eval`` loads them): their answers
    are those of a seed-only run, and the storybeam methods still see ``clips``."""
    clips = _clips()
    weights = np.linspace(0.1, 4.0, MR17.dim)  # another view of the clips: other distances, other answers
    other = [Clip(c.trial, c.label, c.features[:, : MR17.dim] * weights, None, 30.0, subject=c.subject)
             for c in clips]
    mixed = evaluate(clips, ["dtw", "dtw-storybeam"], folds=3, seed_clips=other)
    alone = evaluate(other, ["dtw"], folds=3)
    assert mixed["dtw"].predictions == alone["dtw"].predictions
    assert mixed["dtw"].predictions != evaluate(clips, ["dtw"], folds=3)["dtw"].predictions
    assert mixed["dtw-storybeam"].predictions == evaluate(clips, ["dtw-storybeam"], folds=3)["dtw-storybeam"].predictions
    with pytest.raises(EvaluationError, match="same clips"):
        evaluate(clips, ["dtw"], folds=3, seed_clips=other[::-1])


def test_a_quantizer_on_the_first_columns_ignores_the_rest():
    """``Quantizer.fit(..., columns=k)``: the same codes as a quantiser fitted on the first
    k columns alone, whatever the other columns hold; saved and loaded with its columns."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(300, 7)) * np.array([3, 2, 1, 1, 0.5, 9, 9])
    part = Quantizer.fit(x[:, :5], 3)
    full = Quantizer.fit(x, 3, columns=5)
    np.testing.assert_array_equal(full.encode(x), part.encode(x[:, :5]))
    np.testing.assert_allclose(full.ratios, part.ratios)
    y = x.copy()
    y[:, 5:] = rng.normal(size=(300, 2)) * 100
    np.testing.assert_array_equal(full.encode(y), full.encode(x))
    back = Quantizer.from_arrays(full.to_arrays())
    assert back.columns == 5 and Quantizer.from_arrays(part.to_arrays()).columns is None
    np.testing.assert_array_equal(back.encode(y), full.encode(x))
    with pytest.raises(QuantizerError, match="columns must be 1..7"):
        Quantizer.fit(x, 3, columns=8)
    with pytest.raises(QuantizerError, match="n must be 1..2 for 2-D features"):
        Quantizer.fit(x, 3, columns=2)
    # the searcher's codes, and find()'s centred ones, follow the columns
    lib = [x[i * 30:(i + 1) * 30] for i in range(10)]
    s = StoryBeamSearcher.fit(lib, dims=3, code_columns=5)
    assert s.quantizer.columns == 5 and s.identity_searcher().quantizer.columns == 5
