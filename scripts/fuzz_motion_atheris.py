"""Coverage-guided fuzzing of the BVH and ASF/AMC loaders with atheris (libFuzzer).

Complements retrieval/fuzz.py (structure-aware mutations, run by `storybeam stress`):
libFuzzer keeps inputs that reach new branches of the instrumented loader code. atheris
is an optional developer tool (`pip install atheris`); the contract is the same: any
input loads or raises MotionFormatError. A crash stops libFuzzer and writes the input as
``crash-<sha1>`` in the current folder; ``-timeout`` reports hangs and ``-rss_limit_mb``
memory blow-ups.

    .venv/bin/python scripts/fuzz_motion_atheris.py -runs=20000 -timeout=5 -rss_limit_mb=3000

The first byte of an input picks the target (BVH, ASF with a fixed AMC, AMC with a fixed
ASF); the corpus folder is seeded from the same seed files as retrieval/fuzz.py.
"""
from __future__ import annotations

import logging
import sys
import tempfile
from pathlib import Path

import atheris

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

# The loaders must be imported here, inside the context, to be instrumented
# (retrieval.fuzz imports them lazily).
with atheris.instrument_imports(include=["retrieval"]):
    from retrieval import textfile  # noqa: F401
    from app.stress import fuzz_motion as fuzz
    from retrieval.errors import MotionFormatError

logging.getLogger("retrieval").setLevel(logging.ERROR)
WORK = Path(tempfile.mkdtemp(prefix="atheris-motion-"))
_SEEDS = fuzz.collect_seeds(REPO.parent / "shared" / "data" / "cmu", REPO / "assets" / "motions" / "bvh")
_ASF = next((s.data for s in _SEEDS if s.kind == "asf"), b"")
_AMC = next((s.data for s in _SEEDS if s.kind == "amc"), b"")
_KINDS = [k for k in ("bvh", "asf", "amc") if k == "bvh" or (_ASF and _AMC)]


def test_one_input(data: bytes) -> None:
    if not data:
        return
    kind = _KINDS[data[0] % len(_KINDS)]
    companion = _AMC if kind == "asf" else _ASF if kind == "amc" else b""
    try:
        motion = fuzz.load_bytes(kind, data[1:], companion, WORK)
    except MotionFormatError:
        return
    fuzz._check_motion(motion)


def write_corpus(folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for k, seed in enumerate(_SEEDS):
        if seed.kind in _KINDS:
            (folder / f"seed{k}").write_bytes(bytes([_KINDS.index(seed.kind)]) + seed.data)


if __name__ == "__main__":
    corpus = WORK / "corpus"
    write_corpus(corpus)
    atheris.Setup(sys.argv + [str(corpus)], test_one_input)
    atheris.Fuzz()
