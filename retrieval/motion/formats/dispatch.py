"""One entry point for reading motion files, whatever their format.

``load_motion("walk.bvh")`` or ``load_motion("amc/02_01.amc")`` returns a
:class:`~retrieval.motion.model.Motion`. AMC files need their ASF skeleton: pass
``skeleton_path`` or let :func:`find_asf` look where the CMU layout puts it. Parsed ASF
skeletons are cached (keyed by path, size and modification time), because a dataset
reuses one skeleton for many takes and parsing it each time would dominate load time.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from pathlib import Path

from retrieval.errors import MotionFormatError
from retrieval.motion.formats.acclaim import (
    DEFAULT_AMC_FPS,
    AcclaimSkeleton,
    load_amc,
    load_asf,
)
from retrieval.motion.formats.bvh import load_bvh
from retrieval.motion.model import Motion

#: File extensions :func:`load_motion` understands.
MOTION_EXTENSIONS = (".bvh", ".amc")
_BVH_OPTIONS = {"up_axis", "units", "drop_tpose", "root_offset"}
_AMC_OPTIONS = {"fps"}

_ASF_CACHE_SIZE = 64
_asf_cache: OrderedDict[tuple[str, int, int], AcclaimSkeleton] = OrderedDict()
_asf_lock = threading.Lock()


def load_skeleton(path: str | Path) -> AcclaimSkeleton:
    """The parsed ASF at ``path``, from the cache when the file is unchanged."""
    path = Path(path)
    try:
        st = path.stat()
    except OSError as exc:
        raise MotionFormatError(path, f"cannot read skeleton file: {exc.strerror or exc}") from None
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    with _asf_lock:
        hit = _asf_cache.get(key)
        if hit is not None:
            _asf_cache.move_to_end(key)
            return hit
    asf = load_asf(path)
    with _asf_lock:
        _asf_cache[key] = asf
        while len(_asf_cache) > _ASF_CACHE_SIZE:
            _asf_cache.popitem(last=False)
    return asf


def clear_skeleton_cache() -> None:
    """Forget every cached ASF (tests; long-running processes after editing files)."""
    with _asf_lock:
        _asf_cache.clear()


def find_asf(amc_path: str | Path) -> Path | None:
    """The ASF for an AMC file by CMU naming: for ``.../amc/02_01.amc`` the first that
    exists of ``02_01.asf`` and ``02.asf`` beside it, then in ``../asf/``."""
    amc_path = Path(amc_path)
    stems = [amc_path.stem]
    if "_" in amc_path.stem:
        stems.append(amc_path.stem.split("_", 1)[0])
    for folder in (amc_path.parent, amc_path.parent.parent / "asf"):
        for stem in stems:
            candidate = folder / f"{stem}.asf"
            if candidate.is_file():
                return candidate
    return None


def load_motion(
    path: str | Path,
    skeleton_path: str | Path | None = None,
    **opts,
) -> Motion:
    """Read a ``.bvh`` or ``.amc`` file into a :class:`Motion`.

    ``opts`` go to the format's reader: for BVH ``up_axis``, ``units``, ``drop_tpose``,
    ``root_offset`` (see :func:`retrieval.motion.formats.bvh.load_bvh`); for AMC ``fps`` (default 120,
    CMU's capture rate). Options meant for the other format are ignored, so one call can
    serve a mixed dataset; a name no reader knows raises ``TypeError``. ``skeleton_path``
    is ignored for BVH files. Any problem with the file raises :class:`MotionFormatError`.
    """
    path = Path(path)
    unknown = sorted(set(opts) - _BVH_OPTIONS - _AMC_OPTIONS)
    if unknown:
        raise TypeError(f"load_motion: unknown option(s) {', '.join(unknown)}")
    ext = path.suffix.lower()
    if ext == ".bvh":
        return load_bvh(path, **{k: v for k, v in opts.items() if k in _BVH_OPTIONS})
    if ext == ".amc":
        asf_path = Path(skeleton_path) if skeleton_path is not None else find_asf(path)
        if asf_path is None:
            raise MotionFormatError(path, "no ASF skeleton found (pass skeleton_path)")
        return load_amc(path, load_skeleton(asf_path), fps=opts.get("fps", DEFAULT_AMC_FPS))
    raise MotionFormatError(
        path, f"unsupported motion file type {path.suffix or '(none)'!r} (expected {', '.join(MOTION_EXTENSIONS)})"
    )

