"""Shared test fixtures: where the shared CMU data lives, and skipping without it; the one
numba cache; and the ``slow`` mark for every test that reads the shared data.

The fast lane (``bash scripts/test.sh --fast``, i.e. ``pytest -m "not slow"``) leaves out the
tests marked ``slow`` -- each says why beside its mark: those that start the app (or a Kivy
window, camera or video export) in a child process or SIGKILL child savers, the robustness
campaigns (the short CI versions of ``storybeam stress``), bench runs and whole-video or
whole-session pipelines, and every test that reads ``../shared/data`` (marked here, by the
fixture it uses, so a new such test is marked without anyone remembering to). The full suite
(``bash scripts/test.sh``, CI) runs them all.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
# One numba cache: the product's ($NUMBA_CACHE_DIR, else $STORYBEAM_CACHE/numba, else
# ~/.cache/storybeam/numba), the one scripts/setup.sh warms. Importing jit now fixes its
# folder in the environment for this process and every child before any test can change
# STORYBEAM_CACHE (several point it at a tmp_path) -- which would otherwise compile afresh.
import retrieval.dtw.jit  # noqa: E402,F401  (for its side effect on os.environ)

REPO_ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = Path(os.environ.get("STORYBEAM_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))
CMU = SHARED_DATA / "cmu"

#: Fixtures whose tests are marked ``slow`` wherever they are used (directly or through another fixture).
SLOW_FIXTURES = ("cmu_dir",)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark ``slow`` every test that uses a fixture in :data:`SLOW_FIXTURES` (the shared CMU
    data: sweeps over real files, minutes in all); the fast lane runs without ``../shared``."""
    for item in items:
        if any(name in getattr(item, "fixturenames", ()) for name in SLOW_FIXTURES):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(autouse=True)
def _restore_cpu_affinity():
    """Give the process back every CPU it had when a test pinned it to one (the benches pin
    themselves to one core, :func:`lab.bench.act_videos.pin_process_to_one_core`): under
    ``pytest -n`` (scripts/test.sh) a pinned worker would otherwise run every later test
    on that core, beside the other worker."""
    if not hasattr(os, "sched_getaffinity"):
        yield
        return
    cpus = os.sched_getaffinity(0)
    yield
    if os.sched_getaffinity(0) != cpus:
        os.sched_setaffinity(0, cpus)


@pytest.fixture(scope="session")
def cmu_dir() -> Path:
    """The shared CMU folder (``../shared/data/cmu``); skips the test when absent. Every
    test using it is marked ``slow`` (see :func:`pytest_collection_modifyitems`)."""
    if not (CMU / "labels.csv").is_file():
        pytest.skip(f"shared CMU data not found at {CMU} (set STORYBEAM_SHARED_DATA or put ../shared beside the repo)")
    return CMU


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO_ROOT
