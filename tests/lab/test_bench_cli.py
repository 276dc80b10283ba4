"""`storybeam bench <target>`: every target is listed and has --help; the cheap targets
run end to end on tiny inputs and write the JSON keys the docs read; bad input is a
one-line error, not a traceback."""
from __future__ import annotations

import csv
import json
import shutil

import numpy as np
import pytest
from PIL import Image

from app.cli import main
from app.commands.bench_cmd import TARGETS
from app.paths import MOTIONS_DIR

REQUIRED = ("protocol", "speedup_vs_exact_dtw", "speedup_vs_dtaidistance", "speedup_vs_seed_method",
            "query_ms_median", "query_ms_p95", "library_clips", "library_hours", "table_bytes",
            # issue 16: the honest benchmark's keys
            "vs_ucr_codes_median", "vs_ucr_codes_total", "protocol_vs_ucr_codes_median",
            "protocol_vs_ucr_codes_total", "same_answers", "big_library_clips", "big_library_ms_median",
            "big_library_ms_p95", "big_library_bytes_per_clip")
AR_CONDITION_KEYS = {"detect_rate", "rot_err_deg_median", "trans_err_mm_median", "rot_err_deg_p95", "trans_err_mm_p95",
                     "jitter_raw_deg", "jitter_filtered_deg", "jitter_raw_mm", "jitter_filtered_mm",
                     "landing_error_mm_median", "detect_pose_ms_median", "render_ms_median"}
EXPECTED_TARGETS = ("retrieval", "ar", "animation", "dtw-kernels", "motion-io", "numpy-retrieval", "fast-search-profile",
                    "pose-search", "act-it-out", "act-cameras", "find-body", "storybeam-scale", "surface")


def _json(path) -> dict:
    return json.loads(path.read_text())


