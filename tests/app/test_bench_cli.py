"""`storybeam bench retrieval --quick` runs end to end on the bundled library and writes
the JSON keys the docs and CI read."""
from __future__ import annotations

import json

from app.cli import main

REQUIRED = ("protocol", "speedup_vs_exact_dtw", "speedup_vs_dtaidistance", "speedup_vs_seed_method",
            "query_ms_median", "query_ms_p95", "library_clips", "library_hours", "table_bytes")


def test_bench_retrieval_quick_emits_the_json_keys(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("STORYBEAM_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "bench.json"
    rc = main(["bench", "retrieval", "--quick", "--fps", "30", "--json", str(out), "--quiet"])
    assert rc == 0
    res = json.loads(out.read_text())
    for key in REQUIRED:
        assert key in res, key
    for method in ("fast", "quantized", "dtw", "dtaidistance"):
        assert set(res["protocol"][method]) >= {"seconds", "accuracy"}
        assert res["protocol"][method]["seconds"] > 0
    # the fast search is exact: the seed's method and it answer every query alike
    assert res["protocol"]["fast"]["accuracy"] == res["protocol"]["quantized"]["accuracy"]
    assert res["table_bytes"] <= 64 * 1024
    assert res["library_clips"] >= 300
    assert set(res["ablations"]) >= {"diff_brute", "bounds_plain", "runs_approx", "band", "fast_parallel"}
    printed = capsys.readouterr().out
    assert "paper protocol" in printed and "speed-up" in printed


def test_bench_without_target_prints_help(capsys):
    assert main(["bench"]) == 2
    assert "retrieval" in capsys.readouterr().out
