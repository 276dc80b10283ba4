"""Search by pose (:mod:`retrieval.library.pose_search`): a pose's features equal the
library's frame features; the search's answer equals a brute-force reference (every
clip's nearest frame by feature distance) when the shortlist covers the library, and
every hit it returns is its clip's true nearest frame otherwise; `storybeam search
--pose FILE:FRAME` reports the pose search's answer and refuses bad input plainly."""
from __future__ import annotations

import json

import numpy as np
import pytest

from retrieval.errors import StoryBeamError
from retrieval.features import MR17, leg_length
from retrieval.library import (
    POSE_FEATURE_SET,
    Clip,
    PoseSearch,
    characteristic_frame,
    clip_from_motion,
    pose_features,
)
from retrieval.motion import canonical_joint_map, positions
from tests.support.synthetic_motion import make_motion, make_skeleton, write_bvh


def _reference(clips: list[Clip], pose: np.ndarray, k: int, exclude: str | None = None) -> list[tuple]:
    """Every clip's nearest frame to ``pose`` by Euclidean feature distance, nearest first,
    ties by library order (a plain loop, no codes)."""
    rows = []
    for i, c in enumerate(clips):
        if c.trial == exclude:
            continue
        d = [float(np.sqrt(sum((a - b) ** 2 for a, b in zip(f, pose)))) for f in c.features]
        j = min(range(len(d)), key=lambda t: (d[t], t))
        rows.append((d[j], i, c.trial, j))
    rows.sort()
    return [(t, j, d) for d, _, t, j in rows[:k]]


@pytest.fixture(scope="module")
def clips() -> list[Clip]:
    """40 clips cut from one smooth random walk in feature space (shared stretches, near
    ties), labels a/b/c/d."""
    rng = np.random.default_rng(5)
    walk = np.cumsum(rng.normal(size=(4000, 17)), axis=0) * 0.1
    return [Clip(f"c{i:02d}", "abcd"[i % 4], walk[s:s + int(rng.integers(20, 90))], None, 30.0)
            for i, s in enumerate(rng.integers(0, 3900, 40))]


def test_pose_features_equal_the_frame_row_of_the_whole_clip():
    sk = make_skeleton(scale=0.8)
    motion = make_motion(sk, frames=40, bounce=0.15, knee_bend=35)
    jm = canonical_joint_map(sk)
    pos = positions(motion)
    rows = clip_from_motion(motion, "m").features
    # the clip's floor, as the feature set defines it (2nd percentile of the lowest foot)
    lowest = pos[:, [jm[j] for j in ("left_ankle", "left_toe", "right_ankle", "right_toe")], 1].min(axis=1)
    floor = float(np.percentile(lowest, 2.0))
    size = leg_length(sk, jm)
    for t in (0, 7, 19, 33):
        np.testing.assert_allclose(pose_features(pos[t], jm, size, floor, "mr17"), rows[t], atol=1e-12)
    # the floor only moves the three heights, by the floor's change over the leg length
    lifted = pose_features(pos[7], jm, size, floor - 0.1, "mr17")
    heights = [k for k, s in enumerate(MR17.specs) if s.kind == "height"]
    others = [k for k in range(MR17.dim) if k not in heights]
    np.testing.assert_allclose(lifted[heights] - rows[7][heights], 0.1 / size, atol=1e-12)
    np.testing.assert_allclose(lifted[others], rows[7][others], atol=1e-12)


def test_pose_features_refuse_a_bad_pose():
    sk = make_skeleton()
    jm = canonical_joint_map(sk)
    pos = positions(make_motion(sk, frames=3))[0]
    with pytest.raises(StoryBeamError, match="joints, 3"):
        pose_features(pos[:, :2], jm, 1.0)
    bad = pos.copy()
    bad[3, 1] = np.nan
    with pytest.raises(StoryBeamError, match="finite"):
        pose_features(bad, jm, 1.0)


def test_full_shortlist_equals_the_brute_force_reference(clips):
    search = PoseSearch.from_clips(clips, dims=4)
    rng = np.random.default_rng(0)
    for q in range(12):
        c = clips[int(rng.integers(len(clips)))]
        pose = c.features[int(rng.integers(c.n_frames))] + rng.normal(scale=0.05, size=17)
        got = search.search(pose, k=6, shortlist=len(clips))
        expect = _reference(clips, pose, 6)
        assert [(h.trial, h.frame) for h in got] == [(t, j) for t, j, _ in expect]
        np.testing.assert_allclose([h.distance for h in got], [d for _, _, d in expect], rtol=0, atol=1e-12)


def test_short_shortlist_hits_are_their_clips_nearest_frames_in_code_order(clips):
    search = PoseSearch.from_clips(clips, dims=4)
    pose = clips[9].features[11] + 0.02
    got = search.search(pose, k=5, shortlist=8)
    assert len(got) == 5
    assert [h.distance for h in got] == sorted(h.distance for h in got)
    shortlisted = {m.trial: m.distance for m in search.index.subsequence_codes(search.index.encode(pose[None]), k=8)}
    by_trial = {c.trial: c for c in clips}
    for h in got:
        assert h.trial in shortlisted and h.code_distance == shortlisted[h.trial]
        ref = _reference([by_trial[h.trial]], pose, 1)[0]
        assert (h.frame, h.distance) == pytest.approx((ref[1], ref[2]), abs=1e-12)


def test_own_pose_finds_its_clip_unless_held_back(clips):
    search = PoseSearch.from_clips(clips, dims=4)
    c = clips[17]
    top = search.search(c.features[30], k=3)[0]
    assert (top.trial, top.frame, top.distance) == (c.trial, 30, 0.0)
    held = search.search(c.features[30], k=3, exclude=c.trial)
    assert c.trial not in [h.trial for h in held] and len(held) == 3
    assert [(h.trial, h.frame) for h in held] == [(t, j) for t, j, _ in _reference(clips, c.features[30], 3, c.trial)]


