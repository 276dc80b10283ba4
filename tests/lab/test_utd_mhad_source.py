"""The "utd-mhad" gesture studio of issue 31: scripts/utd_mhad.py reads a snapshot's
skeleton files into labelled clips and writes each as a BVH that StoryBeam reads back at
the very joint positions the Kinect gave.

Built on a throw-away git repository holding one made-up skeleton file, so no fetched
motion is needed.
"""
from __future__ import annotations

import csv
import runpy
from io import BytesIO
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.io import savemat

from retrieval.features import STORYBEAM, motion_features
from retrieval.library import read_labels
from retrieval.library.bundle import LABEL_COLUMNS
from retrieval.motion import canonical_joint_map, load_motion, positions
from tests.support.git_snapshot import bare_snapshot

REPO = Path(__file__).resolve().parents[2]
utd = SimpleNamespace(**runpy.run_path(str(REPO / "scripts" / "utd_mhad.py")))

#: A standing Kinect skeleton (metres, Y up, facing the camera at -Z) in the file's joint order.
_STAND = np.array([
    [0.00, 0.60, 3.0], [0.00, 0.40, 3.0], [0.00, 0.10, 3.0], [0.00, -0.05, 3.0],   # head, shoulder c., spine, hip c.
    [-0.18, 0.38, 3.0], [-0.22, 0.12, 3.0], [-0.24, -0.12, 3.0], [-0.25, -0.20, 3.0],  # left arm
    [0.18, 0.38, 3.0], [0.22, 0.12, 3.0], [0.24, -0.12, 3.0], [0.25, -0.20, 3.0],      # right arm
    [-0.10, -0.12, 3.0], [-0.11, -0.55, 3.0], [-0.12, -0.98, 3.0], [-0.12, -1.02, 2.9],  # left leg
    [0.10, -0.12, 3.0], [0.11, -0.55, 3.0], [0.12, -0.98, 3.0], [0.12, -1.02, 2.9],      # right leg
])


def _wave(frames: int = 40) -> np.ndarray:
    """(T, 20, 3): the right hand raised and swung across in front of the face."""
    xyz = np.repeat(_STAND[None], frames, axis=0).copy()
    swing = 0.15 * np.sin(np.linspace(0, 4 * np.pi, frames))
    xyz[:, 9] = [0.30, 0.45, 3.0]                      # elbow out and up
    xyz[:, 10, 0], xyz[:, 10, 1], xyz[:, 10, 2] = 0.25 + swing, 0.75, 2.95  # wrist swinging above the head
    xyz[:, 11] = xyz[:, 10] + [0.0, 0.08, 0.0]
    return xyz


def _mat(xyz: np.ndarray) -> bytes:
    buf = BytesIO()
    savemat(buf, {"d_skel": np.transpose(xyz, (1, 2, 0))})
    return buf.getvalue()



def test_plan_reads_action_subject_and_take_from_the_file_name():
    rows = utd.plan(["README.md", "data/Skeleton/Skeleton_joint_order.txt", "data/Skeleton/a3_s8_t2_skeleton.mat",
                     "data/Skeleton/a23_s1_t4_skeleton.mat", "data/Depth/a3_s8_t2_depth.mat"])
    assert [(r["trial"], r["label"], r["subject"]) for r in rows] == [("a03_s8_t2", "wave", "s8"),
                                                                       ("a23_s1_t4", "walk", "s1")]
    assert [r["trial"] for r in utd.plan(["data/Skeleton/a3_s8_t2_skeleton.mat",
                                          "data/Skeleton/a23_s1_t4_skeleton.mat"], {23})] == ["a23_s1_t4"]


@pytest.mark.parametrize("paths,words", [
    (["data/Skeleton/a28_s1_t1_skeleton.mat"], "action a28 is not one of UTD-MHAD's a1-a27"),
    (["data/Skeleton/wave_s1.mat"], "not an a<action>_s<subject>_t<take>_skeleton.mat file name"),
    (["README.md"], "no data/Skeleton/a*_s*_t*_skeleton.mat files"),
])
def test_plan_refuses_what_it_cannot_place(paths, words):
    with pytest.raises(utd.SourceError, match=words.replace("*", r"\*").replace("(", r"\(")):
        utd.plan(paths)


def test_a_damaged_skeleton_file_is_refused_naming_it():
    with pytest.raises(utd.SourceError, match="a3.mat: not a MATLAB file"):
        utd.read_skeleton(b"not a mat file", "a3.mat")
    with pytest.raises(utd.SourceError, match=r"a3.mat: no d_skel of shape \(20, 3, frames\)"):
        utd.read_skeleton(_mat(_wave()[:, :15]), "a3.mat")
    bad = _wave()
    bad[3, 4, 1] = np.nan
    with pytest.raises(utd.SourceError, match="a3.mat: d_skel holds a non-finite value"):
        utd.read_skeleton(_mat(bad), "a3.mat")
    with pytest.raises(utd.SourceError, match="--classes: 'a30' is not an action"):
        utd._actions("a3,a30")


def test_the_bvh_puts_every_joint_where_the_kinect_did_and_maps_onto_the_canonical_body(tmp_path):
    xyz = _wave()
    back = load_motion(utd.save_bvh(utd.to_motion(xyz, "w"), tmp_path / "w.bvh", decimals=3))
    names = back.skeleton.names
    got = positions(back)[:, [names.index(n) for n, _ in utd.KINECT]]
    np.testing.assert_allclose(got, xyz, atol=1e-4)  # cm with 3 decimals
    cmap = canonical_joint_map(back.skeleton)
    assert [names[cmap[k]] for k in ("hips", "neck", "right_hand", "right_ankle", "right_toe")] == [
        "Hips", "Neck", "RightWrist", "RightFoot", "RightToeBase"]
    f = motion_features(back, "storybeam")
    assert np.isfinite(f).all()
    # the right hand swings across (side to side) far more than forward
    across, forward = f[:, STORYBEAM.names.index("rhand_across")], f[:, STORYBEAM.names.index("rhand_forward")]
    assert np.ptp(across) > 3 * np.ptp(forward)


def test_materialise_writes_bvh_and_labels_the_library_reads(tmp_path):
    bare, commit = bare_snapshot(tmp_path, {"data/Skeleton/a3_s2_t1_skeleton.mat": _mat(_wave(45)),
                                            "data/Skeleton/Skeleton_joint_order.txt": "1. head;\n"})
    out = tmp_path / "out"
    table = utd.materialise(bare, out, commit=commit)
    assert [(r["trial"], r["label"], r["subject"], r["seconds"]) for r in table] == [("a03_s2_t1", "wave", "s2", "1.50")]
    with open(out / "labels.csv", newline="") as f:
        got = list(csv.DictReader(f))
    assert list(got[0]) == list(LABEL_COLUMNS) and got[0]["file"] == "bvh/a03_s2_t1.bvh"
    row = read_labels(out)[0]
    m = load_motion(row.file)
    assert m.n_frames == 45 and m.fps == pytest.approx(30.0)
