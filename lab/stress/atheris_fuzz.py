"""Coverage-guided fuzzing of the BVH and ASF/AMC loaders with atheris (libFuzzer).

Complements :mod:`lab.stress.fuzz_motion` (structure-aware mutations): libFuzzer keeps the
inputs that reach new branches of the instrumented ``retrieval`` code. The contract is the
same: any input loads into a finite motion or raises
:class:`~retrieval.errors.MotionFormatError`.

atheris is an optional developer tool (``pip install atheris``, or the ``fuzz`` extra);
`storybeam stress --only atheris` runs :func:`run_atheris_campaign`, which starts this
module as a child process::

    python -m lab.stress.atheris_fuzz -runs=20000 -max_total_time=60 -timeout=5 -rss_limit_mb=3000

A child, because libFuzzer ends its process when it is done, and because the loaders must
be imported inside :func:`atheris.instrument_imports` to be instrumented -- something only
a fresh interpreter guarantees. The first byte of an input picks the target (BVH, ASF with
a fixed AMC, AMC with a fixed ASF); the corpus is seeded from the same files as the
mutation fuzzer. A crash, hang (``-timeout``) or memory blow-up (``-rss_limit_mb``) stops
libFuzzer and leaves the input as ``crash-*``, ``timeout-*`` or ``oom-*`` in the work folder.
"""
from __future__ import annotations

import importlib.util
import logging
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Callable

from app.paths import MOTIONS_DIR, REPO_ROOT, SHARED_CMU
from retrieval.errors import MotionFormatError, StoryBeamError

#: The command that installs the fuzzer (what the error says when it is missing).
INSTALL_HINT = "pip install atheris"
#: Per-input limits handed to libFuzzer: seconds before an input counts as a hang, and MB of RSS.
INPUT_TIMEOUT_S = 10
RSS_LIMIT_MB = 3000
#: Artifact prefixes libFuzzer writes, and what each means.
ARTIFACTS = {"crash": "crashes", "timeout": "hangs", "oom": "ooms", "leak": "crashes", "slow-unit": "slow"}


def atheris_available() -> bool:
    """Whether atheris can be imported (it is not installed by default)."""
    return importlib.util.find_spec("atheris") is not None


def require_atheris() -> None:
    """Raise a :class:`StoryBeamError` telling the user how to install atheris if it is missing."""
    if not atheris_available():
        raise StoryBeamError(f"the atheris harness needs atheris, which is not installed: {INSTALL_HINT} "
                             "(or install StoryBeam with the 'fuzz' extra)")


def run_atheris_campaign(work: Path, seconds: float = 60.0, runs: int | None = None, seed: int = 0,
                         progress: Callable[[str], None] | None = None) -> dict:
    """Run libFuzzer on the loaders in a child process for ``seconds`` (or ``runs`` inputs).

    The child runs in ``work`` (corpus and artifacts land there). Its output is parsed for
    the final statistics (``stat::number_of_executed_units``, ``stat::peak_rss_mb``, ...); every
    artifact file counts as a finding. ``progress`` receives each line libFuzzer prints.
    Raises :class:`StoryBeamError` when atheris is not installed.
    """
    require_atheris()
    work.mkdir(parents=True, exist_ok=True)
    flags = [f"-max_total_time={max(1, int(seconds))}", f"-seed={seed + 1}",  # libFuzzer: seed 0 = random
             f"-timeout={INPUT_TIMEOUT_S}", f"-rss_limit_mb={RSS_LIMIT_MB}", "-print_final_stats=1",
             f"-artifact_prefix={work}/"]
    if runs is not None:
        flags.append(f"-runs={runs}")
    cmd = [sys.executable, "-m", __name__, *flags]
    proc = subprocess.Popen(cmd, cwd=str(REPO_ROOT), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            errors="replace")
    tail: list[str] = []
    assert proc.stdout is not None
    for line in proc.stdout:
        tail = (tail + [line.rstrip()])[-40:]
        if progress is not None:
            progress(line.rstrip())
    rc = proc.wait()
    return summarize(work, "\n".join(tail), rc)


def summarize(work: Path, output: str, returncode: int) -> dict:
    """The campaign's figures from libFuzzer's final output and the artifacts in ``work``."""
    stats = {key: int(value) for key, value in re.findall(r"stat::(\w+):\s*(\d+)", output)}
    found = dict.fromkeys(ARTIFACTS.values(), 0)
    files = []
    for path in sorted(work.iterdir()) if work.is_dir() else []:
        kind = next((ARTIFACTS[k] for k in ARTIFACTS if path.name.startswith(k + "-")), None)
        if kind is not None and path.is_file():
            files.append(path)
            found[kind] += 1
    out: dict = {
        "inputs": stats.get("number_of_executed_units", 0),
        "crashes": found["crashes"],
        "hangs": found["hangs"],
        "ooms": found["ooms"],
        "peak_rss_mb": stats.get("peak_rss_mb"),
        "slowest_input_s": stats.get("slowest_unit_time_sec"),
        "new_units": stats.get("new_units_added"),
        "artifacts": [str(p) for p in files],
        "exit_code": returncode,
    }
    # A non-zero exit without an artifact (the child failed to start, say) is still a failure.
    problems = found["crashes"] + found["hangs"] + found["ooms"]
    out["failures"] = problems or int(returncode != 0)
    if returncode != 0 and not problems:
        out["error"] = output[-1500:]
    return out


def main(argv: list[str]) -> None:  # pragma: no cover - runs in the child process, never returns
    """Instrument the loaders, seed a corpus and hand control to libFuzzer."""
    # optional: atheris (pip install atheris), the coverage-guided fuzzer; only this harness needs it
    import atheris

    # deferred: the loaders must be first imported inside instrument_imports() to be instrumented
    with atheris.instrument_imports(include=["retrieval"]):
        from lab.stress import fuzz_motion  # deferred: imports the loaders, instrumented here

    logging.getLogger("retrieval").setLevel(logging.ERROR)  # "ignoring data after ..." warnings
    work = Path(tempfile.mkdtemp(prefix="atheris-motion-"))
    seeds = fuzz_motion.collect_seeds(SHARED_CMU if SHARED_CMU.is_dir() else None, MOTIONS_DIR / "bvh")
    asf = next((s.data for s in seeds if s.kind == "asf"), b"")
    amc = next((s.data for s in seeds if s.kind == "amc"), b"")
    kinds = [k for k in ("bvh", "asf", "amc") if k == "bvh" or (asf and amc)]

    def test_one_input(data: bytes) -> None:
        if not data:
            return
        kind = kinds[data[0] % len(kinds)]
        companion = amc if kind == "asf" else asf if kind == "amc" else b""
        try:
            motion = fuzz_motion.load_bytes(kind, data[1:], companion, work)
        except MotionFormatError:
            return
        fuzz_motion.check_motion(motion)

    corpus = work / "corpus"
    corpus.mkdir()
    for k, seed in enumerate(seeds):
        if seed.kind in kinds:
            (corpus / f"seed{k}").write_bytes(bytes([kinds.index(seed.kind)]) + seed.data)
    atheris.Setup([sys.argv[0], *argv, str(corpus)], test_one_input)
    atheris.Fuzz()


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1:])
