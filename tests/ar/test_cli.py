"""The AR commands: board and calibrate (the AR bench is `storybeam bench ar`, tested in
tests/lab/test_bench_cli.py)."""
from __future__ import annotations

from app.cli import main


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
