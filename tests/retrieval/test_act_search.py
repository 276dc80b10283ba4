"""Search by performance (:class:`retrieval.library.ActSearch`): a library clip's own
joints find the clip itself at distance 0, ``exclude`` leaves trials out, a take's
BlazePose-like landmarks find a clip of the same class, a saved search answers the same
after loading, the answer equals exact DTW over the whole library when the shortlist
covers it, and bad input is refused plainly."""
from __future__ import annotations

import json

import numpy as np
import pytest

from retrieval.dtw import dtw_features
from retrieval.errors import IndexFormatError, StoryBeamError
from retrieval.features import leg_length
from retrieval.library import ActSearch, Match, clip_from_motion, clip_summary
from retrieval.library.act_search import ACT_SUMMARY, SHORT_TAKE_SECONDS, SHORT_WINDOW_SECONDS, feature_key
from retrieval.motion import canonical_joint_map, positions
from retrieval.motion.landmarks import LandmarkError
from tests.retrieval.test_frontal_landmarks import fake_landmarks
from tests.support.synthetic_motion import make_motion, make_skeleton

#: Two "classes": a gentle walk-like swing and a big arm-waving, knee-bending one.
KINDS = {"calm": dict(arm_swing=15.0, knee_bend=10.0), "wild": dict(arm_swing=80.0, knee_bend=60.0, bounce=0.08)}


def _motions():
    sk = make_skeleton()
    out = []
    for label, kw in KINDS.items():
        for k in range(4):
            m = make_motion(sk, frames=50 + 7 * k, period=0.8 + 0.15 * k, phase=0.2 * k, heading_deg=40.0 * k, **kw)
            m.name = f"{label}{k}"
            out.append((m, label, f"s{k % 2}"))
    return out


@pytest.fixture(scope="module")
def library():
    motions = _motions()
    clips = []
    for m, label, subject in motions:
        c = clip_from_motion(m, m.name, label, 30.0, "frontal", source=f"/lib/{m.name}.bvh")
        c.subject = subject
        clips.append(c)
    return ActSearch.from_clips(clips, dims=4), motions


def test_own_joints_find_the_clip_itself(library):
    search, motions = library
    m, label, subject = motions[5]
    jm = canonical_joint_map(m.skeleton)
    hits = search.search_positions(positions(m), 30.0, k=3, joint_map=jm, body_size=leg_length(m.skeleton, jm))
    assert isinstance(hits[0], Match)
    assert hits[0].trial == m.name and hits[0].distance < 1e-6
    assert hits[0].label == label and hits[0].subject == subject and hits[0].clip_path == f"/lib/{m.name}.bvh"
    assert [h.distance for h in hits] == sorted(h.distance for h in hits)
    assert set(hits[0].as_dict()) == {"trial", "label", "subject", "distance", "clip_path", "start_s", "end_s"}
    assert hits[0].start_s == 0.0 and hits[0].end_s == pytest.approx(m.n_frames / 30.0)  # short clips stay whole


def test_exclude_leaves_trials_out(library):
    search, motions = library
    m, label, subject = motions[5]
    jm = canonical_joint_map(m.skeleton)
    same_subject = [mm.name for mm, _, s in motions if s == subject]
    hits = search.search_positions(positions(m), 30.0, k=8, exclude=same_subject, joint_map=jm,
                                   body_size=leg_length(m.skeleton, jm))
    assert hits and not {h.trial for h in hits} & set(same_subject)
    assert len(hits) == len(motions) - len(same_subject)
    assert hits[0].label == label  # the nearest other performer's clip is of the same kind


