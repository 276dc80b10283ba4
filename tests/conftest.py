"""Shared test fixtures: where the shared CMU data lives, and skipping without it."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("NUMBA_CACHE_DIR", str(Path(__file__).resolve().parent.parent / ".numba_cache"))

REPO_ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = Path(os.environ.get("STORYBEAM_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))
CMU = SHARED_DATA / "cmu"


@pytest.fixture(scope="session")
def cmu_dir() -> Path:
    """The shared CMU folder (``../shared/data/cmu``); skips the test when absent."""
    if not (CMU / "labels.csv").is_file():
        pytest.skip(f"shared CMU data not found at {CMU} (set STORYBEAM_SHARED_DATA or put ../shared beside the repo)")
    return CMU


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO_ROOT
