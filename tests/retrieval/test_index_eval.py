"""Dataset loading, the index (build/save/load/query), the k-fold evaluation and the CLI
JSON shapes, on a tiny synthetic labelled folder written as BVH files."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from retrieval.errors import DatasetError, IndexFormatError
from retrieval.library import MotionIndex
from retrieval.motion import load_motion
from tests.support.synthetic_motion import make_motion, make_skeleton, write_bvh

pytest.importorskip("retrieval.motion.formats.dispatch")

STYLES = {  # label: (arm swing, knee bend, bounce, period)
    "walk": (20.0, 15.0, 0.0, 1.0),
    "run": (60.0, 45.0, 0.08, 0.6),
    "wave": (90.0, 3.0, 0.0, 0.8),
}


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> Path:
    """9 clips, 3 per class, with different body sizes, phases, lengths and headings."""
    folder = tmp_path_factory.mktemp("lib")
    rng = np.random.default_rng(7)
    rows = ["trial,label,subject,file,skeleton,notes"]
    for label, (arm, knee, bounce, period) in STYLES.items():
        for k in range(3):
            sk = make_skeleton(scale=float(rng.uniform(0.7, 1.1)))
            m = make_motion(sk, frames=int(rng.integers(36, 50)), fps=30.0, arm_swing=arm * rng.uniform(0.9, 1.1),
                            knee_bend=knee, bounce=bounce, period=period, phase=float(rng.uniform(0, 6)),
                            heading_deg=float(rng.uniform(0, 360)))
            name = f"{label}_{k}"
            write_bvh(m, folder / f"{name}.bvh")
            rows.append(f"{name},{label},s{k},{name}.bvh,,x")
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    return folder


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("STORYBEAM_CACHE", str(tmp_path / "cache"))


def test_dataset_loads_clips_and_reports_bad_rows(library, tmp_path):
    from retrieval.library import load_dataset

    clips = load_dataset(library, fps=15)
    assert [c.label for c in clips].count("run") == 3
    # pose vectors (the Forbes–Fiume baseline's) only when asked for
    assert all(c.fps == 15 and c.features.shape[1] == 17 and c.pose is None for c in clips)
    again = load_dataset(library, fps=15)  # through the cache
    assert np.array_equal(again[4].features, clips[4].features) and again[4].pose is None
    posed = load_dataset(library, fps=15, pose=True)  # a cached entry without poses is rebuilt
    assert all(c.pose is not None and c.pose.shape == (c.n_frames, 54) for c in posed)
    assert np.array_equal(posed[4].features, clips[4].features)
    seen = []
    load_dataset(library, fps=15, progress=lambda done, total: seen.append((done, total)))
    assert seen == [(i + 1, len(clips)) for i in range(len(clips))]

    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "labels.csv").write_text("trial,label,file\nx,walk,x.bvh\n")
    with pytest.raises(DatasetError, match="skeleton"):
        load_dataset(bad)
    (bad / "labels.csv").write_text("trial,label,file,skeleton\nx,walk,missing.bvh,\n")
    with pytest.raises(DatasetError, match="line 2.*missing.bvh"):
        load_dataset(bad)


def test_index_query_save_load(library, tmp_path):
    from retrieval.library import load_dataset
    from retrieval.library import MotionIndex
    from retrieval.motion.formats import load_motion

    index = MotionIndex.build(library, dims=3, fps=30)
    assert len(index) == 9 and index.method == "storybeam" and index.feature_set == "storybeam"
    hits = index.query(load_motion(library / "run_1.bvh"), k=3)
    assert hits[0].trial == "run_1" and hits[0].distance == pytest.approx(0.0, abs=1e-9)
    assert [h.distance for h in hits] == sorted(h.distance for h in hits)
    similar = index.similar_to("walk_0", k=2)
    assert "walk_0" not in [s.trial for s in similar] and similar[0].label == "walk"

    index.save(tmp_path / "idx")
    loaded = MotionIndex.load(tmp_path / "idx")
    feats = load_dataset(library, fps=30, feature_set="storybeam")[2].features
    assert loaded.method == "storybeam" and loaded.query(feats, k=9) == index.query(feats, k=9)
    assert loaded.similar_to("walk_0", k=3) == index.similar_to("walk_0", k=3)
    # the seed's method on request, and an index saved before the method existed loads as it
    seed = MotionIndex.build(library, dims=3, fps=30, method="quantized")
    assert seed.method == "quantized" and seed.feature_set == "mr17"
    meta = json.loads(seed.save(tmp_path / "old").joinpath("index.json").read_text())
    del meta["method"], meta["shortlist"]
    (tmp_path / "old" / "index.json").write_text(json.dumps(meta))
    old = MotionIndex.load(tmp_path / "old")
    seed_feats = load_dataset(library, fps=30)[2].features
    assert old.method == "quantized" and old.query(seed_feats, k=9) == seed.query(seed_feats, k=9)

    (tmp_path / "idx" / "index.json").write_text("{not json")
    with pytest.raises(IndexFormatError):
        MotionIndex.load(tmp_path / "idx")
    with pytest.raises(IndexFormatError):
        MotionIndex.load(tmp_path / "nowhere")


def test_folds_are_stratified_and_disjoint():
    from lab.experiment import stratified_folds

    labels = ["a"] * 7 + ["b"] * 5 + ["c"] * 3
    parts = stratified_folds(labels, 3, seed=1)
    allidx = np.concatenate(parts)
    assert sorted(allidx.tolist()) == list(range(15))
    for p in parts:
        assert 4 <= len(p) <= 6
        assert sum(labels[i] == "c" for i in p) == 1


def test_evaluation_separates_the_synthetic_classes(library):
    from retrieval.library import load_dataset
    from lab.experiment import evaluate

    clips = load_dataset(library, fps=30, pose=True)
    res = evaluate(clips, ["quantized", "dtw", "forbes"], folds=3, dims=3, forbes_clusters=16)
    for name, r in res.items():
        assert r.total == 9
        assert r.accuracy >= 8 / 9, (name, r.predictions)
        assert set(r.per_class) == set(STYLES)
        assert r.search_seconds > 0


def test_cli_json_shapes(library, tmp_path):
    from app.cli import main

    out = tmp_path / "eval.json"
    rc = main(["eval", "--data", str(library), "--folds", "3", "--dims", "3", "--fps", "15",
               "--json", str(out), "--sweep-dims", "1-2", "--plots", str(tmp_path / "plots"), "--quiet",
               "--forbes-clusters", "16"])
    assert rc == 0
    data = json.loads(out.read_text())
    assert data["n_clips"] == 9 and data["total_seconds"] > 0
    for name in ("quantized", "dtw", "forbes"):
        m = data["methods"][name]
        assert 0 <= m["accuracy"] <= 1 and 0 <= m["balanced_accuracy"] <= 1 and m["search_seconds"] > 0
        assert set(m["per_class"]) == set(STYLES)
    assert [r["dims"] for r in data["sweep"]] == [1, 2]
    assert all(Path(p).is_file() for p in data["plots"])

    res = tmp_path / "search.json"
    rc = main(["search", "--data", str(library), "--query", str(library / "wave_2.bvh"), "--top", "4",
               "--dims", "3", "--json", str(res), "--save-index", str(tmp_path / "idx")])
    assert rc == 0
    results = json.loads(res.read_text())["results"]
    assert len(results) == 4 and results[0]["trial"] == "wave_2"
    assert set(results[0]) == {"rank", "trial", "label", "distance"}
    assert [r["distance"] for r in results] == sorted(r["distance"] for r in results)
    # a saved index works as --data too
    rc = main(["search", "--data", str(tmp_path / "idx"), "--query", str(library / "wave_2.bvh"), "--json", str(res)])
    assert rc == 0 and json.loads(res.read_text())["results"][0]["trial"] == "wave_2"
    # "find this clip": the identity ranking, same answer as MotionIndex.find on the saved index
    rc = main(["search", "--data", str(tmp_path / "idx"), "--query", str(library / "wave_2.bvh"), "--find",
               "--top", "3", "--json", str(res)])
    found = json.loads(res.read_text())
    assert rc == 0 and found["mode"] == "find" and found["results"][0]["trial"] == "wave_2"
    saved = MotionIndex.load(tmp_path / "idx")
    expect = saved.find(load_motion(library / "wave_2.bvh"), k=3)
    assert [r["trial"] for r in found["results"]] == [m.trial for m in expect]
    assert main(["search", "--data", str(tmp_path / "idx"), "--query", str(library / "wave_2.bvh"), "--find",
                 "--subsequence"]) == 1


def test_cli_subject_split_confusion_plots_and_identity(library, tmp_path):
    from app.cli import main

    out = tmp_path / "eval.json"
    rc = main(["eval", "--data", str(library), "--dims", "3", "--split", "random,subject", "--quiet",
               "--methods", "storybeam,dtw-storybeam,quantized", "--json", str(out), "--plots", str(tmp_path / "p")])
    assert rc == 0
    data = json.loads(out.read_text())
    assert set(data["splits"]) == {"random", "subject"} and data["feature_set"] == "storybeam"
    assert data["subjects"] == {"s0": 3, "s1": 3, "s2": 3}
    for split in ("random", "subject"):
        methods = data["splits"][split]["methods"]
        assert set(methods) == {"storybeam", "dtw-storybeam", "quantized"}
        for m in methods.values():
            assert m["queries"] == 9 and sum(sum(r.values()) for r in m["confusion"].values()) == 9
        assert data["splits"][split]["dtw_storybeam_over_storybeam_search_time"] > 0
    assert len(data["confusion_plots"]) == 6 and all(Path(p).is_file() for p in data["confusion_plots"])

    ident = tmp_path / "identity.json"
    assert main(["eval", "--data", str(library), "--dims", "3", "--identity", "--quiet", "--json", str(ident)]) == 0
    found = json.loads(ident.read_text())["identity"]
    # the synthetic takes of a class are near-duplicates: report, do not promise, identity here
    assert found["clips"] == 9 and 0 <= found["quantized_top1"] <= 1
    assert len(found["storybeam_misses"]) == round(9 * (1 - found["storybeam_top1"]))
    assert len(found["storybeam_find_misses"]) == round(9 * (1 - found["storybeam_find_top1"]))
    assert main(["eval", "--data", str(library), "--split", "sideways", "--quiet"]) == 1


def test_unlabelled_clips_load_group_and_search_but_are_refused_by_eval(library, tmp_path, capsys):
    """A teacher's import: labels.csv rows with an empty label load as label "", the folder
    can be indexed, searched and grouped (groups named by the labels there are, else by a
    picture), and `storybeam eval` refuses it naming the row."""
    from app.cli import main
    from retrieval.library import MotionIndex, load_dataset, read_labels
    from retrieval.library.grouping import group_folder

    folder = tmp_path / "import"
    folder.mkdir()
    lines = (library / "labels.csv").read_text().splitlines()
    out = [lines[0]]
    for n, line in enumerate(lines[1:]):
        trial, label, rest = line.split(",", 2)
        (folder / f"{trial}.bvh").write_bytes((library / f"{trial}.bvh").read_bytes())
        out.append(f"{trial},{label if n < 3 else ''},{rest}")  # only the first 3 clips keep a label
    (folder / "labels.csv").write_text("\n".join(out) + "\n")
    rows = read_labels(folder)
    assert [r.label for r in rows][:3] != ["", "", ""] and [r.label for r in rows][3:] == [""] * 6
    clips = load_dataset(folder, fps=30)
    assert len(clips) == 9 and sum(not c.label for c in clips) == 6
    index = MotionIndex.from_clips(clips, dims=3)
    assert index.similar_to(clips[4].trial, k=2)[0].trial != clips[4].trial
    grouping = group_folder(folder, dims=3, k=2).grouping
    assert sorted(i for g in grouping.groups for i in g.members) == list(range(9))
    for g in grouping.groups:
        member_labels = [rows[i].label for i in g.members if rows[i].label]
        if member_labels:  # named by its members' most common label
            assert g.name in member_labels
        else:  # no label among the members: a picture of the representative
            assert g.name is None and g.representative in g.trials
    assert main(["eval", "--data", str(folder), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "line 5" in err and "no label" in err
    # a row without a trial or file is still refused, naming the line
    (folder / "labels.csv").write_text(lines[0] + "\n,walk,s0,x.bvh,,x\n")
    with pytest.raises(DatasetError, match="line 2.*empty trial or file"):
        read_labels(folder)


def test_cli_reports_bad_input_as_one_line(library, capsys):
    from app.cli import main

    assert main(["eval", "--data", str(library), "--methods", "magic", "--quiet"]) == 1
    assert "magic" in capsys.readouterr().err
    assert main(["search", "--data", str(library), "--query", "/nonexistent.bvh"]) == 1


def test_stratified_subset_keeps_class_shares():
    from lab.experiment import EvaluationError, stratified_subset
    from retrieval.library import Clip

    clips = [Clip(f"t{i}", lab, np.zeros((2, 17)), None, 30.0) for i, lab in enumerate(["a"] * 60 + ["b"] * 30 + ["c"] * 10)]
    sub = stratified_subset(clips, 50, seed=3)
    labels = [c.label for c in sub]
    assert len(sub) == 50 and len({c.trial for c in sub}) == 50
    assert (labels.count("a"), labels.count("b"), labels.count("c")) == (30, 15, 5)
    with pytest.raises(EvaluationError):
        stratified_subset(clips, 101)


def test_index_from_motions_and_damaged_npz(tmp_path):
    from retrieval.library import MotionIndex

    sk = make_skeleton()
    motions = [make_motion(sk, frames=40, arm_swing=a, knee_bend=k, phase=p)
               for a, k, p in ((20, 15, 0.0), (22, 15, 1.0), (80, 40, 0.0), (78, 42, 2.0))]
    for i, m in enumerate(motions):
        m.name = f"m{i}"
    index = MotionIndex.from_motions(motions, ["slow", "slow", "big", "big"], dims=2, fps=30)
    assert index.similar_to("m2", k=1)[0].trial == "m3"
    assert index.similar_to("m0", k=1)[0].trial == "m1"
    index.save(tmp_path / "idx")
    with np.load(tmp_path / "idx" / "index.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["codes"] = arrays["codes"] + 10_000  # outside [0, 4^2)
    np.savez(tmp_path / "idx" / "index.npz", **arrays)
    with pytest.raises(IndexFormatError, match="inconsistent"):
        MotionIndex.load(tmp_path / "idx")


def test_fast_quantized_method_finds_exactly_the_seed_methods_neighbours(cmu_dir):
    """'quantized-fast' must answer every query of the protocol with the same nearest clip
    (and so the same accuracy) as the seed's full-table search — on real CMU clips, where
    near-ties make a wrong bound or a wrong table entry show."""
    from retrieval.library import load_dataset, read_labels
    from lab.experiment import evaluate, stratified_subset

    rows = read_labels(cmu_dir)
    clips = load_dataset(cmu_dir, fps=15, rows=rows)
    clips = stratified_subset(clips, 60, seed=1)
    res = evaluate(clips, ["quantized-fast", "quantized"], folds=3, dims=6)
    fast, seed = res["quantized-fast"], res["quantized"]
    assert fast.total == seed.total == 60
    assert fast.predictions == seed.predictions
    assert fast.accuracy == seed.accuracy
