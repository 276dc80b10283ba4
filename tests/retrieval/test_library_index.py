"""MotionIndex is StoryBeam's one search path: its answers (query, similar_to, subsequence,
the subset search behind the motion choice, `storybeam search`) must equal the brute-force
references of :mod:`retrieval.search.reference` — same trials, same distances, ties by
library order — on synthetic clips and on the shared CMU data, with both DTW back-ends."""
from __future__ import annotations

import json

import numpy as np
import pytest

import retrieval.search.subsequence as subsequence_module
from retrieval.codes import full_table
from retrieval.errors import IndexFormatError, StoryBeamError
from retrieval.features import STORYBEAM
from retrieval.library import Clip, MotionIndex, choose_clip
from retrieval.library.index import features_tag
from retrieval.motion import CANONICAL_POSE_VERSION
from retrieval.motion.formats import load_motion
from retrieval.search.reference import brute_force, brute_force_subsequence
from tests.support.synthetic_motion import make_motion, make_skeleton, write_bvh

BACKENDS = ["numba", "numpy"]


# ------------------------------------------------------------------ references
def _reference_query(index: MotionIndex, codes: np.ndarray, k: int, table) -> list[tuple[str, float]]:
    idx, dist = brute_force([codes], index.codes, table, k=k)
    return [(index.trials[i], float(d)) for i, d in zip(idx[0], dist[0]) if i >= 0]


def _reference_similar(index: MotionIndex, trial: str, k: int, table) -> list[tuple[str, float]]:
    i = index.position(trial)
    return [(t, d) for t, d in _reference_query(index, index.codes[i], len(index), table) if t != trial][:k]


def _reference_subsequence(index: MotionIndex, codes: np.ndarray, k: int) -> list[tuple]:
    # find_subsequence in every clip (on the index's difference table, whose values are the
    # seed table's); the reference's end frame is inclusive, a Match's exclusive
    hits = brute_force_subsequence(codes, index.codes, index.table, k=k)
    return [(index.trials[c], s, e + 1, d) for c, s, e, d in hits]


def _old_choose_clip(index: MotionIndex, table, label=None, query_codes=None, exclude=()) -> tuple[str, str, float]:
    """choose_clip as it was: a search over the whole library, then filtered (brute force here)."""
    if query_codes is not None:
        for t, d in _reference_query(index, query_codes, len(index), table):
            lab = index.labels[index.position(t)]
            if (label is None or lab == label) and t not in exclude:
                return t, lab, d
        raise AssertionError("no clip")
    members = [t for t, lab in zip(index.trials, index.labels) if lab == label and t not in exclude]
    if len(members) == 1:
        return members[0], label, 0.0
    typical = [float(np.median([d for t2, d in _reference_similar(index, t, len(index), table) if t2 in members]))
               for t in members]
    k = int(np.argmin(typical))
    return members[k], label, typical[k]


def _check_same(got, expect) -> None:
    assert [m.trial for m in got] == [e[0] for e in expect]
    np.testing.assert_allclose([m.distance for m in got], [e[-1] for e in expect], rtol=0, atol=1e-9)


# ------------------------------------------------------------------ synthetic clips
@pytest.fixture(scope="module")
def synthetic() -> tuple[list[Clip], np.ndarray]:
    """30 clips cut from one smooth random walk in feature space (so they share stretches
    and have near-ties), labels a/b/c, plus the walk itself for queries."""
    rng = np.random.default_rng(11)
    walk = np.cumsum(rng.normal(size=(3000, 17)), axis=0) * 0.1
    clips = [Clip(f"s{i:02d}", "abc"[i % 3], walk[s:s + int(rng.integers(25, 80))], None, 30.0)
             for i, s in enumerate(rng.integers(0, 2900, 30))]
    return clips, walk


@pytest.mark.parametrize("backend", BACKENDS)
def test_synthetic_answers_equal_brute_force(synthetic, backend):
    clips, walk = synthetic
    index = MotionIndex.from_clips(clips, dims=5, backend=backend)
    assert index.backend == backend
    table = full_table(index.quantizer.ratios)
    for q in (walk[200:260], walk[1500:1530], clips[3].features):
        codes = index.encode(q)
        _check_same(index.query(q, k=7), _reference_query(index, codes, 7, table))
    for t in ("s00", "s05", "s17"):
        _check_same(index.similar_to(t, k=6), _reference_similar(index, t, 6, table))
    for q in (walk[700:715], clips[8].features[5:20]):
        codes = index.encode(q)
        got = index.subsequence(q, k=5)
        expect = _reference_subsequence(index, codes, 5)
        assert [(m.trial, m.start, m.end) for m in got] == [e[:3] for e in expect]
        np.testing.assert_allclose([m.distance for m in got], [e[3] for e in expect], rtol=0, atol=1e-9)


