"""`storybeam bench act-it-out` in a small fast configuration: two short takes per
variant rendered, tracked by ar.body and searched; the JSON has every key the docs read,
with sane values, the landmark cache is reused on a second run (same answers, no
rendering), and bad arguments are one-line errors. The trial drawing is stratified and
repeatable. Needs the shared CMU data and a TFLite interpreter (skips otherwise)."""
from __future__ import annotations

import json
from collections import Counter

import pytest

from app.cli import main

VARIANT_KEYS = {"variant", "figure", "turn_deg", "clutter", "takes", "frames", "detect_rate", "accuracy_trial_out",
                "accuracy_subject_out", "ceiling_trial_out", "ceiling_subject_out", "recall", "ceiling_recall",
                "pose_ms_median", "search_ms", "per_take"}


def test_choose_trials_is_stratified_and_repeatable(cmu_dir):
    from lab.bench.act_it_out import CLASS_SHARE, choose_trials
    from retrieval.library import read_labels

    rows = read_labels(cmu_dir)
    a = choose_trials(rows, 60, seed=2)
    assert [r.trial for r in a] == [r.trial for r in choose_trials(rows, 60, seed=2)]
    assert [r.trial for r in a] != [r.trial for r in choose_trials(rows, 60, seed=1)]
    assert len(a) == 60 and len({r.trial for r in a}) == 60
    counts = Counter(r.label for r in a)
    assert set(counts) == set(CLASS_SHARE) and counts["kick"] == 9
    assert len(choose_trials(rows, 5, seed=0)) == 5


@pytest.fixture()
def runtime():
    from ar.body import pose_runtime_available

    if not pose_runtime_available():
        pytest.skip("no TFLite interpreter (ai-edge-litert) installed")


def test_tiny_run_writes_every_key_and_reuses_the_cache(cmu_dir, runtime, tmp_path, capsys):
    out, cache = tmp_path / "act.json", tmp_path / "cache"
    args = ["bench", "act-it-out", "--data", str(cmu_dir), "--limit", "2", "--seed", "5", "--seconds", "0.5",
            "--variants", "person,person-clutter", "--extra-limit", "1", "--cache", str(cache), "--json", str(out), "--quiet"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "| person |" in printed and "| person-clutter |" in printed
    res = json.loads(out.read_text())
    assert res["seed"] == 5 and res["limit"] == 2 and res["extra_limit"] == 1 and res["image_size"] == [640, 480]
    assert 100 < res["library_clips"] < res["library_windows"]  # long clips are indexed as several windows
    assert [v["variant"] for v in res["variants"]] == ["person", "person-clutter"]
    for v, takes in zip(res["variants"], (2, 1)):
        assert set(v) == VARIANT_KEYS
        assert v["takes"] == takes and v["frames"] == takes * 15
        assert 0.0 <= v["detect_rate"] <= 1.0 and v["detect_rate"] > 0.5  # the figure is seen
        for key in ("accuracy_trial_out", "accuracy_subject_out", "ceiling_trial_out", "ceiling_subject_out"):
            assert v[key] in (0.0, 0.5, 1.0)
        assert v["accuracy_trial_out"] <= 1.0 and len(v["per_take"]) == takes
        assert v["pose_ms_median"] > 0 and v["search_ms"] > 0
        assert {t["label"] for t in v["per_take"]} == set(v["recall"])
    assert len(list(cache.glob("*.npz"))) == 3
    first = [[t["predicted"] for t in v["per_take"]] for v in res["variants"]]
    # second run: landmarks from the cache, same answers
    mtimes = {p: p.stat().st_mtime_ns for p in cache.glob("*.npz")}
    assert main(args) == 0
    again = json.loads(out.read_text())
    assert [[t["predicted"] for t in v["per_take"]] for v in again["variants"]] == first
    assert {p: p.stat().st_mtime_ns for p in cache.glob("*.npz")} == mtimes


@pytest.mark.parametrize("bad, message", [
    (["--variants", "robot"], "unknown variant"),
    (["--data", "/nonexistent"], "no labels.csv"),
])
def test_bad_arguments_are_one_line_errors(bad, message, cmu_dir, tmp_path, capsys):
    args = ["bench", "act-it-out", "--data", str(cmu_dir), "--cache", str(tmp_path), "--quiet", *bad]
    rc = main(args)
    err = capsys.readouterr().err
    assert rc != 0 and message in err and "Traceback" not in err
