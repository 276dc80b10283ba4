"""The `storybeam` command line: every command module is listed, a broken one is a clear
error (not a silently missing command), and the cheap commands run end to end --
`export` (a tiny story to MP4), `build-library` (a tiny labelled folder), `stress`'s
atheris harness when atheris is absent."""
from __future__ import annotations

import argparse
import csv
import json
import os
import re

import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import app.commands  # noqa: E402
from app.cli import build_parser, command_modules, main  # noqa: E402
from app.commands import export_cmd, stress_cmd  # noqa: E402
from lab.stress import atheris_fuzz  # noqa: E402
from app.story import Character, MotionChoice, Scene, Story  # noqa: E402
from retrieval.library.bundle import LABEL_COLUMNS, SELECTION  # noqa: E402
from retrieval.motion import load_motion  # noqa: E402
from tests.support.synthetic_motion import make_motion, make_skeleton, write_bvh  # noqa: E402


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


# ----------------------------------------------------------------------------- the command list


def test_help_lists_every_command_module(capsys):
    modules = command_modules()
    assert "app.commands.build_library_cmd" in modules and "app.commands.export_cmd" in modules
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    help_text = capsys.readouterr().out
    listed = set(_subcommands(build_parser()))
    for name in modules:  # each module registers its command, and --help shows it
        command = name.rsplit(".", 1)[1][: -len("_cmd")].replace("_", "-")
        assert command in listed, f"{name} registered no command {command!r}"
        assert re.search(rf"^\s+{re.escape(command)}\s", help_text, re.M), f"{command} missing from --help"
    assert len(listed) == len(modules)


def test_a_command_module_that_fails_to_import_is_an_error_naming_it(tmp_path, monkeypatch, capsys):
    (tmp_path / "broken_cmd.py").write_text('raise RuntimeError("boom at import")\n')
    monkeypatch.setattr(app.commands, "__path__", [*app.commands.__path__, str(tmp_path)])
    assert "app.commands.broken_cmd" in command_modules()
    assert main(["board", "--help"]) == 1
    err = capsys.readouterr().err
    assert "app.commands.broken_cmd" in err and "RuntimeError: boom at import" in err


def test_a_command_module_without_register_is_an_error_naming_it(tmp_path, monkeypatch, capsys):
    (tmp_path / "empty_cmd.py").write_text('"""A command module that forgot register()."""\n')
    monkeypatch.setattr(app.commands, "__path__", [*app.commands.__path__, str(tmp_path)])
    assert main(["board", "--help"]) == 1
    err = capsys.readouterr().err
    assert "app.commands.empty_cmd" in err and "register" in err


# ----------------------------------------------------------------------------- export


def test_export_views_match_the_scene_layer():
    from app.player.video_export import VIEWS

    assert export_cmd.VIEWS == VIEWS


def _tiny_story() -> Story:
    path = [(0.2, 0.3, 0.0), (0.6, 0.4, 1.0), (1.0, 0.5, 2.0)]
    return Story(title="tiny", arc="free", scenes=[
        Scene(id="s1", background="grass", characters=[Character(id="c1", kind="robot", path=path,
                                                                 motion=MotionChoice("walk"))])])


def test_export_writes_an_mp4_and_a_result_line(tmp_path, capsys):
    from app.player import available, frame_count

    if available():
        pytest.skip(f"no MP4 export here: {available()}")
    story = _tiny_story()
    src, out = tmp_path / "story.json", tmp_path / "video" / "story.mp4"
    src.write_text(json.dumps(story.to_dict()), encoding="utf-8")
    assert main(["export", str(src), str(out), "--view", "2d", "--fps", "5", "--progress-lines"]) == 0
    lines = capsys.readouterr().out.splitlines()
    expected_frames = frame_count(story, 5)
    assert lines[-1].startswith("result ")
    result = json.loads(lines[-1][len("result "):])
    assert result == {"path": str(out), "mode": "2d", "frames": expected_frames, "note": ""}
    assert f"progress {expected_frames} {expected_frames}" in lines
    assert out.is_file() and out.read_bytes()[4:8] == b"ftyp"  # an MP4 container
    assert not list(out.parent.glob(".*tmp*")), "the temporary file was left behind"


@pytest.mark.parametrize("content", ['{"title": "no scenes"}', "[1, 2, 3]", "not json at all"])
def test_export_of_a_non_story_file_names_the_file(tmp_path, capsys, content):
    src = tmp_path / "notes.json"
    src.write_text(content, encoding="utf-8")
    assert main(["export", str(src), str(tmp_path / "out.mp4"), "--view", "2d"]) == 1
    err = capsys.readouterr().err
    assert str(src) in err and "Traceback" not in err
    assert not (tmp_path / "out.mp4").exists()


# ----------------------------------------------------------------------------- build-library


