"""Random-touch monkey on the real app under offscreen Kivy (short CI version of
`storybeam stress --only monkey`): no crash, no stuck state, no lost story."""
from __future__ import annotations

import json
import sys

import pytest

from lab.stress import monkey

pytestmark = pytest.mark.slow  # the monkey campaign: the real app in a child process, 20 s


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    return monkey.run_monkey(tmp_path_factory.mktemp("monkey"), seconds=20, seed=3)


def test_monkey_finds_no_crash_stuck_state_or_lost_story(report):
    assert report.get("error") is None, report.get("error")
    assert report["crashes"] == 0, report["crash_examples"]
    assert report["hangs"] == 0 and report["stuck"] == 0, report["stuck_examples"]
    assert report["stories_lost"] == 0


def test_monkey_really_used_the_app(report):
    """It must have touched things, left the home screen and saved stories, or it proves nothing."""
    assert report["actions"] >= 15 and report["taps"] >= 8
    assert len(report["screens_seen"]) >= 2
    assert report["saves"] >= 1


def test_monkey_reports_a_crashing_app(tmp_path, monkeypatch):
    """The harness can fail: an app that dies without a result is reported as a crash."""
    real_popen = monkey.subprocess.Popen

    def fake_popen(cmd, **kw):
        return real_popen([sys.executable, "-c", "import sys; sys.exit(5)"], **kw)

    monkeypatch.setattr(monkey.subprocess, "Popen", fake_popen)
    out = monkey.run_monkey(tmp_path, seconds=1)
    assert out["crashes"] == 1 and out["failures"] >= 1 and "exit 5" in out["error"]
    json.dumps(out)
