"""The app's moves the CMU folder lacks (``assets/motions/moves``): a rig's helper joints
dropped without moving the rest, every move a clip the library and Act it out can use,
listed in the app's library, joined to any ``--data`` folder by trial name, and found
when performed."""
from __future__ import annotations

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.commands.output import moves_folder
from app.paths import MOTIONS_DIR, MOVES_DIR, REPO_ROOT
from retrieval.errors import DatasetError, StoryBeamError
from retrieval.library import ActSearch, read_labels
from retrieval.library.bundle import (
    LABEL_COLUMNS, MOVES_FOLDER, SELECTION, build, keep_joints, level_floor, moves_rows,
)
from retrieval.motion import canonical_joint_map, load_motion, positions
from retrieval.motion.model import Joint, Motion, Skeleton
from tests.support.synthetic_motion import make_motion, make_skeleton, write_bvh

CLASSES = {"walk", "run", "jump", "kick", "dance"}


def _with_helpers(motion: Motion) -> Motion:
    """``motion`` with two helper joints added: a leaf under the root and a chain of two
    under the first child, each named without the rig's prefix."""
    sk = motion.skeleton
    joints = [Joint("rig_" + j.name if not j.name.endswith("_end") else "rig_" + j.name, j.parent, j.offset,
                    j.channels, j.rotation_order, j.pre_rotation) for j in sk.joints]
    n = len(joints)
    joints += [Joint("Femur", 0, np.array([5.0, -3.0, 1.0]), ["Zrotation", "Xrotation", "Yrotation"]),
               Joint("Tibia", 1, np.array([0.0, -4.0, 0.0]), ["Zrotation", "Xrotation", "Yrotation"]),
               Joint("Tibia_end", n + 1, np.array([0.0, -2.0, 0.0]))]
    rng = np.random.default_rng(0)
    extra = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(3)])
    rot = np.concatenate([motion.rotations, np.broadcast_to(extra, (motion.n_frames, 3, 3, 3))], axis=1)
    return Motion(Skeleton(joints, sk.metres_per_unit, sk.up_axis, sk.name), rot, motion.root_translation,
                  motion.fps, "helpers")


def test_keep_joints_drops_helpers_and_leaves_the_rig_where_it_was():
    motion = make_motion(make_skeleton(), frames=20, fps=30.0, arm_swing=20.0, knee_bend=15.0)
    helped = _with_helpers(motion)
    kept = keep_joints(helped, "rig_")
    assert kept.skeleton.names == ["rig_" + n for n in motion.skeleton.names]
    np.testing.assert_allclose(positions(kept), positions(motion), atol=1e-9)
    with pytest.raises(DatasetError, match="root"):
        keep_joints(helped, "Tibia")


def _lowest_foot(motion: Motion) -> np.ndarray:
    jm = canonical_joint_map(motion.skeleton)
    return positions(motion)[:, [jm["left_ankle"], jm["right_ankle"]], 1].min(axis=1)


def test_level_floor_takes_out_a_drift_and_keeps_a_jump():
    """A 4 s gait whose root drifts up 0.3 m (a video capture's floor), with a 0.3 s jump
    of 0.2 m at 2 s: levelled, the standing foot stays within 2 cm of its start, and the
    jump still rises at least 0.15 m."""
    motion = make_motion(make_skeleton(), frames=120, fps=30.0, knee_bend=10.0)
    t = np.arange(120) / 30.0
    up = 0.3 * t / t[-1] + 0.2 * (np.abs(t - 2.0) < 0.15)
    root = motion.root_translation.copy()
    root[:, 1] += up / motion.skeleton.metres_per_unit
    drifted = Motion(motion.skeleton, motion.rotations, root, motion.fps, "drift")
    before, after = _lowest_foot(motion), _lowest_foot(level_floor(drifted))
    calm = np.abs(t - 2.0) > 0.6
    inside = (t > 0.5) & (t < t[-1] - 0.5)
    gap = after - before
    assert np.ptp(gap[calm & inside]) < 0.015
    assert np.ptp(gap[calm]) < 0.04
    jump = np.abs(t - 2.0) < 0.1
    assert (gap[jump] - np.median(gap[calm])).min() > 0.15
    assert np.abs(_lowest_foot(level_floor(motion)) - before).max() < 0.002  # a level clip moves under 2 mm


