"""The real-footage development set of Act it out (issue 27): its manifest
(lab/datasets/act_real_manifest.csv) and the script that materialises it (scripts/act_real.py).

* the committed manifest is a usable set: >= 30 clips, >= 5 per class, windows of 1.5-8 s,
  a view and a licence on every row, and none of the repositories the issue reserves for
  its acceptance check;
* the script cuts exactly the frames of each window out of a repository snapshot, writes
  labels.csv, skips (and says so) a repository that is not there, and ``--only`` adds to a
  materialised set instead of replacing it;
* malformed manifest rows are refused with the file and line.

Built on a throw-away git repository holding a generated video whose frames carry their
index, so no network and no fetched footage is needed.
"""
from __future__ import annotations

import csv
import importlib.util
import subprocess
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
RESERVED = {"AssemblyAI-Community/mediapipe-python", "jacky1107/Pose-Estimation", "Furkan-Gulsen/Sport-With-AI",
            "AlejandraSoto2709/Walking-Gait", "lilskyex0x/HumanActivityRecognitionSystem",
            "omartarek198/Pose-estimation-using-dollarpy", "prashant-1285/action_recognition",
            "AnanthaKannan/ai-media-pipe", "purpleladydragons/Radar-Gun", "buptjiwei/demo_dancer",
            "fiyud/Multi-Person-Mediapipe", "gillhung/real_virtual_dancing"}


def _script():
    spec = importlib.util.spec_from_file_location("act_real", REPO / "scripts" / "act_real.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


act_real = _script()


def test_the_committed_manifest_is_a_usable_development_set():
    rows = act_real.read_manifest(act_real.MANIFEST)
    counts = Counter(r["label"] for r in rows)
    assert len(rows) >= 30 and all(counts[c] >= 5 for c in act_real.LABELS), counts
    assert counts["jump"] == max(counts.values())  # the first class: the most clips
    for r in rows:
        span = float(r["end_s"]) - float(r["start_s"])
        assert 1.5 <= span <= 8.0, (r["clip"], span)
        assert r["view"] and r["licence"] and r["notes"] and len(r["commit"]) == 40, r["clip"]
        owner_name = r["repository"].lower()
        assert owner_name not in {x.lower() for x in RESERVED}, f"{r['clip']}: {r['repository']} is reserved"
        # nor a repository of the same name (a fork or a copy of one, whatever its owner)
        assert not any(owner_name.split("/")[1] == x.lower().split("/")[1] for x in RESERVED), r["repository"]


def _git(cwd: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(cwd), *args], check=True, capture_output=True, text=True).stdout.strip()


@pytest.fixture()
def mirror(tmp_path) -> tuple[Path, str]:
    """A snapshot folder holding ``someone/clips`` with one 3 s, 10 fps video whose frame
    ``i`` is uniformly grey level ``8 i``."""
    import cv2

    repo = tmp_path / "mirror" / "someone+clips" / "repo"
    repo.mkdir(parents=True)
    _git(repo, "init", "-q")
    video = repo / "videos" / "hop.mp4"
    video.parent.mkdir()
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (64, 48))
    for i in range(30):
        w.write(np.full((48, 64, 3), 8 * i, np.uint8))
    w.release()
    _git(repo, "add", "-A")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "clip")
    return tmp_path / "mirror", _git(repo, "rev-parse", "HEAD")


def _manifest(path: Path, commit: str, rows: list[tuple[str, str, str, float, float]]) -> Path:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(act_real.COLUMNS)
        for clip, label, repo, start, end in rows:
            w.writerow([clip, label, repo, commit, "videos/hop.mp4", start, end, "facing", "MIT", "test"])
    return path


def _greys(path: Path) -> list[float]:
    import cv2

    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, frame = cap.read()
        if not ok:
            return out
        out.append(float(frame.mean()))


def test_materialise_cuts_the_window_and_writes_labels(mirror, tmp_path, capsys):
    root, commit = mirror
    man = _manifest(tmp_path / "m.csv", commit, [("hop1", "jump", "someone/clips", 0.5, 1.2),
                                                 ("gone1", "walk", "nobody/missing", 0.0, 1.0)])
    out = tmp_path / "set"
    assert act_real.main(["--out", str(out), "--mirror", str(root), "--manifest", str(man)]) == 1  # one skipped
    text = capsys.readouterr().out
    assert "gone1: skipped" in text and "fetch github:nobody/missing" in text
    greys = _greys(out / "hop1.mp4")
    assert len(greys) == 7  # frames 5..11 of 10 fps: [0.5 s, 1.2 s)
    source = _greys(root / "someone+clips" / "repo" / "videos" / "hop.mp4")
    assert np.allclose(greys, source[5:12], atol=3)  # the same frames, re-encoded once more
    assert (out / "labels.csv").read_text().splitlines() == ["file,label", "hop1.mp4,jump"]
    with open(out / "manifest.csv") as f:
        row = next(csv.DictReader(f))
    assert row["frames"] == "7" and row["width"] == "64" and float(row["fps"]) == 10.0


def test_only_adds_to_the_materialised_set(mirror, tmp_path):
    root, commit = mirror
    man = _manifest(tmp_path / "m.csv", commit, [("a", "jump", "someone/clips", 0.0, 1.0),
                                                 ("b", "run", "someone/clips", 1.0, 2.0)])
    out = tmp_path / "set"
    assert act_real.main(["--out", str(out), "--mirror", str(root), "--manifest", str(man), "--only", "a"]) == 0
    assert act_real.main(["--out", str(out), "--mirror", str(root), "--manifest", str(man), "--only", "b"]) == 0
    assert (out / "labels.csv").read_text().splitlines() == ["file,label", "a.mp4,jump", "b.mp4,run"]


@pytest.mark.parametrize("row, message", [
    ("x,fly,o/r,c,p,0,1,v,l,n", "label 'fly'"),
    ("x,jump,o/r,c,p,2,1,v,l,n", "window 2.0-1.0 s is empty"),
    ("x,jump,o/r,c,p,a,1,v,l,n", "must be numbers"),
])
def test_bad_rows_name_the_file_and_line(row, message, tmp_path):
    path = tmp_path / "m.csv"
    path.write_text(",".join(act_real.COLUMNS) + "\n" + row + "\n")
    with pytest.raises(act_real.ManifestError, match=rf"m.csv:2: .*{message}"):
        act_real.read_manifest(path)
    path.write_text("clip,label\n")
    with pytest.raises(act_real.ManifestError, match="m.csv:1: missing column"):
        act_real.read_manifest(path)


def test_repeated_clip_names_are_refused(tmp_path):
    path = tmp_path / "m.csv"
    row = "x,jump,o/r,c,p,0,1,v,l,n"
    path.write_text(",".join(act_real.COLUMNS) + f"\n{row}\n{row}\n")
    with pytest.raises(act_real.ManifestError, match="m.csv:3: clip name 'x'"):
        act_real.read_manifest(path)