def test_pose_search_refuses_bad_queries_and_inconsistent_features(clips):
    search = PoseSearch.from_clips(clips, dims=4)
    with pytest.raises(StoryBeamError, match="17 finite"):
        search.search(np.zeros(5))
    with pytest.raises(StoryBeamError, match="at least 1"):
        search.search(np.zeros(17), k=0)
    with pytest.raises(StoryBeamError, match="feature arrays"):
        PoseSearch(search.index, [c.features for c in clips[:-1]])
    with pytest.raises(StoryBeamError, match="codes for"):
        PoseSearch(search.index, [c.features[:-1] for c in clips])


def test_characteristic_frames_follow_their_rules():
    names = MR17.names
    f = np.zeros((10, 17))
    f[4, names.index("hips_height")] = 2.0
    f[6, names.index("rankle_height")] = 3.0  # one foot high: a kick
    f[8, names.index("lankle_height")] = 1.0  # both feet up, lower one highest: flight
    f[8, names.index("rankle_height")] = 1.0
    assert characteristic_frame(f, "jump") == 4
    assert characteristic_frame(f, "kick") == 6
    assert characteristic_frame(f, "run") == 8
    assert characteristic_frame(f, "dance") is None


# ------------------------------------------------------------------ the command
def _folder(tmp_path):
    sk = make_skeleton()
    folder = tmp_path / "lib"
    folder.mkdir()
    rows = ["trial,label,file,skeleton"]
    for i, (arm, knee) in enumerate(((20, 15), (22, 14), (80, 40), (78, 42))):
        write_bvh(make_motion(sk, frames=45, arm_swing=arm, knee_bend=knee, phase=0.3 * i), folder / f"m{i}.bvh")
        rows.append(f"m{i},{'slow' if i < 2 else 'big'},m{i}.bvh,")
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    return folder


def test_search_pose_command_reports_the_pose_search(tmp_path, capsys):
    from app.cli import main

    folder = _folder(tmp_path)
    q = folder / "m2.bvh"
    assert main(["search", "--data", str(folder), "--pose", f"{q}:12", "--top", "3", "--dims", "3",
                 "--json", "-"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["mode"] == "pose" and out["clips"] == 4 and out["search_ms"] >= 0
    assert [set(r) >= {"trial", "label", "frame", "distance"} for r in out["results"]] == [True] * 3
    search = PoseSearch.build(folder, dims=3)
    expect = search.search(search.features[2][12], k=3)
    assert [(r["trial"], r["frame"], r["distance"]) for r in out["results"]] == \
        [(h.trial, h.frame, h.distance) for h in expect]
    assert out["results"][0]["trial"] == "m2" and out["results"][0]["frame"] == 12


@pytest.mark.parametrize("pose, message", [
    ("nocolon", "FILE:FRAME"), ("{q}:-1", "FILE:FRAME"), ("{q}:x", "FILE:FRAME"),
    ("{q}:45", "past the last frame"), ("{d}/none.bvh:0", "not found"),
])
def test_search_pose_command_refuses_bad_input_plainly(tmp_path, capsys, pose, message):
    from app.cli import main

    folder = _folder(tmp_path)
    arg = pose.format(q=folder / "m0.bvh", d=folder)
    assert main(["search", "--data", str(folder), "--pose", arg, "--dims", "3"]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_search_needs_exactly_one_of_query_and_pose(tmp_path, capsys):
    from app.cli import main

    folder = _folder(tmp_path)
    assert main(["search", "--data", str(folder)]) == 1
    assert "--query FILE or --pose" in capsys.readouterr().err


def test_pose_search_bench_on_a_small_folder(tmp_path, capsys):
    from app.cli import main

    sk = make_skeleton()
    folder = tmp_path / "lib"
    folder.mkdir()
    rows = ["trial,label,file,skeleton"]
    kinds = {"jump": dict(bounce=0.3, knee_bend=40, period=1.2), "run": dict(bounce=0.08, knee_bend=45, period=0.6),
             "walk": dict(bounce=0.0, knee_bend=15, period=1.1)}
    for i in range(9):
        label = list(kinds)[i % 3]
        write_bvh(make_motion(sk, frames=40, phase=0.5 * i, **kinds[label]), folder / f"m{i}.bvh")
        rows.append(f"m{i},{label},m{i}.bvh,")
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "b.json"
    assert main(["bench", "pose-search", "--data", str(folder), "--quiet", "--json", str(out), "--against", "mr17"]) == 0
    r = json.loads(out.read_text())
    # old vs new side by side: both searches answered every query in each of the rounds
    side = r["side_by_side"]
    assert set(side["search_ms"]) == {POSE_FEATURE_SET, "mr17"} != {"mr17"}
    assert all(t["queries"] == 6 * side["rounds"] and t["median"] > 0 for t in side["search_ms"].values())
    assert r["clips"] == 9 and r["queries"] == 6  # the jumps and runs, not the walks
    assert set(r["classes"]) == {"jump", "run"}
    for c in r["classes"].values():
        assert c["queries"] == 3 and c["correct"] == round(3 * c["accuracy"])
    # every query's top answer is the pose search's, with the query's own clip held back
    search = PoseSearch.build(folder)
    for q in r["queries_detail"]:
        top = search.search(search.features[search.index.position(q["trial"])][q["frame"]], k=1,
                            exclude=q["trial"])[0]
        assert q["top"]["trial"] == top.trial != q["trial"]
    printed = capsys.readouterr().out
    assert r["search_ms"]["median"] > 0 and "top-1 class" in printed and "side by side, interleaved" in printed
