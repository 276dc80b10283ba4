"""`storybeam bench find-body` in a tiny configuration: every scene a few frames long, both
modes; the JSON has the keys docs/notebook/pose.md reads, the extra pass finds the small
person the whole-frame detector misses, a folder without labels.csv is a one-line error.
The scenes' truth itself (the pasted performers' landmarks) is checked here too."""
from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from ar.body import pose_runtime_available
from lab.bench import find_body

needs_runtime = pytest.mark.skipif(not pose_runtime_available(),
                                   reason="no TFLite interpreter: pip install ai-edge-litert (desktop)")


def test_scene_truth_follows_the_pasted_performer():
    frames = list(find_body.scene("edge-small", 3))
    f = frames[0]
    assert f.image.shape == (1080, 1920, 3) and f.target == 0
    xy = f.truths[0]
    assert np.ptp(xy[:, 1]) == pytest.approx(180 * 0.85, rel=0.15)  # landmarks span most of 1/6 of the height
    inside = xy.round().astype(int)
    assert (np.abs(f.image[inside[:, 1], inside[:, 0]].astype(int) - find_body.WALL_BGR).max(axis=1) > 12).mean() > 0.6
    assert list(find_body.scene("empty", 2))[0].target is None
    with pytest.raises(find_body.StoryBeamError, match="unknown scene"):
        next(find_body.scene("nowhere"))


@needs_runtime
@pytest.mark.slow
def test_bench_find_body_tiny(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(find_body, "_pin_one_core", lambda: None)  # leave the test process's cores alone
    out = tmp_path / "fb.json"
    assert main(["bench", "find-body", "--frames", "4", "--quiet", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "| edge-small | with |" in printed and "acquisition" in printed
    result = json.loads(out.read_text())
    assert result["tiles"] == 11 and result["tiles_per_frame"] == 4
    assert set(result["scenes"]) == set(find_body.SCENES)
    for modes in result["scenes"].values():
        assert set(modes) == {"with", "without"}
        for r in modes.values():
            assert {"found", "on_target", "wrong_frames", "pose_ms_median", "tracked_ms_median", "detect_frames",
                    "detect_ms_median", "tile_runs"} <= set(r)
    edge = result["scenes"]["edge-small"]
    assert edge["with"]["found"] == 1.0 and edge["without"]["found"] == 0.0
    assert edge["without"]["tile_runs"] == 0 and edge["with"]["tile_runs"] >= 1
    assert result["acquisition"]["edge-small"]["with"]["found"] == 1.0
    assert result["acquisition"]["centre"]["without"]["found"] == 1.0


def test_videos_without_labels_is_a_one_line_error(tmp_path, capsys):
    if not pose_runtime_available():
        pytest.skip("no TFLite interpreter")
    assert main(["bench", "find-body", "--frames", "4", "--quiet", "--videos", str(tmp_path)]) != 0
    assert "labels.csv" in capsys.readouterr().err
