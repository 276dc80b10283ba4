"""app.services.BackgroundLoad: the background loads of the pose search, the groups and Act it out."""
from __future__ import annotations

import threading

import pytest

from app.services import BackgroundLoad


class _Load(BackgroundLoad):
    thread_name = "test-load"

    def __init__(self, fail: bool = False):
        super().__init__()
        self.gate = threading.Event()
        self.runs = 0
        self.fail = fail
        self.thread_seen: str | None = None

    def _work(self) -> None:
        self.runs += 1
        self.thread_seen = threading.current_thread().name
        self.gate.wait(5)
        if self.fail:
            raise RuntimeError("boom")


def test_callbacks_wait_for_the_end_and_run_once_each():
    load = _Load()
    calls: list[str] = []
    load.when_ready(lambda: calls.append("early"))
    load.start()
    load.start()  # idempotent
    assert not load.ready and calls == []
    load.gate.set()
    assert load.wait(5) and load.ready
    load.when_ready(lambda: calls.append("late"))  # after the end: at once
    assert calls == ["early", "late"]
    assert load.runs == 1 and load.thread_seen == "test-load"


@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")
def test_a_failing_load_still_ends():
    # an unexpected error still ends the load (callbacks run), then surfaces in the thread
    load = _Load(fail=True)
    calls: list[int] = []
    load.when_ready(lambda: calls.append(1))
    load.gate.set()
    assert load.wait(5) and load.ready and calls == [1]
    load._thread.join(5)  # let the thread finish raising inside this test


def test_the_base_class_has_no_work_of_its_own():
    with pytest.raises(NotImplementedError):
        BackgroundLoad()._work()
