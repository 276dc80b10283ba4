"""The suite's own plumbing: a test that pins the process to one CPU (as the benches do)
gets every CPU back afterwards (tests/conftest.py), so under ``pytest -n`` the worker it ran
on does not run the rest of the suite on one core. The two tests run in file order, on one
worker (``--dist loadscope``)."""
from __future__ import annotations

import os

import pytest

pytestmark = pytest.mark.skipif(not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2,
                                reason="needs CPU affinity and at least two CPUs")

_BEFORE: set[int] = set()


def test_a_bench_pins_the_process_to_one_cpu():
    from lab.bench.act_videos import pin_process_to_one_core

    _BEFORE.update(os.sched_getaffinity(0))
    cpu = pin_process_to_one_core()
    assert os.sched_getaffinity(0) == {cpu}


def test_the_next_test_has_every_cpu_back():
    assert _BEFORE, "the pinning test must run first"
    assert os.sched_getaffinity(0) == _BEFORE