@pytest.mark.slow  # a whole bench run: every method on two libraries
def test_bench_retrieval_quick_emits_the_json_keys(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("STORYBEAM_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "bench.json"
    rc = main(["bench", "retrieval", "--quick", "--fps", "30", "--json", str(out), "--quiet"])
    assert rc == 0
    res = _json(out)
    for key in REQUIRED:
        assert key in res, key
    for method in ("fast", "ucr_rival", "quantized", "dtw", "dtaidistance"):
        assert set(res["protocol"][method]) >= {"seconds", "accuracy"}
        assert res["protocol"][method]["seconds"] > 0
    # the fast search is exact: the seed's method, the rival and it answer every query alike
    assert res["same_answers"] is True
    assert res["protocol_interleaved"]["same_answers_codes"] is True
    assert res["protocol"]["fast"]["accuracy"] == res["protocol"]["quantized"]["accuracy"]
    assert res["protocol"]["ucr_rival"]["accuracy"] == res["protocol"]["quantized"]["accuracy"]
    # dtaidistance configured with the Euclidean inner distance is the project's float DTW
    assert res["protocol_interleaved"]["same_answers_float"] is True
    assert res["protocol"]["dtw"]["accuracy"] == res["protocol"]["dtaidistance"]["accuracy"]
    # per-query timings, interleaved: every method timed on every query
    for part in ("library", "big_library"):
        for m in res[part]["methods"].values():
            assert m["queries"] == res["latency_queries"] and 0 < m["ms_median"] <= m["ms_p95"]
    assert res["vs_ucr_codes_median"] > 0 and res["protocol_vs_ucr_codes_total"] > 0
    # the rival in both strategies, "the rival" being the faster (lower total) on each data set
    for part, where in (("protocol", res["protocol_interleaved"]["methods"]), ("library", res["library"]["methods"]),
                        ("big_library", res["big_library"]["methods"])):
        strategy = res["rival_strategy"][part]
        assert strategy in ("cascade", "sorted")
        totals = {s: where[f"ucr_rival_{s}"]["ms_total"] for s in ("cascade", "sorted")}
        assert where["ucr_rival"] == where[f"ucr_rival_{strategy}"] and totals[strategy] == min(totals.values())
    assert res["table_bytes"] <= 64 * 1024
    assert res["library_clips"] >= 300
    assert res["big_library_clips"] >= 3 * res["library_clips"] // 2
    sizes = [c["clips"] for c in res["latency_vs_library_size"]]
    assert sizes == sorted(set(sizes)) and sizes[0] == res["library_clips"] and sizes[-1] == res["big_library_clips"]
    assert set(res["ablations"]) >= {"diff_brute", "bounds_plain", "runs_approx", "band", "fast_parallel"}
    # ratios compare only on the same CPU: the run says which one it was
    assert res["machine"]["cpus"] >= 1 and res["machine"]["cpu_model"]
    printed = capsys.readouterr().out
    assert "paper protocol" in printed and "UCR rival" in printed and "big library" in printed


def test_bench_without_target_prints_help_listing_every_target(capsys):
    assert main(["bench"]) == 2
    printed = capsys.readouterr().out
    assert tuple(TARGETS) == EXPECTED_TARGETS
    for target in EXPECTED_TARGETS:
        assert target in printed, target


@pytest.mark.parametrize("target", EXPECTED_TARGETS)
def test_every_target_has_help_with_a_json_option(target, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", target, "--help"])
    assert exc.value.code == 0
    printed = capsys.readouterr().out
    assert f"storybeam bench {target}" in printed and "--json" in printed


def test_the_old_commands_are_gone(capsys):
    with pytest.raises(SystemExit):
        main(["ar-bench", "--help"])
    assert "invalid choice: 'ar-bench'" in capsys.readouterr().err


def test_bench_dtw_kernels_tiny(tmp_path, capsys):
    out = tmp_path / "kernels.json"
    assert main(["bench", "dtw-kernels", "--frames", "40", "--repeat", "1", "--json", str(out)]) == 0
    res = _json(out)
    assert res["frames"] == 40 and res["repeat"] == 1
    names = [k["kernel"] for k in res["kernels"]]
    assert any("split table" in n for n in names) and any("numpy" in n for n in names)
    for k in res["kernels"]:
        assert set(k) == {"kernel", "seconds", "cells", "ns_per_cell"}
        assert k["ns_per_cell"] > 0 and k["cells"] > 0
    assert "ns/cell" in capsys.readouterr().out


@pytest.fixture
def tiny_library(tmp_path):
    """Two bundled BVH clips and a labels.csv naming them."""
    folder = tmp_path / "mini"
    (folder / "bvh").mkdir(parents=True)
    with open(MOTIONS_DIR / "labels.csv", newline="") as fh:
        reader = csv.DictReader(fh)
        rows = [r for r in reader][:2]
        fields = reader.fieldnames
    for r in rows:
        shutil.copy(MOTIONS_DIR / r["file"], folder / r["file"])
    with open(folder / "labels.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fields)
        writer.writeheader()
        writer.writerows(rows)
    return folder


def test_bench_motion_io_tiny(tiny_library, tmp_path, capsys):
    out = tmp_path / "io.json"
    assert main(["bench", "motion-io", "--data", str(tiny_library), "--repeat", "2", "--json", str(out)]) == 0
    res = _json(out)
    assert res["files"] == 2 and res["repeat"] == 2 and len(res["pass_seconds"]) == 2
    assert res["frames"] > 0 and res["frames_per_second"] > 0
    assert "2 files" in capsys.readouterr().out


@pytest.mark.slow  # a bench run over the bundled library
def test_bench_numpy_retrieval_on_the_bundled_library(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("STORYBEAM_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "numpy.json"
    assert main(["bench", "numpy-retrieval", str(MOTIONS_DIR), "30", "--quiet", "--json", str(out)]) == 0
    res = _json(out)
    assert set(res["methods"]) == {"fast_numpy", "fast_numpy_no_range", "quantized"}
    # all three are exact: the same answers, so the same accuracy
    assert len({m["accuracy"] for m in res["methods"].values()}) == 1
    assert res["speedup_vs_seed_method"] > 0 and res["clips"] >= 3
    assert "speed-up" in capsys.readouterr().out


@pytest.mark.slow  # a bench run: profiles the search's variants (a minute of numba compiling on a fresh cache)
def test_bench_fast_search_profile_on_the_bundled_library(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("STORYBEAM_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "profile.json"
    assert main(["bench", "fast-search-profile", "30", "--data", str(MOTIONS_DIR), "--quiet", "--json", str(out)]) == 0
    res = _json(out)
    assert res["compare"]["identical_answers"] is True
    assert set(res["stages_seconds"]) == {"pack", "rows", "bounds", "loop"}
    assert all(v >= 0 for v in res["stages_seconds"].values())
    variants = res["compare"]["variants"]
    assert len(variants) == 2 and all(v["stats"]["candidates"] > 0 for v in variants.values())
    assert "stages of the default search" in capsys.readouterr().out


@pytest.mark.slow  # a bench run: AR frames
def test_bench_ar_few_frames(tmp_path, capsys):
    out = tmp_path / "ar.json"
    rc = main(["bench", "ar", "--frames", "3", "--conditions", "clean,occlusion_30", "--true-calibration",
               "--json", str(out), "--examples", str(tmp_path / "img"), "--renderers", "none"])
    assert rc == 0
    result = _json(out)
    assert set(result["conditions"]) == {"clean", "occlusion_30"}
    for cond in result["conditions"].values():
        assert AR_CONDITION_KEYS <= set(cond)
    assert result["conditions"]["clean"]["detect_rate"] == 1.0
    assert result["conditions"]["clean"]["rot_err_deg_median"] < 0.2
    for key in ("landing_error_mm_median", "detect_pose_ms_median", "render_ms_median"):
        assert result[key] > 0
    assert "| clean |" in capsys.readouterr().out
    with Image.open(tmp_path / "img" / "ar_clean_projector_view.png") as im:
        lit = np.asarray(im.convert("L")) > 20
    assert 0.01 < lit.mean() < 0.5  # the test scene is drawn, on black
    assert (tmp_path / "img" / "ar_occlusion_30_camera_axes.png").is_file()


@pytest.mark.slow  # a bench run: AR frames per renderer
def test_bench_ar_frame_timing_per_renderer(tmp_path, capsys):
    """Camera frame -> projector frame per renderer (issue 13): each renderer in its own
    process, the keys the issue names, the accuracy of the fast path, a lit projector frame."""
    out = tmp_path / "frame.json"
    rc = main(["bench", "ar", "--frame-only", "--frames", "4", "--conditions", "clean",
               "--renderers", "kivy-gl,pyrender", "--json", str(out)])
    assert rc == 0
    clean = _json(out)["conditions"]["clean"]
    assert set(clean["renderers"]) == {"kivy-gl", "pyrender"}
    for name, r in clean["renderers"].items():
        assert "error" not in r, (name, r)
        for key in ("detect_pose_ms_median", "render_ms_median", "frame_ms_median", "frame_ms_p95"):
            assert r[key] > 0 and r["cpu"][key] > 0
        assert r["frame_ms_p95"] >= r["frame_ms_median"] >= r["render_ms_median"]
        assert r["detect_rate"] == 1.0 and r["rot_err_deg_median"] < 0.2 and r["trans_err_mm_median"] < 1.0
        assert r["before_detect_pose_ms_median"] > 0 and r["search_paths"]["region"] == 3
        assert r["lit_fraction_median"] > 0.001  # the robot's light is in the frame
    assert "| clean | pyrender |" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["ar", "--frames", "3", "--conditions", "fog"], "unknown condition(s) fog"),
    (["ar", "--frames", "3", "--renderers", "vulkan"], "unknown renderer(s) vulkan"),
    (["ar", "--frames", "3", "--board", "checker:9x6"], "expected 3"),
    (["animation", "--characters", "dragon"], "unknown character(s) dragon"),
    (["motion-io", "--data", "{tmp}/nope"], "labels.csv not found"),
    (["numpy-retrieval", "{tmp}/nope"], "has no labels.csv"),
    (["storybeam-scale", "--data", "{tmp}"], "no labels.csv"),
    (["storybeam-scale", "--data", "{tmp}", "--hours", "-1"], "--hours -1: must be 0 or more"),
])
def test_bad_input_is_a_one_line_error(argv, message, tmp_path, capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(["bench", *argv]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.parametrize("argv", [["dtw-kernels", "--frames", "1"], ["motion-io", "--repeat", "0"],
                                  ["ar", "--frames", "x"], ["numpy-retrieval", ".", "-3"]])
def test_bad_numbers_are_usage_errors(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", *argv])
    assert exc.value.code == 2
    assert "error: argument" in capsys.readouterr().err


def test_bench_storybeam_scale_on_the_bundled_library(tmp_path, capsys):
    out = tmp_path / "sbs.json"
    rc = main(["bench", "storybeam-scale", "--data", str(MOTIONS_DIR), "--clips", "40", "--hours", "0.02",
               "--baseline", "2", "--quiet", "--json", str(out)])
    assert rc == 0
    res = _json(out)
    assert res["library"]["clips"] >= 40 and res["library"]["hours"] >= 0.02
    assert res["queries"] >= 6 and 0 < res["search_ms"]["median"] <= res["search_ms"]["p95"]
    assert res["baseline"]["queries"] == 2 and 0 <= res["baseline"]["same_nearest_clip"] <= 2
    assert "1-NN search" in capsys.readouterr().out


def test_storybeam_scale_with_the_whole_library_shortlisted_is_exact_dtw():
    from lab.bench.storybeam_scale import run_storybeam_scale_bench

    res = run_storybeam_scale_bench(MOTIONS_DIR, min_clips=25, min_hours=0.0, baseline_queries=4,
                                    shortlist=10_000, progress=False)
    assert res["baseline"]["same_nearest_clip"] == 4  # re-ranking every clip is exact DTW's 1-NN

