"""The random-touch monkey behind the teacher PIN (short CI version of
`storybeam stress --only monkey-teacher`): it gets in by tapping the PIN on the real pad
and spends its time on the teacher screens, with no crash, stuck state or lost story."""
from __future__ import annotations

import pytest

from lab.stress import monkey

pytestmark = pytest.mark.slow  # the monkey campaign: the real app in a child process, 25 s


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    return monkey.run_monkey(tmp_path_factory.mktemp("monkey_teacher"), seconds=25, seed=5, teacher=True)


def test_teacher_monkey_finds_no_crash_stuck_state_or_lost_story(report):
    assert report.get("error") is None, report.get("error")
    assert report["crashes"] == 0, report["crash_examples"]
    assert report["hangs"] == 0 and report["stuck"] == 0, report["stuck_examples"]
    assert report["stories_lost"] == 0


def test_teacher_monkey_really_got_behind_the_pin(report):
    """It must have typed the PIN on the pad and worked on the teacher screens, or it
    proves nothing about them."""
    assert report["teacher"] is True
    assert report["unlock_tries"] >= 1 and report["unlocks"] >= 1  # typed on the pad, reached teacher mode
    assert report["screens_seen"].get("teacher", 0) >= 5
    assert report["teacher_actions"] >= 5
