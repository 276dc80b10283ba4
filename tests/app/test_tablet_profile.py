"""The tablet profile (issue 13, part 2): the child's whole flow by touch in interpreters
that can import only what buildozer.spec ships, and buildozer.spec checked against what
that flow imported.

The flow (tests/support/tablet_scenarios.py, run through tests/support/tablet_profile.py,
whose import blocker refuses numba, llvmlite, pyrender, OpenGL, trimesh, matplotlib,
imageio and every other third-party package the tablet does not have): new story,
sketch two characters' paths, a motion by category and one through "More like this" (the
motion index, numpy path), Play with 3-D characters drawn by Kivy GL, the projector
screen through the synthetic tracked rig, then SIGKILL; a second interpreter reopens
the profile, opens the story by its tile and plays it in 3-D again.

Simulated, not the device: the display is SDL's offscreen EGL (Mesa), not an Android GPU;
the rig is the synthetic one (its camera frames are drawn with OpenCV, no pyrender); the
touches are Kivy's test touches.
"""
from __future__ import annotations

import configparser
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("kivy")

from app.story import Story  # noqa: E402
from app.story.storage import ProfileStore  # noqa: E402
from tests.support.tablet_profile import (  # noqa: E402
    BLOCKED,
    DESKTOP_STANDINS,
    HARNESS_MODULES,
    RECIPE_MODULES,
    is_third_party,
)

pytestmark = pytest.mark.slow  # the tablet profile runs the app in child interpreters

REPO = Path(__file__).resolve().parents[2]
PROFILE = REPO / "tests" / "support" / "tablet_profile.py"
#: requirements that are not Python packages the flow imports on this desktop: the
#: interpreter itself, and pyjnius (``jnius``, Android's Java bridge: only on the device)
NOT_IMPORTED_HERE = {"python3": "the interpreter", "pyjnius": "jnius exists on Android only",
                     "tflite-runtime": "the pose estimator: imported by the Act it out flow, which "
                                       "tests/app/test_act_it_out_flow.py runs on this profile and checks"}


def _env(tmp_path: Path, **extra: str) -> dict:
    return dict(os.environ, SDL_VIDEODRIVER="offscreen", KIVY_NO_ARGS="1", KIVY_HOME=str(tmp_path / "kivy"),
                STORYBEAM_TEST_LANG="en", PYTHONPATH=str(REPO), **extra)