def test_every_bundled_move_is_a_labelled_clip_the_library_can_read():
    rows = read_labels(MOVES_DIR)
    assert len(rows) >= 6 and {r.label for r in rows} <= CLASSES
    assert {"jump", "kick", "dance"} <= {r.label for r in rows}
    for r in rows:
        m = load_motion(r.file)
        canonical_joint_map(m.skeleton)  # raises when a body part is missing
        assert m.fps == pytest.approx(30.0) and 1.5 <= m.seconds <= 10.01, r.trial
    licences = sorted(p.name for p in MOVES_DIR.glob("LICENSE-*.txt"))
    assert licences == ["LICENSE-facebookresearch-AnimatedDrawings.txt", "LICENSE-lsw9021-MASS.txt",
                        "LICENSE-michaelchughes-NPBayesHMM.txt"]
    credits = (MOVES_DIR / "CREDITS.md").read_text(encoding="utf-8")
    assert all(f"`{r.trial}`" in credits for r in rows)


def test_the_apps_library_lists_its_moves():
    """What ``storybeam build-library`` writes: the app plays them and its Act it out finds them."""
    with open(MOTIONS_DIR / "labels.csv", newline="", encoding="utf-8") as fh:
        listed = {r["trial"]: r for r in csv.DictReader(fh)}
    for r in read_labels(MOVES_DIR):
        assert listed[r.trial]["file"] == f"{MOVES_FOLDER}/{Path(r.file).name}"
        assert listed[r.trial]["label"] == r.label


