"""Third-party conversions of CMU trials (issue 31): the manifest
(lab/datasets/cmu_third_manifest.csv) and the script that materialises it (scripts/cmu_third.py).

* the committed manifest names real trials of the shared library, a 40-digit commit, a
  converter, a skeleton and a licence on every row, and none of the sets the issue reserves
  for its acceptance check;
* the script writes each row's file from its own commit (two versions of one path land in
  two sources, byte for byte), skips (and says so) a repository that is not there;
* malformed rows are refused with the file and line.

Built on a throw-away git repository, so no network and no fetched data is needed.
"""
from __future__ import annotations

import csv
import runpy
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

REPO = Path(__file__).resolve().parents[2]
RESERVED_REPOS = {"dragonforgedtheartist/iclone-cmu-mocap"}
RESERVED_WORDS = ("bandai-namco-research-motiondataset", "iclone-cmu-mocap")


#: the script's globals (it is not a package module): read_manifest, main, COLUMNS, ...
cmu_third = SimpleNamespace(**runpy.run_path(str(REPO / "scripts" / "cmu_third.py"), run_name="cmu_third"))


def test_the_committed_manifest_names_library_trials_and_no_reserved_set():
    rows = cmu_third.read_manifest(cmu_third.MANIFEST)
    assert len({r["source"] for r in rows}) >= 2  # at least two other skeletons
    for r in rows:
        assert r["repository"].lower() not in RESERVED_REPOS
        assert not any(w in (r["repository"] + r["path"]).lower() for w in RESERVED_WORDS), r
    labels = REPO.parent / "shared" / "data" / "cmu" / "labels.csv"
    if labels.is_file():
        with open(labels, newline="", encoding="utf-8") as f:
            trials = {row["trial"] for row in csv.DictReader(f)}
        assert {r["trial"] for r in rows} <= trials


def _git(cwd: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(cwd), *args], check=True, capture_output=True, text=True).stdout.strip()


def _manifest(path: Path, rows: list[dict[str, str]]) -> Path:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=cmu_third.COLUMNS)
        w.writeheader()
        w.writerows(rows)
    return path


def _row(**kw: str) -> dict[str, str]:
    base = {"source": "daz", "trial": "02_03", "repository": "someone/mocap", "commit": "0" * 40,
            "path": "Motions/02_03.bvh", "converter": "c", "skeleton": "s", "licence": "l", "notes": "n"}
    base.update(kw)
    return base


def test_each_row_is_read_from_its_own_commit_and_a_missing_repository_is_skipped(tmp_path, capsys):
    work = tmp_path / "work"
    (work / "Motions").mkdir(parents=True)
    _git(work, "init", "-q")
    _git(work, "config", "user.email", "t@example.org")
    _git(work, "config", "user.name", "t")
    versions = []
    for text in ("HIERARCHY first\n", "HIERARCHY second, merged onto another armature\n"):
        (work / "Motions" / "02_03.bvh").write_text(text)
        _git(work, "add", ".")
        _git(work, "commit", "-qm", "v")
        versions.append(_git(work, "rev-parse", "HEAD"))
    mirror = tmp_path / "mirror"
    subprocess.run(["git", "clone", "-q", "--bare", str(work), str(mirror / "someone+mocap" / "repo")], check=True)
    manifest = _manifest(tmp_path / "m.csv", [
        _row(source="daz", commit=versions[0]), _row(source="hybrid", commit=versions[1]),
        _row(source="other", repository="nobody/absent", commit=versions[0])])
    out = tmp_path / "out"
    assert cmu_third.main(["--out", str(out), "--mirror", str(mirror), "--manifest", str(manifest)]) == 1
    assert (out / "daz" / "02_03.bvh").read_text() == "HIERARCHY first\n"
    assert (out / "hybrid" / "02_03.bvh").read_text().startswith("HIERARCHY second")
    assert not (out / "other").exists()
    assert "nobody/absent" in capsys.readouterr().err
    # --sources writes only the named ones
    out2 = tmp_path / "out2"
    assert cmu_third.main(["--out", str(out2), "--mirror", str(mirror), "--manifest", str(manifest),
                           "--sources", "hybrid"]) == 0
    assert [p.name for p in out2.iterdir()] == ["hybrid"]


@pytest.mark.parametrize("row,message", [
    (_row(commit="abc"), "not 40 hex digits"),
    (_row(trial="walk1"), "not SUBJECT_TAKE"),
    (_row(licence=""), "empty column(s) licence"),
])
def test_malformed_rows_are_refused_with_file_and_line(tmp_path, row, message):
    path = _manifest(tmp_path / "m.csv", [_row(), row])
    with pytest.raises(cmu_third.ManifestError) as err:
        cmu_third.read_manifest(path)
    assert f"{path}:3:" in str(err.value) and message in str(err.value)


def test_a_repeated_row_and_a_missing_column_are_refused(tmp_path):
    with pytest.raises(cmu_third.ManifestError, match=r"m\.csv:3: daz/02_03 listed twice"):
        cmu_third.read_manifest(_manifest(tmp_path / "m.csv", [_row(), _row()]))
    bad = tmp_path / "bad.csv"
    bad.write_text("source,trial\ndaz,02_03\n")
    with pytest.raises(cmu_third.ManifestError, match=r"bad\.csv:1: missing column"):
        cmu_third.read_manifest(bad)
