"""The AR commands: board, calibrate, ar-bench (JSON keys on a few frames)."""
from __future__ import annotations

import json
import os

import numpy as np

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from app.cli import main  # noqa: E402

CONDITION_KEYS = {"detect_rate", "rot_err_deg_median", "trans_err_mm_median", "rot_err_deg_p95", "trans_err_mm_p95",
                  "jitter_raw_deg", "jitter_filtered_deg", "jitter_raw_mm", "jitter_filtered_mm",
                  "landing_error_mm_median", "detect_pose_ms_median", "render_ms_median"}


def test_ar_bench_json(tmp_path, capsys):
    out = tmp_path / "bench.json"
    rc = main(["ar-bench", "--frames", "4", "--conditions", "clean,occlusion_30", "--true-calibration",
               "--json", str(out), "--examples", str(tmp_path / "img")])
    assert rc == 0
    result = json.loads(out.read_text())
    assert set(result["conditions"]) == {"clean", "occlusion_30"}
    for cond in result["conditions"].values():
        assert CONDITION_KEYS <= set(cond)
    assert result["conditions"]["clean"]["detect_rate"] == 1.0
    assert result["conditions"]["clean"]["rot_err_deg_median"] < 0.2
    for key in ("landing_error_mm_median", "detect_pose_ms_median", "render_ms_median"):
        assert result[key] > 0
    assert "| clean |" in capsys.readouterr().out
    from PIL import Image

    with Image.open(tmp_path / "img" / "ar_clean_projector_view.png") as im:
        lit = np.asarray(im.convert("L")) > 20
    assert 0.01 < lit.mean() < 0.5  # the test scene is drawn, on black
    assert (tmp_path / "img" / "ar_occlusion_30_camera_axes.png").is_file()


def test_ar_bench_unknown_condition_is_one_line_error(capsys):
    assert main(["ar-bench", "--frames", "3", "--conditions", "fog"]) == 1
    err = capsys.readouterr().err
    assert "unknown condition(s) fog" in err and "Traceback" not in err


def test_board_command(tmp_path, capsys):
    assert main(["board", "--board", "checker:9x6:0.025", "--out", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").stat().st_size > 1000
    assert "300 x 225 mm" in capsys.readouterr().out
    assert main(["board", "--board", "checker:9x6", "--out", str(tmp_path / "x.png")]) == 1
    assert "expected 3" in capsys.readouterr().err


def test_calibrate_camera_errors_name_the_problem(tmp_path, capsys):
    assert main(["calibrate", "camera", "--images", str(tmp_path / "nope"), "--out", str(tmp_path / "c.json")]) == 1
    assert "image folder not found" in capsys.readouterr().err
    (tmp_path / "empty").mkdir()
    assert main(["calibrate", "camera", "--images", str(tmp_path / "empty"), "--out", str(tmp_path / "c.json")]) == 1
    assert "no images" in capsys.readouterr().err


def test_calibrate_projector_needs_inputs(tmp_path, capsys):
    assert main(["calibrate", "projector", "--out", str(tmp_path / "p.json")]) == 1
    assert "--images and --camera are required" in capsys.readouterr().err
    assert main(["calibrate", "projector", "--show-steps"]) == 0
    assert "Step 8/8" in capsys.readouterr().out