@pytest.fixture(scope="module")
def flow(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("tablet")
    db, out = tmp / "p.db", tmp / "out"
    proc = subprocess.Popen([sys.executable, str(PROFILE), "tablet", str(db), str(out)], env=_env(tmp),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 400  # a bound for a loaded 2-core machine, not a speed check
        line = ""
        while time.time() < deadline and "READY" not in line:
            line = proc.stdout.readline()
            if not line and proc.poll() is not None:
                break
        if "READY" not in line:
            proc.kill()
            why = (out / "result.json").read_text() if (out / "result.json").exists() else proc.stderr.read()[-3000:]
            pytest.fail(f"the tablet flow did not finish: {why}")
        proc.send_signal(signal.SIGKILL)
        proc.wait(60)
    finally:
        if proc.poll() is None:
            proc.kill()
    first = json.loads((out / "result.json").read_text())
    assert proc.returncode == -signal.SIGKILL
    out2 = tmp / "out2"
    again = subprocess.run([sys.executable, str(PROFILE), "tablet_reopen", str(db), str(out2)],
                           env=_env(tmp, STORYBEAM_TEST_STORY=first["story_id"]), capture_output=True, text=True,
                           timeout=400)
    assert (out2 / "result.json").is_file(), again.stderr[-3000:]
    return first, json.loads((out2 / "result.json").read_text()), db


def test_the_childs_flow_runs_by_touch_with_3d_characters_on_the_tablet_profile(flow):
    r, _again, _db = flow
    assert "error" not in r, r.get("error")
    assert not set(r["modules"]) & set(BLOCKED), "a blocked package was imported"
    assert r["paths"] == [10, 10]  # two sketched paths, every stroke sample kept
    (m1, clip1), (_m2, clip2) = r["motions"]
    assert m1 == "walk" and clip1 is None  # by category
    assert r["index_ready"] and clip2 == r["similar"][1]  # picked from "More like this" (the index's answer)
    assert r["play"]["drawn_by"] == "kivy-gl" and r["play"]["render_error"] is None
    assert r["play"]["texture"] == [640, 426] and r["play"]["uploads"] > 20
    p = r["projector"]
    assert p["use_stage"] and p["drawn_by"] == "kivy-gl" and p["render_error"] is None
    assert p["state"] == "tracking" and not p["live"] and not p["problems"]
    assert len(p["character_px"]) == 2  # both characters on stage ...
    assert p["lit_pixels"] > 200  # ... and their light in the projector image


def test_the_story_survives_sigkill_and_reopens_in_3d(flow):
    r, again, db = flow
    with ProfileStore(db) as store:
        saved = store.load_story(r["story_id"])
    assert saved.to_dict() == Story.from_dict(r["story"]).to_dict()
    assert r["story_id"] in again["tiles"]
    assert again["story"] == saved.to_dict()
    assert again["play_again"]["drawn_by"] == "kivy-gl" and again["play_again"]["render_error"] is None
    assert not set(again["modules"]) & set(BLOCKED)


def requirement_problems(requirements: set[str], imported: set[str]) -> list[str]:
    """What is wrong with buildozer.spec's ``requirements`` for a flow that imported the
    top-level modules ``imported``: a third-party module no requirement ships, or a
    requirement none of whose modules was imported."""
    problems = []
    shipped = {m: r for r, mods in RECIPE_MODULES.items() if r in requirements for m in mods}
    shipped.update({m: r for m, r in DESKTOP_STANDINS.items() if r in requirements})  # e.g. ai_edge_litert
    for m in sorted(imported):
        if is_third_party(m) and m not in HARNESS_MODULES and m not in shipped:
            problems.append(f"the flow imported {m!r}, which no requirement ships")
    for req in sorted(requirements - set(NOT_IMPORTED_HERE)):
        standins = {m for m, r in DESKTOP_STANDINS.items() if r == req}
        if not (set(RECIPE_MODULES.get(req, (req,))) | standins) & imported:
            problems.append(f"requirement {req!r} is not imported by the flow")
    return problems


def test_requirement_check_can_fail():
    assert requirement_problems({"python3", "kivy", "numpy"}, {"kivy", "numpy", "os"}) == []
    assert requirement_problems({"python3", "kivy"}, {"kivy", "numpy"}) == \
        ["the flow imported 'numpy', which no requirement ships"]
    assert requirement_problems({"python3", "kivy", "tqdm"}, {"kivy"}) == \
        ["requirement 'tqdm' is not imported by the flow"]


def test_buildozer_requirements_name_exactly_what_the_flow_imported(flow):
    r, again, _db = flow
    cp = configparser.ConfigParser()
    cp.read(REPO / "buildozer.spec")
    requirements = {x.split("==")[0].strip() for x in cp["app"]["requirements"].split(",")}
    imported = set(r["modules"]) | set(again["modules"])
    assert requirement_problems(requirements, imported) == []


def test_the_blocker_refuses_the_desktop_packages(tmp_path):
    code = ("import sys; sys.path.insert(0, 'tests/support'); from tablet_profile import Blocker; "
            "sys.meta_path.insert(0, Blocker()); import numpy\n"
            "for name in ('trimesh', 'pyrender', 'numba', 'OpenGL', 'matplotlib', 'imageio', 'PIL'):\n"
            "    try:\n        __import__(name)\n    except ModuleNotFoundError:\n        continue\n"
            "    raise SystemExit(name + ' imported')\nprint('ok')")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120,
                          env=_env(tmp_path))
    assert proc.returncode == 0 and "ok" in proc.stdout, proc.stdout + proc.stderr


def test_the_android_entry_point_draws_3d_with_kivy_gl(tmp_path):
    """main.py (python-for-android's entry point), imported on the tablet profile, makes
    the app with the Kivy GL renderer factory (not the 2-D fallback)."""
    code = ("import sys; sys.path.insert(0, 'tests/support'); from tablet_profile import Blocker; "
            "sys.meta_path.insert(0, Blocker()); import main; app = main.make_app(); "
            "print(app.renderer_factory.renderer, app.renderer_factory.supports_stage)")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120,
                          env=_env(tmp_path, ANDROID_PRIVATE=str(tmp_path / "private")))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-2:] == ["kivy-gl", "True"]