def test_equals_exact_dtw_over_the_library(library):
    search, motions = library
    m, _, _ = motions[2]
    jm = canonical_joint_map(m.skeleton)
    q = search.position_features(positions(m)[5:40], 30.0, jm, leg_length(m.skeleton, jm))
    q32 = q.astype(np.float32).astype(np.float64)
    nearest: dict[str, float] = {}  # a trial's nearest window (its mirror, a tiled hop, ...)
    for f, t in zip(search.index.clip_features, search.index.trials):
        nearest[t] = min(nearest.get(t, np.inf), dtw_features(q32, f))
    want = sorted((d, t) for t, d in nearest.items())
    hits = search.search_features(q, k=len(motions), exclude=[m.name])
    assert [h.trial for h in hits] == [t for _, t in want if t != m.name]
    np.testing.assert_allclose([h.distance for h in hits], [d for d, t in want if t != m.name], rtol=1e-9)


def test_a_filmed_take_finds_its_class(library):
    search, motions = library
    sk = make_skeleton(scale=0.8)  # a smaller performer
    for label, kw in KINDS.items():
        m = make_motion(sk, frames=70, period=0.9, **kw)
        pos = positions(m)
        jm = canonical_joint_map(sk)
        pos[..., [0, 2]] -= pos[:, [jm["hips"]]][..., [0, 2]]
        world, image = fake_landmarks(pos, jm)
        valid = np.ones(len(pos), bool)
        valid[[3, 4, 30]] = False
        world[~valid] = np.nan
        hits = search.search_take(world, image, valid, 30.0, (640, 480), k=2)
        assert hits[0].label == label, (label, [h.as_dict() for h in hits])
    with pytest.raises(LandmarkError, match="no frame"):
        search.search_take(world, image, np.zeros(len(pos), bool), 30.0)


def test_other_frame_rates_are_resampled(library):
    search, motions = library
    m, _, _ = motions[1]
    jm = canonical_joint_map(m.skeleton)
    pos = positions(m)
    t = np.arange(len(pos)) / 30.0
    t60 = np.arange(int(t[-1] * 60) + 1) / 60.0
    pos60 = np.stack([np.interp(t60, t, c) for c in pos.reshape(len(pos), -1).T], 1).reshape(len(t60), *pos.shape[1:])
    hits = search.search_positions(pos60, 60.0, k=1, joint_map=jm, body_size=leg_length(m.skeleton, jm))
    assert hits[0].trial == m.name


def test_save_and_load_answer_the_same(library, tmp_path):
    search, motions = library
    m, _, _ = motions[6]
    jm = canonical_joint_map(m.skeleton)
    args = (positions(m)[::2], 15.0)
    kw = dict(k=4, joint_map=jm, body_size=leg_length(m.skeleton, jm), exclude=[m.name])
    search.save(tmp_path / "act")
    again = ActSearch.load(tmp_path / "act")
    assert [h.as_dict() for h in again.search_positions(*args, **kw)] == [h.as_dict() for h in search.search_positions(*args, **kw)]
    (tmp_path / "act" / "act.json").write_text(json.dumps({"subjects": []}))
    with pytest.raises(IndexFormatError, match="act.json"):
        ActSearch.load(tmp_path / "act")
    (tmp_path / "act" / "act.json").unlink()
    with pytest.raises(IndexFormatError, match="not found"):
        ActSearch.load(tmp_path / "act")


def test_bad_queries_are_refused(library):
    search, _ = library
    with pytest.raises(StoryBeamError, match="positions"):
        search.search_positions(np.zeros((10, 3)), 30.0)
    with pytest.raises(StoryBeamError, match="fps"):
        search.search_positions(np.random.default_rng(0).normal(size=(10, 18, 3)), 0.0)
    with pytest.raises(StoryBeamError, match="zero leg length"):
        search.search_positions(np.zeros((10, 18, 3)), 30.0)
    with pytest.raises(StoryBeamError, match="k must be"):
        search.search_features(np.zeros((10, 17)), k=0)
    with pytest.raises(StoryBeamError, match=r"\(frames, 17\)"):
        search.search_features(np.zeros((10, 16)))


