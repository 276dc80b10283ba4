"""`storybeam eval --identity/--pose-identity --skeleton-from DIR`: the same trials on
another skeleton (another size, Z up), matched by name."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.support.synthetic_motion import make_motion, make_skeleton, write_bvh

#: label -> (arm swing, knee bend, bounce, period) per take: distinct takes, so each finds itself
TAKES = {
    "walk": [(20.0, 15.0, 0.0, 1.0), (30.0, 25.0, 0.0, 1.3), (12.0, 10.0, 0.0, 0.8)],
    "run": [(60.0, 45.0, 0.08, 0.6), (75.0, 55.0, 0.12, 0.5), (50.0, 35.0, 0.05, 0.7)],
}


def _take(sk, label: str, k: int):
    arm, knee, bounce, period = TAKES[label][k]
    return make_motion(sk, frames=40 + 5 * k, fps=30.0, arm_swing=arm, knee_bend=knee, bounce=bounce,
                       period=period, phase=0.7 * k, heading_deg=40.0 * k)


@pytest.fixture(scope="module")
def folders(tmp_path_factory) -> tuple[Path, Path]:
    """A labelled library (adult size, Y up) and the same takes on a smaller Z-up
    skeleton, named by trial, plus one trial the library does not hold."""
    lib = tmp_path_factory.mktemp("lib")
    other = tmp_path_factory.mktemp("other")
    rows = ["trial,label,subject,file,skeleton"]
    small = make_skeleton(scale=0.6, up_axis="z", name="small")
    for label in TAKES:
        for k in range(3):
            name = f"{label}_{k}"
            write_bvh(_take(make_skeleton(1.0), label, k), lib / f"{name}.bvh")
            write_bvh(_take(small, label, k), other / f"{name}.bvh")
            rows.append(f"{name},{label},s{k},{name}.bvh,")
    write_bvh(_take(small, "walk", 1), other / "not_there.bvh")
    (lib / "labels.csv").write_text("\n".join(rows) + "\n")
    return lib, other


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("STORYBEAM_CACHE", str(tmp_path / "cache"))


def test_other_skeleton_folder_matched_by_name(folders, tmp_path):
    from lab.experiment import other_skeleton_trials
    from retrieval.errors import StoryBeamError

    lib, other = folders
    trials = other_skeleton_trials(other)
    assert [t.trial for t in trials] == sorted(["not_there"] + [f"{c}_{k}" for c in TAKES for k in range(3)])
    assert [t.trial for t in other_skeleton_trials(lib)][:1] == ["run_0"]  # a labels.csv is read as such
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(StoryBeamError, match="no labels.csv and no .bvh"):
        other_skeleton_trials(empty)


def test_cli_skeleton_identity_and_pose_identity(folders, tmp_path, capsys):
    from app.cli import main

    lib, other = folders
    out = tmp_path / "ident.json"
    assert main(["eval", "--data", str(lib), "--dims", "3", "--identity", "--pose-identity", "--skeleton-from",
                 str(other), "--quiet", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    data = json.loads(out.read_text())
    ident, pose = data["skeleton_identity"], data["pose_identity"]
    assert ident["trials"] == 6 and ident["not_in_library"] == ["not_there"]
    # the same motion on a body 0.6 times the size, Z up: every take finds itself
    assert ident["find_top1"] == 1.0 and ident["misses"] == []
    assert "same trial first: storybeam find 6/6" in printed
    assert pose["poses"] == 18 and pose["trials"] == 6 and not pose["trial_left_out"]
    assert pose["same_class"] == 1.0 and pose["same_trial"] == 1.0
    assert "same trial 18/18" in printed

    # without --skeleton-from: the library's own frames, their own trial left out
    assert main(["eval", "--data", str(lib), "--dims", "3", "--pose-identity", "--quiet", "--json", str(out)]) == 0
    pose = json.loads(out.read_text())["pose_identity"]
    assert pose["trial_left_out"] and "same_trial" not in pose
    assert all(m["found"] != m["trial"] for m in pose["misses"])
    assert len([m for m in pose["misses"] if m["found_label"] != m["label"]]) == round(18 * (1 - pose["same_class"]))


def test_cli_skeleton_from_errors(folders, tmp_path, capsys):
    from app.cli import main

    lib, other = folders
    assert main(["eval", "--data", str(lib), "--skeleton-from", str(other), "--quiet"]) == 1
    assert "--skeleton-from goes with --identity" in capsys.readouterr().err
    stranger = tmp_path / "stranger"
    stranger.mkdir()
    (stranger / "zz.bvh").write_bytes((other / "walk_0.bvh").read_bytes())
    assert main(["eval", "--data", str(lib), "--identity", "--skeleton-from", str(stranger), "--quiet"]) == 1
    assert "none of its 1 trial names (zz) is a trial of --data" in capsys.readouterr().err


def test_motion_pose_is_the_search_commands_row(folders):
    from retrieval.errors import StoryBeamError
    from retrieval.library import PoseSearch, clip_from_motion, load_dataset, pose_feature_set
    from retrieval.motion import load_motion

    lib, _ = folders
    canonical = pose_feature_set("canonical")
    search = PoseSearch.from_clips(load_dataset(lib, fps=30.0, feature_set=canonical), dims=3, feature_set=canonical)
    motion = load_motion(lib / "run_1.bvh")
    feats = clip_from_motion(motion, "run_1", "", 30.0, search.index.feature_set).features
    assert np.array_equal(search.motion_pose(motion, 20), feats[20])
    assert search.search(search.motion_pose(motion, 20), k=1)[0].trial == "run_1"
    with pytest.raises(StoryBeamError, match="outside the motion's frames"):
        search.motion_pose(motion, motion.n_frames)
    # a search over another feature set computes its queries in that set
    assert search.index.feature_set == canonical == "mr17-canonical" == pose_feature_set()
    source = pose_feature_set("source")
    other = PoseSearch.from_clips(load_dataset(lib, fps=30.0, feature_set=source), dims=3, feature_set=source)
    assert np.array_equal(other.motion_pose(motion, 20),
                          clip_from_motion(motion, "run_1", "", 30.0, source).features[20])
    assert not np.allclose(other.motion_pose(motion, 20), search.motion_pose(motion, 20))


@pytest.mark.parametrize("character", ["kid", "robot", "cat"])
def test_a_pose_on_the_apps_character_finds_its_take(folders, character):
    """A child's pose comes from the app's own characters (big heads, short legs): every
    take of the library retargeted onto one finds itself at 1/4, 1/2 and 3/4 in the
    default pose search (the canonical body); on the file's own body half the poses land
    on another take."""
    from ar.scene.characters import build_character
    from retrieval.animation import retarget
    from retrieval.library import POSE_FEATURE_SET, PoseSearch, load_dataset
    from retrieval.motion import load_motion

    lib, _ = folders
    target = build_character(character).skeleton
    found = {}
    for feature_set in (POSE_FEATURE_SET, "mr17"):
        search = PoseSearch.from_clips(load_dataset(lib, fps=30.0, feature_set=feature_set), dims=3,
                                       feature_set=feature_set)
        hits = []
        for trial in search.index.trials:
            moved = retarget(load_motion(lib / f"{trial}.bvh"), target)
            for frac in (0.25, 0.5, 0.75):
                pose = search.motion_pose(moved, int(round(frac * (moved.n_frames - 1))))
                hits.append(search.search(pose, k=1)[0].trial == trial)
        found[feature_set] = sum(hits)
    assert found[POSE_FEATURE_SET] == 18
    assert found["mr17"] <= 12  # what the canonical body buys



@pytest.mark.parametrize("character", ["kid", "robot", "cat"])
def test_a_clip_on_the_apps_character_finds_its_take(tmp_path, character):
    """Issue 31: a take retargeted onto one of the app's characters (other bone lengths,
    a big head) is answered by its own library clip first -- by "find this clip"
    (``search --query --find``) and by the nearest-clip ranking (``search --query``),
    with the default clip features (the canonical body) -- even when the library also
    holds a *twin*: a slightly different take (arms and knees 10 % wider) performed by a
    body built like that character. On the file's own body the twin's proportions match
    the query's, which outweighs the small difference in motion: the ranking answers the
    twin."""
    from dataclasses import replace

    from ar.scene.characters import build_character
    from retrieval.animation import retarget
    from retrieval.features import STORYBEAM, register_feature_set
    from retrieval.library import MotionIndex
    from retrieval.motion import load_motion, save_bvh

    target = build_character(character).skeleton
    rows = ["trial,label,subject,file,skeleton"]
    for label, takes in TAKES.items():
        for k, (arm, knee, bounce, period) in enumerate(takes):
            write_bvh(_take(make_skeleton(1.0), label, k), tmp_path / f"{label}_{k}.bvh")
            twin = make_motion(make_skeleton(1.0), frames=40 + 5 * k, fps=30.0, arm_swing=1.1 * arm,
                               knee_bend=1.1 * knee, bounce=bounce, period=period, phase=0.7 * k,
                               heading_deg=40.0 * k)
            save_bvh(retarget(twin, target), tmp_path / f"{label}_{k}_twin.bvh")
            rows += [f"{label}_{k},{label},s{k},{label}_{k}.bvh,", f"{label}_{k}_twin,{label},t{k},{label}_{k}_twin.bvh,"]
    (tmp_path / "labels.csv").write_text("\n".join(rows) + "\n")
    source = register_feature_set(replace(STORYBEAM, name="storybeam-source-test", body="source")).name
    found = {}
    for feature_set in ("storybeam", source):
        index = MotionIndex.build(tmp_path, dims=3, fps=30.0, feature_set=feature_set)
        hits = []
        for label, takes in TAKES.items():
            for k in range(len(takes)):
                trial = f"{label}_{k}"
                q = index.features(retarget(load_motion(tmp_path / f"{trial}.bvh"), target))
                hits.append((index.find(q, k=1)[0].trial == trial, index.query(q, k=1)[0].trial == trial))
        found[feature_set] = tuple(sum(h[i] for h in hits) for i in (0, 1))
    assert found["storybeam"] == (6, 6)
    assert found[source][0] < 6 and found[source][1] <= 3  # what the canonical body buys (measured 0-4, 0)