def _tiny_cmu_folder(folder, frames: int = 45) -> None:
    """A labelled folder in the shared CMU layout listing every trial of SELECTION, each a
    short synthetic BVH (1.5 s at 30 fps)."""
    (folder / "bvh").mkdir(parents=True)
    skeleton = make_skeleton()
    with open(folder / "labels.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=LABEL_COLUMNS)
        writer.writeheader()
        for k, (label, trials) in enumerate(SELECTION.items()):
            motion = make_motion(skeleton, frames=frames, fps=30.0, arm_swing=10.0 + 15 * k, knee_bend=10.0 + 5 * k)
            write_bvh(motion, folder / "bvh" / f"{label}.bvh")
            for trial in trials:
                writer.writerow({"trial": trial, "label": label, "subject": trial.split("_")[0],
                                 "file": f"bvh/{label}.bvh", "skeleton": "", "seconds": f"{frames / 30:.2f}",
                                 "description": f"synthetic {label}", "source": "tests"})


def test_build_library_on_a_tiny_labelled_folder(tmp_path, capsys):
    data, out = tmp_path / "cmu", tmp_path / "library"
    _tiny_cmu_folder(data)
    rc = main(["build-library", "--data", str(data), "--out", str(out), "--fps", "15", "--max-seconds", "1",
               "--quiet"])
    assert rc == 0
    n = sum(len(t) for t in SELECTION.values())
    assert f"wrote {n} clips" in capsys.readouterr().out
    with open(out / "labels.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["trial"] for r in rows] == [t for trials in SELECTION.values() for t in trials]
    assert "storybeam build-library" in (out / "CREDITS.md").read_text(encoding="utf-8")
    clip = load_motion(out / rows[0]["file"])
    assert clip.fps == pytest.approx(15.0)
    assert clip.n_frames == 15  # cut to --max-seconds 1 at --fps 15
    assert float(rows[0]["seconds"]) == pytest.approx(1.0)


@pytest.mark.parametrize("problem", ["missing", "no-labels", "out-is-data", "bad-fps", "bad-decimals"])
def test_build_library_refuses_bad_input_plainly(tmp_path, capsys, problem):
    data = tmp_path / "cmu"
    if problem != "missing":
        data.mkdir()
    if problem not in ("missing", "no-labels"):
        (data / "labels.csv").write_text(",".join(LABEL_COLUMNS) + "\n")
    argv = ["build-library", "--data", str(data), "--out", str(data if problem == "out-is-data" else tmp_path / "o")]
    argv += {"bad-fps": ["--fps", "0"], "bad-decimals": ["--decimals", "40"]}.get(problem, [])
    assert main(argv + ["--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("storybeam build-library: error: ") and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_build_library_reports_trials_missing_from_the_labels(tmp_path, capsys):
    data = tmp_path / "cmu"
    data.mkdir()
    (data / "labels.csv").write_text(",".join(LABEL_COLUMNS) + "\n02_01,walk,02,bvh/x.bvh,,1,walk,t\n")
    assert main(["build-library", "--data", str(data), "--out", str(tmp_path / "o"), "--quiet"]) == 1
    assert "trials not listed" in capsys.readouterr().err


# ----------------------------------------------------------------------------- stress


def test_atheris_is_not_a_default_harness():
    assert "atheris" not in stress_cmd.HARNESSES
    args = _subcommands(build_parser())["stress"].parse_args([])
    assert "atheris" not in stress_cmd.selected(args.only)


def test_stress_atheris_without_atheris_says_how_to_install_it(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(atheris_fuzz, "atheris_available", lambda: False)
    assert main(["stress", "--only", "atheris", "--work-dir", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "pip install atheris" in err and "Traceback" not in err


def test_stress_rejects_an_unknown_harness(capsys):
    assert main(["stress", "--only", "fuzz,bogus"]) == 1
    assert "bogus" in capsys.readouterr().err


def test_atheris_summary_counts_libfuzzer_stats_and_artifacts(tmp_path):
    output = ("Done 1200 runs in 3 second(s)\nstat::number_of_executed_units: 1200\n"
              "stat::new_units_added:          7\nstat::peak_rss_mb:              97\n")
    clean = atheris_fuzz.summarize(tmp_path, output, 0)
    assert (clean["inputs"], clean["crashes"], clean["hangs"], clean["failures"]) == (1200, 0, 0, 0)
    assert clean["peak_rss_mb"] == 97
    (tmp_path / "crash-0a1b").write_bytes(b"x")
    (tmp_path / "timeout-2c3d").write_bytes(b"y")
    (tmp_path / "seed0").write_bytes(b"not an artifact")
    found = atheris_fuzz.summarize(tmp_path, output, 1)
    assert (found["crashes"], found["hangs"], found["failures"]) == (1, 1, 2)
    assert sorted(found["artifacts"]) == [str(tmp_path / "crash-0a1b"), str(tmp_path / "timeout-2c3d")]
    # a child that died without leaving an input is still a failure, with its output
    died = atheris_fuzz.summarize(tmp_path / "empty", "Traceback: ImportError", 1)
    assert died["failures"] == 1 and "ImportError" in died["error"]


@pytest.mark.skipif(not atheris_fuzz.atheris_available(), reason="atheris is not installed (pip install atheris)")
def test_stress_atheris_runs_a_short_campaign(tmp_path, capsys):
    out = tmp_path / "summary.json"
    assert main(["stress", "--only", "atheris", "--fuzz-inputs", "200", "--seconds", "60",
                 "--work-dir", str(tmp_path / "work"), "--json", str(out)]) == 0
    detail = json.loads(out.read_text())["detail"]["atheris"]
    assert detail["inputs"] >= 200 and detail["crashes"] == 0 and detail["hangs"] == 0