def test_long_clips_are_searched_by_take_long_windows():
    sk = make_skeleton()
    clips, motions = [], []
    for k, (label, kw) in enumerate(KINDS.items()):
        for j in range(2):
            m = make_motion(sk, frames=300, period=0.9 + 0.2 * j, **kw)  # 10 s: several windows
            m.name = f"{label}{j}"
            motions.append(m)
            clips.append(clip_from_motion(m, m.name, label, 30.0, "frontal"))
    search = ActSearch.from_clips(clips, dims=4)
    assert len(search) == 4 and search.clip_names == [m.name for m in motions]
    assert len(search.index) > 4 * 4  # windows of 3.5 s every 1.75 s
    m = motions[1]
    jm = canonical_joint_map(sk)
    hits = search.search_positions(positions(m)[120:225], 30.0, k=4, joint_map=jm,
                                   body_size=leg_length(sk, jm))
    assert [h.trial for h in hits][0] == m.name and len({h.trial for h in hits}) == len(hits) == 4  # each clip once
    assert hits[0].end_s - hits[0].start_s == pytest.approx(3.5)
    hits = search.search_positions(positions(m)[120:225], 30.0, k=4, joint_map=jm, body_size=leg_length(sk, jm),
                                   exclude=[m.name])
    assert m.name not in {h.trial for h in hits} and len(hits) == 3


def test_short_takes_are_searched_by_short_windows(tmp_path):
    """A take under SHORT_TAKE_SECONDS is answered from the second index, whose windows
    are 2 s long (a 2 s kick against 3.5 s windows must warp 3.5 s onto 2); a longer take
    from the 3.5 s windows; the short index is saved and loaded with the search."""
    sk = make_skeleton()
    clips, motions = [], []
    for label, kw in KINDS.items():
        m = make_motion(sk, frames=300, period=0.9, **kw)
        m.name = label
        motions.append(m)
        clips.append(clip_from_motion(m, m.name, label, 30.0, "frontal"))
    search = ActSearch.from_clips(clips, dims=4)
    assert search.short is not None and search.short.short is None
    assert search.short.clip_names == search.clip_names and len(search.short.index) > len(search.index)
    jm = canonical_joint_map(sk)
    kw = dict(k=2, joint_map=jm, body_size=leg_length(sk, jm))
    take = positions(motions[1])[150:150 + int(SHORT_WINDOW_SECONDS * 30)]
    assert len(take) < SHORT_TAKE_SECONDS * 30
    hits = search.search_positions(take, 30.0, **kw)
    assert hits[0].trial == motions[1].name and hits[0].end_s - hits[0].start_s == pytest.approx(SHORT_WINDOW_SECONDS)
    long_take = positions(motions[1])[150:255]
    assert search.search_positions(long_take, 30.0, **kw)[0].end_s - \
        search.search_positions(long_take, 30.0, **kw)[0].start_s == pytest.approx(3.5)
    again = ActSearch.load(search.save(tmp_path / "act"))
    assert again.short is not None and len(again.short.index) == len(search.short.index)
    assert [h.as_dict() for h in again.search_positions(take, 30.0, **kw)] == [h.as_dict() for h in hits]
    single = ActSearch.from_clips(clips, dims=4, short_seconds=None)
    assert single.short is None
    hit = single.search_positions(take, 30.0, **kw)[0]
    assert hit.end_s - hit.start_s == pytest.approx(3.5)  # without it, a 2 s take meets 3.5 s windows


