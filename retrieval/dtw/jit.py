"""numba, optional, and where its compiled kernels are cached.

The one place StoryBeam imports numba: every compiled kernel module takes ``HAVE_NUMBA``
and ``numba`` from here, so a machine without numba (python-for-android) gets the numpy
paths everywhere, and every kernel shares one cache folder keyed on all their sources.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

#: The modules that define compiled kernels (their numba caches must move together: the
#: kernels call one another across them). A test checks that every module using
#: ``numba.njit`` is listed.
KERNEL_MODULES = (
    "dtw/block_corner.py", "dtw/kernels.py", "dtw/range_bound.py", "dtw/rerank.py", "dtw/rowscan.py",
    "dtw/runlength.py", "dtw/subsequence.py",
    "search/bounds.py", "search/cascade.py", "search/order.py", "search/packed.py", "search/segment_bound.py",
    "search/summary.py",
)


def kernel_cache_dir(root: str | os.PathLike[str], sources: str | os.PathLike[str] | None = None) -> Path:
    """A numba cache folder under ``root`` for this version of the kernels' sources.

    numba keys a cached function on its own source file only, so a kernel that calls one
    defined in another file keeps running the old compiled callee after that file changes
    (it happened while tuning the run-length DP: the edited DP was not used until the
    cache was cleared). One folder per hash of all the kernel modules' sources makes every
    edit, ``git pull`` or upgrade compile afresh; the previous folders stay until removed.
    ``sources``: the folder the :data:`KERNEL_MODULES` paths are relative to (the
    ``retrieval`` package by default)."""
    here = Path(sources) if sources is not None else Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for name in KERNEL_MODULES:
        try:
            digest.update((here / name).read_bytes())
        except OSError:  # pragma: no cover - a packaged build without sources
            digest.update(name.encode())
    return Path(root) / digest.hexdigest()[:16]


def _default_cache_root() -> Path:
    return Path(os.environ.get("STORYBEAM_CACHE", Path.home() / ".cache" / "storybeam")) / "numba"


# Where the compiled kernels are cached: NUMBA_CACHE_DIR names the root if set, else
# $STORYBEAM_CACHE/numba (default ~/.cache/storybeam/numba) -- the one scripts/setup.sh warms
# and the tests read (tests/conftest.py imports this first); either way one sub-folder per
# version of the sources (see kernel_cache_dir). The root is remembered for child
# processes, which inherit the environment and must land in the same sub-folder.
_cache_root = (os.environ.get("STORYBEAM_NUMBA_CACHE_ROOT") or os.environ.get("NUMBA_CACHE_DIR")
               or str(_default_cache_root()))
os.environ["STORYBEAM_NUMBA_CACHE_ROOT"] = _cache_root
os.environ["NUMBA_CACHE_DIR"] = str(kernel_cache_dir(_cache_root))

try:  # numba is optional: Android and minimal installs use the numpy path.
    import numba

    HAVE_NUMBA = True
    numba.config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]  # in case numba was imported first
except ImportError:  # pragma: no cover - exercised only where numba is absent
    numba = None
    HAVE_NUMBA = False

BACKENDS = ("auto", "numba", "numpy")


