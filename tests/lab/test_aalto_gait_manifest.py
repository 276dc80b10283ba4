"""The "aalto-gait" development studio of issue 31: its manifest
(lab/datasets/aalto_gait_manifest.csv) and scripts/aalto_gait.py, which materialises it.

Built on a throw-away git repository holding a tiny BVH file, so no fetched motion is needed.
"""
from __future__ import annotations

import csv
import runpy
import subprocess
from collections import Counter
from pathlib import Path
from types import SimpleNamespace

import pytest

REPO = Path(__file__).resolve().parents[2]
RESERVED = ("Bandai-Namco-Research-Motiondataset", "IClone-CMU-Mocap")


aalto = SimpleNamespace(**runpy.run_path(str(REPO / "scripts" / "aalto_gait.py")))  # the script's names

_BVH = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tEnd Site
\t{
\t\tOFFSET 0 10 0
\t}
}
MOTION
Frames: 3
Frame Time: 0.010000
0 90 0 0 0 0
0 91 0 0 0 0
0 92 0 0 0 0
"""


def test_the_committed_manifest_is_a_usable_development_set():
    rows = aalto.read_manifest(aalto.MANIFEST)
    by = Counter((r["label"], r["subject"]) for r in rows)
    assert len(rows) >= 80
    assert all(by[(c, s)] >= 5 for c in aalto.LABELS for s in ("k", "t")), by  # every class by both actors
    assert len({r["path"] for r in rows}) == len(rows)
    for r in rows:
        assert len(r["commit"]) == 40 and r["path"].endswith(".bvh") and r["style"], r["trial"]
        assert not any(x.lower() in r["repository"].lower() for x in RESERVED), r["repository"]
        # a blend mixes takes of one class by one actor only: every take with a weight carries the label
        weights = [int(w) for w in r["blend"].split()]
        takes = r["trial"].split("_")[: 3 * len(weights)]
        used = [takes[3 * i: 3 * i + 3] for i, w in enumerate(weights) if w]
        assert used and all(t[0] == r["subject"] and t[1] == r["label"] for t in used), r["trial"]


def _git(cwd: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(cwd), *args], check=True, capture_output=True, text=True).stdout.strip()


def test_materialise_writes_the_bvh_and_labels_in_the_shared_format(tmp_path):
    src = tmp_path / "src"
    (src / "Data").mkdir(parents=True)
    (src / "Data" / "k_walk_fast.bvh").write_text(_BVH)
    _git(tmp_path, "init", "-q", str(src))
    _git(src, "add", ".")
    _git(src, "-c", "user.email=t@t", "-c", "user.name=t", "commit", "-qm", "x")
    commit = _git(src, "rev-parse", "HEAD")
    mirror = tmp_path / "mirror"
    (mirror / "someone+gait").mkdir(parents=True)
    subprocess.run(["git", "clone", "-q", "--bare", str(src), str(mirror / "someone+gait" / "repo")], check=True)
    rows = [{"trial": "k_walk_fast", "label": "walk", "subject": "k", "style": "fast", "repository": "someone/gait",
             "commit": commit, "path": "Data/k_walk_fast.bvh", "blend": ""},
            {"trial": "k_run_gone", "label": "run", "subject": "k", "style": "fast", "repository": "someone/gait",
             "commit": commit, "path": "Data/missing.bvh", "blend": ""}]
    said = []
    out = tmp_path / "out"
    assert aalto.materialise(rows, mirror, out, log=said.append) == 1
    assert (out / "bvh" / "k_walk_fast.bvh").read_text() == _BVH
    with open(out / "labels.csv", newline="") as f:
        got = list(csv.DictReader(f))
    assert list(got[0]) == ["trial", "label", "subject", "file", "skeleton", "seconds", "description", "source"]
    assert got[0]["file"] == "bvh/k_walk_fast.bvh" and got[0]["seconds"] == "0.03" and got[0]["subject"] == "k"
    assert any("k_run_gone" in s for s in said)


def test_a_malformed_manifest_is_refused_with_file_and_line(tmp_path):
    bad = tmp_path / "m.csv"
    bad.write_text(",".join(aalto.COLUMNS) + "\nx,hop,k,fast,a/b," + "0" * 40 + ",p.bvh,\n")
    with pytest.raises(aalto.ManifestError, match=r"m\.csv:2: label 'hop'"):
        aalto.read_manifest(bad)