def test_relative_features_per_window_and_per_query(tmp_path):
    """The frontal set's ankle–hip distances are relative to their median over each
    library window, and over the query: a take cut from the middle of a long clip finds
    its window at distance ~0, and an index saved under another rule is refused."""
    sk = make_skeleton()
    clips = []
    for k, (label, kw) in enumerate(KINDS.items()):
        # whole periods (0.7 s = 21 frames) in the clip and in a take-long window, so the
        # heights' floor (a percentile of the lowest foot) is the same over both
        m = make_motion(sk, frames=294, period=0.7, knee_bend=20.0 + 40.0 * k, **{a: b for a, b in kw.items()
                                                                                   if a != "knee_bend"})
        m.name = label
        clips.append((m, clip_from_motion(m, label, label, 30.0, "frontal")))
    search = ActSearch.from_clips([c for _, c in clips], dims=4)
    fs = search.feature_set
    ah = [fs.names.index(n) for n in fs.relative]
    assert ah and len(search.index) > 2
    for f in search.index.clip_features:
        assert np.median(np.asarray(f, np.float64)[:, ah].mean(axis=1)) == pytest.approx(1.0, abs=1e-5)
    m = clips[1][0]
    start = search.starts[search.names.index(m.name) + 2]  # exactly the third window of the clip
    jm = canonical_joint_map(sk)
    hits = search.search_positions(positions(m)[start:start + 105], 30.0, k=1, joint_map=jm,
                                   body_size=leg_length(sk, jm))
    assert hits[0].trial == m.name and hits[0].start_s == pytest.approx(start / 30.0) and hits[0].distance < 1e-3
    folder = search.save(tmp_path / "act")
    meta = json.loads((folder / "act.json").read_text())
    assert meta["relative"] == list(fs.relative)
    assert meta["features"] == feature_key(fs) and "floor p30" in meta["features"]
    for key, value in (("relative", []), ("features", "weights 1; floor p2")):  # built under another rule
        (folder / "act.json").write_text(json.dumps({**meta, key: value}))
        with pytest.raises(IndexFormatError, match="rebuild"):
            ActSearch.load(folder)


def test_the_tablet_path_answers_as_the_compiled_one_in_one_sweep(monkeypatch):
    """On numpy (the tablet) the re-ranking sweeps every shortlisted window at once, so a
    top crowded by one clip's windows is answered from that same sweep: the same clips at
    the same distances as the compiled path, with one sweep per search."""
    import retrieval.library.storybeam_search as sbs

    sk = make_skeleton()
    clips = []
    for k, (label, kw) in enumerate(KINDS.items()):
        for j in range(3):
            m = make_motion(sk, frames=300, period=0.9 + 0.2 * j, phase=0.1 * j, **kw)
            m.name = f"{label}{j}"
            clips.append(clip_from_motion(m, m.name, label, 30.0, "frontal"))
    search = ActSearch.from_clips(clips, dims=4)
    jm = canonical_joint_map(sk)
    m = make_motion(sk, frames=300, period=1.0, **KINDS["wild"])
    sweeps = []
    real = sbs.dtw_features_many
    monkeypatch.setattr(sbs, "dtw_features_many", lambda *a, **kw: sweeps.append(1) or real(*a, **kw))
    for start, k in ((0, 1), (60, 3), (150, 5), (190, 6)):
        args = (positions(m)[start:start + 105], 30.0)
        kw = dict(k=k, joint_map=jm, body_size=leg_length(sk, jm))
        search.searcher.searcher.backend = "auto"
        want = search.search_positions(*args, **kw)
        search.searcher.searcher.backend = "numpy"  # the tablet: codes and re-ranking on numpy
        sweeps.clear()
        got = search.search_positions(*args, **kw)
        assert [(h.trial, h.distance, h.start_s) for h in got] == [(h.trial, h.distance, h.start_s) for h in want]
        assert len(got) == k and len(sweeps) == 1


