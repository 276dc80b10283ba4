"""The "hdm05" development studio of issue 31: scripts/hdm05.py reads a snapshot's file
names into labelled clips and copies the ASF/AMC files as they are.

Built on a throw-away git repository holding one tiny clip, so no fetched motion is needed.
"""
from __future__ import annotations

import csv
import runpy
from pathlib import Path
from types import SimpleNamespace

import pytest

from retrieval.library import read_labels
from retrieval.library.bundle import LABEL_COLUMNS
from retrieval.motion import load_motion
from tests.support.git_snapshot import bare_snapshot
from tests.support.synthetic_motion import TINY_ASF

REPO = Path(__file__).resolve().parents[2]
hdm = SimpleNamespace(**runpy.run_path(str(REPO / "scripts" / "hdm05.py")))

# Vicon's first comment names the capture folder, in Latin-1 for HDM05
_AMC = b"#!OML:ASF X:\\f\xfcr Bonn\\a.ASF\r\n:FULLY-SPECIFIED\r\n:DEGREES\r\n1\r\nroot 0 17 0 0 0 0\r\na 5\r\n" \
       b"2\r\nroot 0 17 0 0 0 0\r\na 10\r\n"



def test_plan_reads_class_and_actor_from_the_file_name():
    rows = hdm.plan(["README", "train/6/HDM_bd.asf", "train/6/HDM_bd_kickLFront1Reps_003_120.amc",
                     "train/6/HDM_bd_kickLFront1Reps_003_120.amc.mat"])
    assert [(r["trial"], r["label"], r["subject"], r["asf"]) for r in rows] == [
        ("HDM_bd_kickLFront1Reps_003_120", "kick_left_front", "bd", "train/6/HDM_bd.asf")]


@pytest.mark.parametrize("paths,words", [
    (["test/1/HDM_mm.asf", "test/1/HDM_mm_waveRightHand_001_120.amc"], "class 'waveRightHand' is not one of"),
    (["test/1/HDM_mm_squat1Reps_001_120.amc"], "its skeleton test/1/HDM_mm.asf is not in the snapshot"),
    (["test/1/HDM_mm.asf", "test/1/mm_squat.amc"], "not an HDM_<actor>_<class>_<take>_120.amc file name"),
    (["README"], "no HDM_*_120.amc files"),
])
def test_plan_refuses_what_it_cannot_place(paths, words):
    with pytest.raises(hdm.SourceError, match=words.replace("*", r"\*").replace("(", r"\(")):
        hdm.plan(paths)


def test_materialise_copies_the_clips_and_writes_labels_the_library_reads(tmp_path):
    bare, commit = bare_snapshot(tmp_path, {"train/10/HDM_dg.asf": TINY_ASF,
                                            "train/10/HDM_dg_squat1Reps_002_120.amc": _AMC})
    out = tmp_path / "out"
    table = hdm.materialise(bare, out, commit=commit)
    assert [r["label"] for r in table] == ["squat"]
    assert (out / "amc" / "HDM_dg_squat1Reps_002_120.amc").read_bytes() == _AMC  # copied as it is
    with open(out / "labels.csv", newline="") as f:
        got = list(csv.DictReader(f))
    assert list(got[0]) == list(LABEL_COLUMNS) and got[0]["skeleton"] == "asf/HDM_dg.asf" and got[0]["subject"] == "dg"
    row = read_labels(out)[0]
    assert load_motion(row.file, row.skeleton).n_frames == 2  # the Latin-1 comment is read