def test_subset_search_equals_the_filtered_full_search(synthetic):
    """MotionIndex.among (what the motion choice uses) = the full answer filtered to the subset."""
    clips, walk = synthetic
    index = MotionIndex.from_clips(clips, dims=5)
    codes = index.encode(walk[900:960])
    full = index.query_codes(codes, k=len(index))
    subset = [i for i, lab in enumerate(index.labels) if lab == "b"][1:]
    allowed = {index.trials[i] for i in subset}
    expect = [m for m in full if m.trial in allowed]
    assert index.among(codes, subset, k=len(subset)) == expect
    assert index.among(codes, subset, k=2) == expect[:2]
    assert index.among(codes, subset, k=3, exclude=subset[0]) == [m for m in expect if m.trial != index.trials[subset[0]]][:3]
    assert index.among(codes, [], k=3) == []
    with pytest.raises(StoryBeamError, match="positions"):
        index.among(codes, [0, len(index)], k=1)


@pytest.mark.parametrize("backend", BACKENDS)
def test_choose_clip_equals_the_old_full_library_answer(synthetic, backend):
    clips, walk = synthetic
    index = MotionIndex.from_clips(clips, dims=5, backend=backend)
    table = full_table(index.quantizer.ratios)
    for label in ("a", "b", "c"):
        assert choose_clip(index, label) == _old_choose_clip(index, table, label)
        excl = (index.trials[index.labels.index(label)],)
        assert choose_clip(index, label, exclude=excl) == _old_choose_clip(index, table, label, exclude=excl)
    q = walk[2100:2160]
    codes = index.encode(q)
    for label in ("a", "c", None):
        assert choose_clip(index, label, q) == _old_choose_clip(index, table, label, codes)
    best = choose_clip(index, None, q)[0]
    assert choose_clip(index, None, q, exclude=(best,)) == _old_choose_clip(index, table, None, codes, (best,))


def test_choose_clip_reports_bad_choices(synthetic):
    clips, _ = synthetic
    index = MotionIndex.from_clips(clips, dims=4)
    with pytest.raises(StoryBeamError, match="no 'z' clips"):
        choose_clip(index, "z")
    with pytest.raises(StoryBeamError, match="by class"):
        choose_clip(index)
    with pytest.raises(StoryBeamError, match="excluded"):
        choose_clip(index, "a", exclude=tuple(t for t, lab in zip(index.trials, index.labels) if lab == "a"))


def test_save_load_round_trip_gives_the_same_answers(synthetic, tmp_path):
    clips, walk = synthetic
    index = MotionIndex.from_clips(clips, dims=5)
    loaded = MotionIndex.load(index.save(tmp_path / "idx"))
    assert loaded.trials == index.trials and loaded.labels == index.labels and loaded.fps == index.fps
    q = walk[400:450]
    assert loaded.query(q, k=8) == index.query(q, k=8)
    assert loaded.similar_to("s04", k=5) == index.similar_to("s04", k=5)
    assert loaded.subsequence(walk[40:52], k=4) == index.subsequence(walk[40:52], k=4)