def test_the_summary_places_bring_the_windows_nearest_by_summary(library, tmp_path):
    """Of the shortlist, :data:`ACT_SUMMARY` places go to the windows nearest by their
    summary (mean and spread of each feature) that the codes did not bring, never to an
    excluded trial's; the setting is kept by save and load. With a shortlist smaller than
    the library, those windows are re-ranked although the code search left them out."""
    search, motions = library
    assert search.summary == ACT_SUMMARY > 0 and search.searcher.summary == ACT_SUMMARY
    assert search.searcher is search.index.storybeam_searcher  # built once, with the index
    ix = search.index
    narrow = ActSearch(ix, search.names, search.starts, search.subjects, search.paths, shortlist=4,
                       augment=search.augment, summary=2)
    codes_only = ActSearch(ix, search.names, search.starts, search.subjects, search.paths, shortlist=4,
                           augment=search.augment, summary=0)
    m, _, _ = motions[3]
    jm = canonical_joint_map(m.skeleton)
    q = search.feature_set.relative_to_segment(
        search.position_features(positions(m), 30.0, jm, leg_length(m.skeleton, jm)))
    drop = set(search._entries[m.name])
    got = narrow.searcher.shortlist_of(q, 1, exclude=drop)
    by_codes = [i for i, cd in got if cd is not None]
    by_summary = [i for i, cd in got if cd is None]
    assert len(by_codes) >= 2 and len(by_summary) == 2  # the codes ask for one more per excluded window
    assert not (set(by_codes) | set(by_summary)) & drop
    gap = np.linalg.norm(narrow.searcher.summaries - clip_summary(q), axis=1)
    free = [i for i in np.argsort(gap, kind="stable") if i not in drop and i not in by_codes]
    assert by_summary == free[:2]
    assert all(cd is not None for _, cd in codes_only.searcher.shortlist_of(q, 1, exclude=drop))
    again = ActSearch.load(narrow.save(tmp_path / "act"))
    assert again.summary == 2 and again.searcher.summary == 2
    loaded = ActSearch.load(search.save(tmp_path / "full"))
    assert loaded.searcher is loaded.index.storybeam_searcher and loaded.searcher.summary == ACT_SUMMARY


@pytest.fixture(scope="module")
def long_library():
    """Two kinds, two 10 s clips each: a take of several windows can be cut from any."""
    sk = make_skeleton()
    clips, motions = [], []
    for label, kw in KINDS.items():
        for j in range(2):
            m = make_motion(sk, frames=300, period=0.9 + 0.2 * j, **kw)
            m.name = f"{label}{j}"
            motions.append(m)
            clips.append(clip_from_motion(m, m.name, label, 30.0, "frontal"))
    return ActSearch.from_clips(clips, dims=4), motions, sk


def _features(search, motion, sk, frames):
    jm = canonical_joint_map(sk)
    return search.position_features(positions(motion)[frames], 30.0, jm, leg_length(sk, jm))


