"""Search by pose and the library's groups in the motion picker: the posable figure's
limits (no Kivy window), then the real app driven by touch offscreen (one app per
subprocess, like tests/app/test_ui.py), in both languages: the figure is posed by
dragging its handles, the tiles are the pose search's answer for the pose the figure
reports, a tile picks its clip; the groups are those of :func:`group_folder` on the
bundled library, named by label, and a clip picked in a group becomes the character's."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.paths import MOTIONS_DIR
from app.ui.clip_tiles import numbered_names
from app.ui.strings import tr
from retrieval.library import PoseSearch, group_folder, pose_features
from retrieval.motion import CANONICAL_JOINTS

REPO = Path(__file__).resolve().parents[2]
DRIVER = REPO / "tests" / "support" / "pose_driver.py"
J = {n: i for i, n in enumerate(CANONICAL_JOINTS)}


def _figure():
    from app.ui import pose_figure  # deferred: imports Kivy's widget classes (no window is opened)
    return pose_figure


def _bone(p: np.ndarray, a: str, b: str) -> float:
    return float(np.linalg.norm(p[J[a]] - p[J[b]]))


def _check_limits(f, p: np.ndarray, head_deg: float) -> None:
    """Bone lengths fixed, feet above the floor, knees forward, elbows back, head within its limit."""
    for side in ("left", "right"):
        assert _bone(p, f"{side}_shoulder", f"{side}_elbow") == pytest.approx(f.UPPER_ARM, abs=1e-9)
        assert _bone(p, f"{side}_elbow", f"{side}_hand") == pytest.approx(f.FOREARM, abs=1e-9)
        assert _bone(p, f"{side}_hip", f"{side}_knee") == pytest.approx(f.THIGH, abs=1e-9)
        assert _bone(p, f"{side}_knee", f"{side}_ankle") == pytest.approx(f.SHIN, abs=1e-9)
        assert p[J[f"{side}_ankle"], 1] >= f.ANKLE_H - 1e-9
        hip, knee, ankle = (p[J[f"{side}_{j}"], :2] for j in ("hip", "knee", "ankle"))
        u, v = ankle - hip, knee - hip
        assert u[0] * v[1] - u[1] * v[0] >= -1e-9  # knee on the counter-clockwise (front) side
        sh, el, ha = (p[J[f"{side}_{j}"], :2] for j in ("shoulder", "elbow", "hand"))
        u, v = ha - sh, el - sh
        assert u[0] * v[1] - u[1] * v[0] <= 1e-9  # elbow on the back side
    assert abs(head_deg) <= f.HEAD_LIMIT_DEG + 1e-9
    assert f.HIPS_RANGE[0] - 1e-9 <= p[J["hips"], 1] <= f.HIPS_RANGE[1] + 1e-9


# ------------------------------------------------------------------ the figure's body
def test_figure_limits_hold_under_wild_drags():
    f = _figure()
    m = f.PoseModel()
    _check_limits(f, m.positions(), m.head_deg)
    rng = np.random.default_rng(3)
    for _ in range(300):
        handle = f.HANDLES[int(rng.integers(len(f.HANDLES)))]
        m.drag(handle, *rng.uniform(-3, 4, 2))
        _check_limits(f, m.positions(), m.head_deg)


def test_figure_moves_what_was_dragged_within_reach():
    f = _figure()
    m = f.PoseModel()
    m.drag("right_foot", 0.45, 0.6)  # reachable: the ankle goes exactly there
    assert m.positions()[J["right_ankle"], :2] == pytest.approx([0.45, 0.6], abs=1e-9)
    m.drag("left_hand", 0.0, 5.0)  # far above: the arm straightens towards it
    p = m.positions()
    assert p[J["left_hand"], 1] == pytest.approx(p[J["left_shoulder"], 1] + f.UPPER_ARM + f.FOREARM, abs=1e-6)
    m.drag("head", 3.0, 0.0)
    assert m.head_deg == pytest.approx(f.HEAD_LIMIT_DEG)
    before = m.positions()[J["right_ankle"]].copy()
    m.drag("hips", 0.0, 0.8)  # crouch: the planted foot stays where it is in the room
    assert m.positions()[J["right_ankle"]] == pytest.approx(before, abs=1e-9)
    m.drag("left_foot", 0.2, -1.0)  # below the floor (within reach): held at the floor
    assert m.positions()[J["left_ankle"], :2] == pytest.approx([0.2, f.ANKLE_H], abs=1e-9)
    m.drag("hips", 0.0, 9.0)  # as high as the hips go: the feet are pulled up off the floor
    assert m.positions()[J["hips"], 1] == f.HIPS_RANGE[1]
    assert m.positions()[J["left_ankle"], 1] > f.ANKLE_H + 0.3
    with pytest.raises(ValueError, match="no handle"):
        m.drag("tail", 0, 0)


def test_figure_features_are_the_library_features_of_its_joints():
    f = _figure()
    m = f.PoseModel()
    m.drag("right_foot", 0.6, 0.7)
    expect = pose_features(m.positions(), J, f.LEG, f.floor_height())
    np.testing.assert_allclose(m.features(), expect, rtol=0, atol=0)
    # the pose search's set is the canonical body's: heights above the standing ankles,
    # so a standing figure's feet are on the library's floor (its clips' lowest ankle)
    from retrieval.features import get_feature_set
    from retrieval.library import POSE_FEATURE_SET
    assert get_feature_set(POSE_FEATURE_SET).body == "canonical" and f.floor_height() == f.ANKLE_H
    assert f.floor_height("mr17") == f.FLOOR
    names = get_feature_set(POSE_FEATURE_SET).names
    stand = f.PoseModel()
    feet = [stand.features()[names.index(n)] for n in ("lankle_height", "rankle_height")]
    lowest = min(stand.positions()[J[a], 1] for a in ("left_ankle", "right_ankle"))
    assert min(feet) == pytest.approx((lowest - f.ANKLE_H) / f.LEG, abs=1e-9) and max(feet) < 0.02
    assert m.features()[names.index("rankle_height")] > 0.5
    names = ["rankle_height", "lankle_height", "hips_height"]
    from retrieval.features import MR17
    got = {n: m.features("mr17")[MR17.names.index(n)] for n in names}  # the file's own body: the figure's joints
    assert got["rankle_height"] == pytest.approx((0.7 - f.FLOOR) / f.LEG)
    assert got["lankle_height"] < 0.2 and got["hips_height"] == pytest.approx((f.STAND_HIPS - f.FLOOR) / f.LEG)


def test_library_extras_load_what_they_can_and_always_finish(tmp_path):
    from app.ui.pose_picker import LibraryExtras  # deferred: imports Kivy's widget classes (no window is opened)
    from tests.support.synthetic_motion import make_motion, make_skeleton, write_bvh

    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "labels.csv").write_text("trial,label,file,skeleton\na,walk,missing.bvh,\n")
    extras = LibraryExtras(broken)
    assert extras.wait(60) and extras.ready
    assert extras.pose_search is None and extras.groups is None
    assert "missing.bvh" in extras.error and "missing.bvh" in extras.groups_error
    assert extras.search(_figure().PoseModel()) == []

    small = tmp_path / "small"  # two clips: searchable, too few to group
    small.mkdir()
    sk = make_skeleton()
    for i in range(2):
        write_bvh(make_motion(sk, frames=30, arm_swing=20 + 40 * i), small / f"m{i}.bvh")
    (small / "labels.csv").write_text("trial,label,file,skeleton\nm0,walk,m0.bvh,\nm1,run,m1.bvh,\n")
    extras = LibraryExtras(small)
    assert extras.wait(60)
    assert extras.error is None and extras.groups is None and "at least 3" in extras.groups_error
    hits = extras.search(_figure().PoseModel(), k=2)
    assert sorted(h.trial for h in hits) == ["m0", "m1"]
    assert extras.clip_frames("m0") == 30


# ------------------------------------------------------------------ the app, by touch
@pytest.fixture(scope="module", params=["en", "ja"])
def driven(request, tmp_path_factory):
    lang = request.param
    tmp = tmp_path_factory.mktemp(f"pose_{lang}")
    out = tmp / "out"
    env = dict(os.environ, SDL_VIDEODRIVER="offscreen", KIVY_NO_ARGS="1", KIVY_HOME=str(tmp / "kivy"),
               STORYBEAM_TEST_LANG=lang, PYTHONPATH=str(REPO))
    env.pop("STORYBEAM_TEST_MOTIONS", None)
    proc = subprocess.run([sys.executable, str(DRIVER), "pose", str(tmp / "p.db"), str(out)], env=env,
                          capture_output=True, text=True, timeout=300)
    result_file = out / "result.json"
    assert result_file.is_file(), f"driver produced no result (rc {proc.returncode}):\n{proc.stderr[-3000:]}"
    result = json.loads(result_file.read_text())
    assert "error" not in result, result["error"]
    return lang, result, out


@pytest.fixture(scope="module")
def library():
    return PoseSearch.build(MOTIONS_DIR), group_folder(MOTIONS_DIR)


@pytest.mark.slow  # starts the app in a child process
def test_posing_by_touch_searches_the_pose_the_figure_shows(driven, library):
    lang, r, out = driven
    f = _figure()
    search, _ = library
    assert r["pose_title"] == tr("pose_title", lang)
    assert r["pose_button"][2] == tr("pose_button", lang) and r["groups_button"][2] == tr("groups_button", lang)
    for name in ("standing", "kick", "jump"):
        rec = r[name]
        pos = np.array(rec["positions"])
        _check_limits(f, pos, rec["head_deg"])
        # the tiles are the pose search's answer for the pose the figure reports
        np.testing.assert_allclose(rec["features"], pose_features(pos, J, f.LEG, f.floor_height()), atol=1e-12)
        expect = search.search(np.array(rec["features"]), k=len(rec["hits"]))
        assert [(h["trial"], h["frame"]) for h in rec["hits"]] == [(h.trial, h.frame) for h in expect]
        # each tile's figure starts at the moment its clip passes through the pose
        for h, start in zip(rec["hits"], rec["starts"]):
            n = len(search.features[search.index.position(h["trial"])])
            assert start == pytest.approx(h["frame"] / max(n - 1, 1))
    stand, kick, jump = (np.array(r[n]["positions"]) for n in ("standing", "kick", "jump"))
    assert kick[J["right_ankle"], 1] - stand[J["right_ankle"], 1] > 0.4  # the foot went up by the drag
    assert jump[J["hips"], 1] - stand[J["hips"], 1] > 0.2  # the hips went up
    for side in ("left", "right"):  # hands pulled far above the head: arms straight up, no further
        assert jump[J[f"{side}_hand"], 1] - jump[J[f"{side}_shoulder"], 1] > 0.5
    assert r["jump"]["head_deg"] == pytest.approx(f.HEAD_LIMIT_DEG)  # dragged far: held at its limit
    assert r["picked"] == r["clip_after_pose"] == r["jump"]["hits"][0]["trial"]
    assert r["class_after_pose"] == r["jump"]["hits"][0]["label"]
    for box in r["tile_boxes"] + r["group_boxes"]:
        assert box[2] >= 48 and box[3] >= 48  # big touch targets
    assert r["handle_dp"] >= 48
    assert (out / "pose_jump.png").is_file() and (out / "groups.png").is_file()


@pytest.mark.slow  # starts the app in a child process
def test_groups_by_touch_are_the_library_groups_named_by_label(driven, library):
    lang, r, _ = driven
    _, grouped = library
    groups = grouped.grouping.groups
    assert r["groups_title"] == tr("groups_title", lang)
    assert r["group_reps"] == [g.representative for g in groups]
    names = numbered_names([tr(f"motion_{g.name}", lang) if g.name else tr("group_n", lang, n=g.number + 1)
                            for g in groups])  # two groups of one class: "Kick 1", "Kick 2" (issue 29)
    assert len(set(names)) == len(names)
    for text, name, g in zip(r["group_texts"], names, groups):
        assert text == f"{name} ({len(g.members)})"
    assert r["group0_clips"] == [grouped.trials[i] for i in groups[0].members]
    assert r["group_pick"] == r["clip_after_group"]
    assert r["group_pick"] in [grouped.trials[i] for i in groups[-1].members]


def test_every_new_string_exists_in_both_languages():
    from app.ui.strings import STRINGS
    for key in ("pose_button", "pose_title", "pose_hint", "pose_found", "library_loading", "groups_button",
                "groups_title", "group_n"):
        assert STRINGS[key]["en"] and STRINGS[key]["ja"] and STRINGS[key]["en"] != STRINGS[key]["ja"]