def test_build_library_lists_the_moves_folder_and_refuses_a_clash(tmp_path):
    data, out = tmp_path / "cmu", tmp_path / "library"
    (data / "bvh").mkdir(parents=True)
    motion = make_motion(make_skeleton(), frames=30, fps=30.0)
    write_bvh(motion, data / "bvh" / "clip.bvh")
    with open(data / "labels.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=LABEL_COLUMNS)
        w.writeheader()
        for label, trials in SELECTION.items():
            w.writerows({"trial": t, "label": label, "subject": "s", "file": "bvh/clip.bvh", "skeleton": "",
                         "seconds": "1", "description": label, "source": "tests"} for t in trials)
    (out / MOVES_FOLDER).mkdir(parents=True)
    write_bvh(motion, out / MOVES_FOLDER / "hop.bvh")
    move = {"trial": "x_hop", "label": "jump", "subject": "x", "file": "hop.bvh", "skeleton": "", "seconds": "1",
            "description": "hop", "source": "tests"}
    for trial in ("x_hop", "02_01"):
        with open(out / MOVES_FOLDER / "labels.csv", "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=LABEL_COLUMNS)
            w.writeheader()
            w.writerow({**move, "trial": trial})
        if trial == "02_01":
            with pytest.raises(DatasetError, match="02_01"):
                build(data, out)
            continue
        rows = build(data, out)
        assert rows[-1]["trial"] == "x_hop" and rows[-1]["file"] == f"{MOVES_FOLDER}/hop.bvh"
        assert [r.trial for r in read_labels(out)][-1] == "x_hop"
        assert "x_hop" in (out / "CREDITS.md").read_text(encoding="utf-8")
    assert moves_rows(tmp_path) == []


@pytest.fixture(scope="module")
def small_library(tmp_path_factory) -> Path:
    """Four bundled CMU clips (a walk, a run, a jump, a kick) as a labelled folder."""
    folder = tmp_path_factory.mktemp("small")
    (folder / "bvh").mkdir()
    with open(MOTIONS_DIR / "labels.csv", newline="", encoding="utf-8") as fh:
        rows = {r["trial"]: r for r in csv.DictReader(fh)}
    with open(folder / "labels.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=LABEL_COLUMNS)
        w.writeheader()
        for trial in ("02_01", "02_03", "02_04", "10_01"):
            shutil.copy(MOTIONS_DIR / rows[trial]["file"], folder / "bvh")
            w.writerow(rows[trial])
    return folder


def test_the_act_library_joins_moves_by_trial_name(small_library):
    alone = ActSearch.build(small_library, moves=None)
    joined = ActSearch.build(small_library, moves=MOVES_DIR)
    moves = [r.trial for r in read_labels(MOVES_DIR)]
    assert alone.clip_names == ["02_01", "02_03", "02_04", "10_01"]
    assert joined.clip_names == alone.clip_names + moves
    # a folder that already holds the moves (the app's own library) gets no second copy
    own = ActSearch.build(MOTIONS_DIR, moves=MOVES_DIR)
    assert len(own) == len(read_labels(MOTIONS_DIR))


def test_a_jumping_jack_is_found_only_when_the_library_has_one(small_library):
    """The move performed (its own joints, a second and a half in) is answered by itself
    with the moves, and by something else without them."""
    m = load_motion(MOVES_DIR / "ad_jumping_jacks.bvh")
    jm = canonical_joint_map(m.skeleton)
    pos = positions(m)[45:]
    joined = ActSearch.build(small_library, moves=MOVES_DIR)
    assert joined.search_positions(pos, m.fps, k=1, joint_map=jm)[0].trial == "ad_jumping_jacks"
    alone = ActSearch.build(small_library, moves=None)
    assert alone.search_positions(pos, m.fps, k=1, joint_map=jm)[0].trial != "ad_jumping_jacks"


def test_the_moves_option_names_a_folder_or_none(tmp_path):
    assert moves_folder(None) == MOVES_DIR
    assert moves_folder("none") is None and moves_folder("None") is None
    assert moves_folder(str(MOVES_DIR)) == MOVES_DIR
    with pytest.raises(StoryBeamError, match="--moves .*no labels.csv"):
        moves_folder(str(tmp_path))


@pytest.mark.parametrize("row,words", [
    ("x,skip,s,o/r,{c},p.bvh,,,0,,,1,d,MIT,n", "label 'skip'"),
    ("x,jump,s,o/r,{c},p.bvh,,,2,1.5,,1,d,MIT,n", "end must be seconds after start, got '1.5'"),
    ("x,jump,s,o/r,{c},p.amc,,,0,,,1,d,MIT,n", "an AMC file needs its ASF in skeleton"),
    ("x,jump,s,o/r,{c},p.bvh,s.asf,,0,,,1,d,MIT,n", "an AMC file needs its ASF in skeleton"),
])
def test_the_materialiser_refuses_a_malformed_manifest(tmp_path, row, words):
    manifest = tmp_path / "m.csv"
    manifest.write_text("trial,label,subject,repository,commit,path,skeleton,keep,start,end,level,seconds,description,"
                        "licence,notes\n" + row.format(c="a" * 40) + "\n")
    out = subprocess.run([sys.executable, str(REPO_ROOT / "scripts" / "act_moves.py"), "--manifest", str(manifest),
                          "--out", str(tmp_path / "o"), "--mirror", str(tmp_path)], capture_output=True, text=True)
    assert out.returncode != 0
    assert f"{manifest}:2: {words}" in out.stderr
    assert "Traceback" not in out.stderr


def test_convert_move_reads_an_amc_with_its_asf_and_keeps_its_window(cmu_dir, tmp_path):
    """A move cut from a longer CMU take (the jumping jacks of 13_29, say): the AMC read with
    its ASF, the window's frames kept, resampled to 30 fps, nothing else moved."""
    from retrieval.library.bundle import convert_move
    src, asf = cmu_dir / "amc" / "02_01.amc", cmu_dir / "asf" / "02.asf"
    whole = load_motion(src, asf)
    out = convert_move(src, tmp_path / "w.bvh", "w", start=1.0, max_seconds=1.5, skeleton=asf)
    assert out.fps == pytest.approx(30.0) and out.n_frames == 45
    back = load_motion(tmp_path / "w.bvh")
    jm, jw = canonical_joint_map(back.skeleton), canonical_joint_map(whole.skeleton)
    p, q = positions(back), positions(whole)
    for k in (0, 44):  # frame k at 30 fps is frame 120 + 4k of the 120 fps take
        for part in ("hips", "left_ankle", "right_hand"):
            np.testing.assert_allclose(p[k, jm[part]] - p[0, jm["hips"]], q[120 + 4 * k, jw[part]] - q[120, jw["hips"]],
                                       atol=0.002)