def test_damaged_index_raises_index_format_error_naming_the_file(synthetic, tmp_path):
    clips, _ = synthetic
    folder = MotionIndex.from_clips(clips, dims=4).save(tmp_path / "idx")
    npz, js = folder / "index.npz", folder / "index.json"
    good_npz, good_js = npz.read_bytes(), js.read_text()

    npz.write_bytes(good_npz[: len(good_npz) // 2])  # truncated
    with pytest.raises(IndexFormatError, match="index.npz"):
        MotionIndex.load(folder)
    npz.write_bytes(good_npz)

    js.write_text(good_js[:40])  # broken JSON
    with pytest.raises(IndexFormatError, match="index.json"):
        MotionIndex.load(folder)
    meta = json.loads(good_js)
    meta["trials"] = meta["trials"][:-1]  # trials disagree with the codes
    js.write_text(json.dumps(meta))
    with pytest.raises(IndexFormatError, match="index.npz"):
        MotionIndex.load(folder)
    js.write_text(good_js)

    npz.unlink()
    with pytest.raises(IndexFormatError, match="index.npz"):
        MotionIndex.load(folder)


def test_an_index_saved_on_another_body_is_refused(synthetic, tmp_path):
    """Issue 31 moved the "storybeam" features onto the canonical body: an index saved
    before (no body recorded: the file's own) would compare a query on one body with a
    library on another, so it is refused with what to do; the demo builds it again."""
    clips, _ = synthetic
    storybeam_clips = [Clip(c.trial, c.label, np.hstack([c.features, np.zeros((len(c.features), STORYBEAM.dim - 17))]),
                            None, c.fps) for c in clips]
    folder = MotionIndex.from_clips(storybeam_clips, dims=4, feature_set="storybeam", method="storybeam").save(
        tmp_path / "idx")
    js = folder / "index.json"
    meta = json.loads(js.read_text())
    assert meta["body"] == features_tag("storybeam") == f"canonical-{CANONICAL_POSE_VERSION}"
    assert MotionIndex.load(folder).feature_set == "storybeam"
    del meta["body"]  # as saved before issue 31
    js.write_text(json.dumps(meta))
    with pytest.raises(IndexFormatError, match="index.json: .* the file's own body, .* the canonical-.* body: build the index again"):
        MotionIndex.load(folder)
    # the seed's features never moved: an old mr17 index still loads
    old = MotionIndex.from_clips(clips, dims=4).save(tmp_path / "old")
    meta = json.loads((old / "index.json").read_text())
    assert meta.pop("body") == "source"
    (old / "index.json").write_text(json.dumps(meta))
    assert MotionIndex.load(old).feature_set == "mr17"


def test_the_pruned_subsequence_search_skips_clips(synthetic):
    """The subsequence searcher behind MotionIndex.subsequence prunes by its bound (it
    does not run the DP against every clip) and still equals the reference above."""
    clips, _ = synthetic
    index = MotionIndex.from_clips(clips, dims=5)
    index.subsequence(clips[12].features[10:25], k=1)
    assert isinstance(index._subsequence, subsequence_module.SubsequenceSearcher)
    assert 1 <= index._subsequence.last_completed < len(index)


# ------------------------------------------------------------------ shared CMU data
@pytest.fixture(scope="module")
def cmu_index(cmu_dir) -> MotionIndex:
    return MotionIndex.build(cmu_dir, dims=6, fps=30.0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_cmu_answers_equal_brute_force(cmu_index, backend):
    """205 real CMU clips (near-ties between takes of one subject make a wrong bound show):
    a subset of queries — whole clips, a 4 s excerpt and a 1 s excerpt — of every class."""
    base = cmu_index
    index = MotionIndex(base.quantizer, base.codes, base.trials, base.labels, base.fps, base.feature_set,
                        base.band, backend=backend)
    assert len(index) == 205 and index.backend == backend
    table = full_table(index.quantizer.ratios)
    firsts = [base.labels.index(lab) for lab in sorted(set(base.labels))]  # one clip per class
    for i in firsts[:4]:
        _check_same(index.similar_to(index.trials[i], k=5), _reference_similar(index, index.trials[i], 5, table))
    long_clip = int(np.argmax([len(c) for c in index.codes]))
    excerpt = index.codes[long_clip][30:150]  # 4 s at 30 fps
    _check_same(index.query_codes(excerpt, k=5), _reference_query(index, excerpt, 5, table))
    short = index.codes[firsts[1]][10:40]  # 1 s
    got = index.subsequence_codes(short, k=3)
    expect = _reference_subsequence(index, short, 3)
    assert [(m.trial, m.start, m.end) for m in got] == [e[:3] for e in expect]
    np.testing.assert_allclose([m.distance for m in got], [e[3] for e in expect], rtol=0, atol=1e-9)


def test_cmu_motion_choice_equals_the_old_answer(cmu_index):
    index = cmu_index
    table = full_table(index.quantizer.ratios)
    q = index.codes[index.labels.index("walk")][:120]
    trial = index.trials[index.labels.index("walk")]
    # choose_clip takes a Motion; with codes, check the subset search it runs
    got = index.among(q, [i for i, (t, lab) in enumerate(zip(index.trials, index.labels))
                          if lab == "walk" and t != trial], k=1)[0]
    assert (got.trial, got.label, got.distance) == _old_choose_clip(index, table, "walk", q, (trial,))
    assert choose_clip(index, "jump") == _old_choose_clip(index, table, "jump")


# ------------------------------------------------------------------ the command
def test_search_command_json_to_stdout_and_subsequence(tmp_path, capsys):
    from app.cli import main

    sk = make_skeleton()
    folder = tmp_path / "lib"
    folder.mkdir()
    rows = ["trial,label,file,skeleton"]
    for i, (arm, knee) in enumerate(((20, 15), (22, 14), (80, 40), (78, 42))):
        write_bvh(make_motion(sk, frames=45, arm_swing=arm, knee_bend=knee, phase=0.3 * i), folder / f"m{i}.bvh")
        rows.append(f"m{i},{'slow' if i < 2 else 'big'},m{i}.bvh,")
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    q = folder / "m2.bvh"

    assert main(["search", "--data", str(folder), "--query", str(q), "-k", "3", "--dims", "3", "--json", "-"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"query", "data", "results", "search_ms", "encode_ms", "backend", "clips"}
    assert out["clips"] == 4 and out["search_ms"] >= 0 and out["backend"] in ("numba", "numpy")
    assert [r["rank"] for r in out["results"]] == [1, 2, 3] and out["results"][0]["trial"] == "m2"
    index = MotionIndex.build(folder, dims=3)
    expect = index.query(load_motion(q), k=3)
    assert [(r["trial"], r["distance"]) for r in out["results"]] == [(m.trial, m.distance) for m in expect]

    assert main(["search", "--data", str(folder), "--query", str(q), "--top", "2", "--dims", "3",
                 "--subsequence", "--json", str(tmp_path / "s.json")]) == 0
    sub = json.loads((tmp_path / "s.json").read_text())
    assert len(sub["results"]) == 2 and all({"start", "end"} <= set(r) for r in sub["results"])
    assert sub["results"][0]["trial"] == "m2" and sub["results"][0]["distance"] == 0.0
    assert "frames" in capsys.readouterr().out  # the human table is still printed

    assert main(["search", "--data", str(folder), "--query", str(q), "-k", "0"]) == 1
    assert "at least 1" in capsys.readouterr().err


def test_an_index_saved_before_the_hand_columns_is_refused_and_the_codes_skip_them(synthetic, tmp_path):
    """The "storybeam" set gained four hand-placement columns (issue 31) that its codes do
    not see: an index saved with the 18 columns before is refused with what to do, and a
    new one codes the first 18 columns only (the hand columns move no code)."""
    clips, _ = synthetic
    rng = np.random.default_rng(3)
    wide = [Clip(c.trial, c.label, np.hstack([c.features, rng.normal(size=(len(c.features), STORYBEAM.dim - 17))]),
                 None, c.fps) for c in clips]
    index = MotionIndex.from_clips(wide, dims=4, feature_set="storybeam", method="storybeam")
    assert index.quantizer.columns == STORYBEAM.coded == 18
    moved = [f.copy() for f in (c.features for c in wide)]
    for f in moved:
        f[:, 18:] += 5.0  # only the hand columns change
    assert all(np.array_equal(index.quantizer.encode(f), c) for f, c in zip(moved, index.codes))
    again = MotionIndex.load(index.save(tmp_path / "new"))
    assert again.quantizer.columns == 18
    assert all(np.array_equal(a, b) for a, b in zip(again.codes, index.codes))
    narrow = [Clip(c.trial, c.label, f[:, :18], None, c.fps) for c, f in zip(wide, (c.features for c in wide))]
    old = MotionIndex.from_clips(narrow, dims=4, feature_set="storybeam-no-hands", method="storybeam").save(
        tmp_path / "old")
    meta = json.loads((old / "index.json").read_text())
    meta["feature_set"] = "storybeam"  # as an index saved before the hand columns records its set
    (old / "index.json").write_text(json.dumps(meta))
    with pytest.raises(IndexFormatError, match="index.npz: its 'storybeam' features have 18 columns, this "
                                               "StoryBeam's have 22: build the index again"):
        MotionIndex.load(old)