def test_a_long_take_is_searched_window_by_window_and_combined_by_class(long_library, monkeypatch):
    """A take longer than LONG_TAKE_WINDOWS windows: each library-long window (every half
    window, the last ending with the take) is searched whole, and the classes' ranks are
    summed over the windows. Checked against that rule computed here from the windows'
    own answers; a take of calm windows and one wild one answers calm although its wild
    window matches a library window exactly, nearer than any calm window matches."""
    import retrieval.library.act_search as act  # deferred: test-local, for the constants

    search, motions, sk = long_library
    w = int(round(act.WINDOW_SECONDS * 30))
    calm = _features(search, motions[0], sk, slice(0, 280))
    calm = calm + np.random.default_rng(3).normal(0.0, 0.05, calm.shape)  # another performer's calm
    wild = _features(search, motions[3], sk, slice(52, 52 + w))  # one of the library's own windows
    take = np.concatenate([calm[:3 * w // 2 + w // 2], wild])  # 8 s: calm, then one window of wild
    assert len(take) > act.LONG_TAKE_WINDOWS * w

    seen = []
    whole = search._search_whole
    monkeypatch.setattr(search, "_search_whole", lambda f, k, ex: seen.append(len(f)) or whole(f, k, ex))
    hits = search.search_features(take, k=3)
    assert seen and set(seen) == {w}  # only library-long windows, never the whole take
    starts = list(range(0, len(take) - w + 1, w // 2))
    starts += [] if starts[-1] == len(take) - w else [len(take) - w]
    assert len(seen) == len(starts)

    answers = [whole(take[s:s + w], act.LONG_DEPTH, ()) for s in starts]
    score = {}
    for a in answers:
        for c in KINDS:
            score[c] = score.get(c, 0) + next((i for i, m in enumerate(a) if m.label == c), act.LONG_DEPTH)
    assert hits[0].label == min(score, key=score.get) == "calm"
    assert min((m for a in answers for m in a), key=lambda m: m.distance).label == "wild"  # the nearest window disagrees
    assert len({h.trial for h in hits}) == len(hits) == 3  # each clip once
    best = {}  # each clip's best window
    for m in (m for a in answers for m in a):
        best[m.trial] = m if m.trial not in best or m.distance < best[m.trial].distance else best[m.trial]
    for h in hits:
        assert h.distance == best[h.trial].distance and h.end_s - h.start_s == pytest.approx(act.WINDOW_SECONDS)
    rank = {}  # then every other clip by its own rank sum over the windows (ties: summed distances)
    for a in answers:
        where = {m.trial: (i, m.distance) for i, m in enumerate(a)}
        for t in best:
            i, d = where.get(t, (act.LONG_DEPTH, a[-1].distance))
            rank[t] = (rank.get(t, (0, 0.0))[0] + i, rank.get(t, (0, 0.0))[1] + d)
    rest = sorted((t for t in best if t != hits[0].trial), key=lambda t: rank[t])
    assert [h.trial for h in hits[1:]] == rest[:2]
    assert hits[0].trial == min((t for t in best if best[t].label == "calm"), key=lambda t: rank[t])


def test_a_long_take_keeps_exclude_and_caps_its_windows(long_library, monkeypatch):
    import retrieval.library.act_search as act  # deferred: test-local, for the constants

    search, motions, sk = long_library
    take = _features(search, motions[1], sk, slice(0, 300))
    hits = search.search_features(take, k=4, exclude=[motions[1].name])
    assert motions[1].name not in {h.trial for h in hits} and len(hits) == 3
    assert search.search_features(take, k=1)[0].trial == motions[1].name
    monkeypatch.setattr(act, "LONG_MAX_WINDOWS", 3)
    seen = []
    whole = search._search_whole
    monkeypatch.setattr(search, "_search_whole", lambda f, k, ex: seen.append(len(f)) or whole(f, k, ex))
    search.search_features(np.concatenate([take] * 4), k=1)  # 40 s: 21 windows, 3 searched
    assert len(seen) == 3


def test_a_take_up_to_the_long_take_limit_is_searched_whole(long_library, monkeypatch):
    import retrieval.library.act_search as act  # deferred: test-local, for the constants

    search, motions, sk = long_library
    w = int(round(act.WINDOW_SECONDS * 30))
    take = _features(search, motions[2], sk, slice(10, 10 + int(act.LONG_TAKE_WINDOWS * w)))
    seen = []
    whole = search._search_whole
    monkeypatch.setattr(search, "_search_whole", lambda f, k, ex: seen.append(len(f)) or whole(f, k, ex))
    search.search_features(take, k=2)
    assert seen == [len(take)]


def test_the_window_length_is_saved_with_the_search(long_library, tmp_path):
    search, motions, sk = long_library
    assert search.window_seconds == 3.5 and search.short.window_seconds == SHORT_WINDOW_SECONDS
    folder = search.save(tmp_path / "act")
    again = ActSearch.load(folder)
    assert again.window_seconds == 3.5 and again.short.window_seconds == SHORT_WINDOW_SECONDS
    take = _features(search, motions[0], sk, slice(0, 300))
    assert [h.as_dict() for h in again.search_features(take, k=3)] == [h.as_dict() for h in search.search_features(take, k=3)]
    for path in (folder / "act.json", folder / "short" / "act.json"):  # saved before the field: the role's length
        meta = json.loads(path.read_text())
        del meta["window_seconds"]
        path.write_text(json.dumps(meta))
    older = ActSearch.load(folder)
    assert older.window_seconds == 3.5 and older.short.window_seconds == SHORT_WINDOW_SECONDS
