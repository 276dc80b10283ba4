"""Mutation fuzzing of the motion-file loaders (BVH, ASF, AMC).

The contract under test: *every* byte string given to :func:`retrieval.motion.formats.bvh.load_bvh`,
:func:`retrieval.motion.formats.acclaim.load_asf` or :func:`retrieval.motion.formats.acclaim.load_amc` either loads
into a :class:`~retrieval.motion.model.Motion` with finite numbers, or raises
:class:`~retrieval.errors.MotionFormatError` — never another exception, never a hang,
never a memory blow-up. A child's tablet may be handed any file from a USB stick.

Why a structure-aware mutator rather than random bytes: the loaders reject random bytes
on the first line, so random inputs never reach the hierarchy, frame and number code.
Starting from real seed files (the shared CMU takes, or the bundled BVHs) and applying
the damage real files suffer — truncation, bit flips, edited counts, NaN/inf, deep or
duplicated blocks, spliced files — reaches every branch. Seeds are cut to a few frames
so one input takes milliseconds (the per-frame code is vectorised; extra frames add time
but no new paths). Coverage-guided fuzzing with atheris (:mod:`lab.stress.atheris_fuzz`, `storybeam stress
--only atheris`) complements this when atheris is installed.

Inputs run in-process with a per-input alarm (:func:`check_input`); a worker subprocess
(:func:`run_campaign`) adds a watchdog for hangs inside C code the alarm cannot interrupt
and a memory cap (``RLIMIT_AS``), and reports peak RSS. Outcomes are counted, and every
crash or hang is written to disk so it can be replayed.
"""
from __future__ import annotations

import json
import logging
import re
import selectors
import resource
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from app.paths import MOTIONS_DIR
from retrieval.errors import MotionFormatError
from retrieval.motion import positions
from retrieval.motion.formats import MAX_FILE_BYTES, find_asf, load_amc, load_asf, load_bvh

#: Frames kept per seed file (see module docstring).
SEED_FRAMES = 8
#: Per-input time limit (seconds): a valid small file loads in about 10 ms.
INPUT_TIME_LIMIT_S = 5.0
#: Address-space cap of the worker (bytes): a loader needing more on a seed-sized input
#: has a memory blow-up.
WORKER_MEMORY_LIMIT = 3 * 1024**3

KINDS = ("bvh", "asf", "amc")


class InputTimeout(BaseException):
    """Raised by the per-input alarm; a BaseException so no ``except Exception`` in a
    loader can swallow it."""


@dataclass(frozen=True)
class Seed:
    """A fuzzing seed: ``kind`` is the file being mutated; ``companion`` is the file it
    needs (the ASF for an AMC, an AMC for an ASF) and is kept intact."""

    kind: str
    name: str
    data: bytes
    companion: bytes = b""


@dataclass
class FuzzStats:
    inputs: int = 0
    loaded: int = 0
    rejected: int = 0
    crashes: int = 0
    hangs: int = 0
    by_kind: dict[str, int] = field(default_factory=dict)
    by_mutator: dict[str, int] = field(default_factory=dict)
    slowest_input_s: float = 0.0
    peak_rss_mb: float = 0.0
    crash_examples: list[dict] = field(default_factory=list)

    def add(self, other: "FuzzStats") -> None:
        for name in ("inputs", "loaded", "rejected", "crashes", "hangs"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for mine, theirs in ((self.by_kind, other.by_kind), (self.by_mutator, other.by_mutator)):
            for k, v in theirs.items():
                mine[k] = mine.get(k, 0) + v
        self.slowest_input_s = max(self.slowest_input_s, other.slowest_input_s)
        self.peak_rss_mb = max(self.peak_rss_mb, other.peak_rss_mb)
        self.crash_examples.extend(other.crash_examples[: max(0, 20 - len(self.crash_examples))])

    def to_dict(self) -> dict:
        return dict(self.__dict__)


# ----------------------------------------------------------------------------- seeds


def _trim_bvh(data: bytes, frames: int) -> bytes:
    text = data.decode("utf-8", "replace")
    head, sep, body = text.partition("MOTION")
    if not sep:
        return data
    lines = body.splitlines()
    out, kept = [], 0
    for line in lines:
        if line.strip().lower().startswith("frames:"):
            out.append(f"Frames: {frames}")
        elif line.strip().lower().startswith("frame time") or not line.strip():
            out.append(line)
        elif kept < frames:
            out.append(line)
            kept += 1
    return (head + sep + "\n".join(out) + "\n").encode()


def _trim_amc(data: bytes, frames: int) -> bytes:
    out = []
    for line in data.decode("utf-8", "replace").splitlines():
        s = line.strip()
        if s.isdecimal() and int(s) > frames:
            break
        out.append(line)
    return ("\n".join(out) + "\n").encode()


def collect_seeds(cmu_dir: Path | None, bundled_bvh_dir: Path | None, per_kind: int = 12) -> list[Seed]:
    """Seeds from the shared CMU folder when present, else the bundled BVHs.

    A few files of each kind, spread over the folder (different skeletons and exporters),
    each cut to :data:`SEED_FRAMES` frames.
    """
    seeds: list[Seed] = []

    def spread(files: list[Path]) -> list[Path]:
        files = sorted(files)
        if len(files) <= per_kind:
            return files
        idx = np.linspace(0, len(files) - 1, per_kind).round().astype(int)
        return [files[i] for i in idx]

    bvh_files: list[Path] = []
    if cmu_dir is not None and cmu_dir.is_dir():
        bvh_files = [p for sub in ("bvh", "extra") for p in (cmu_dir / sub).glob("*.bvh")]
        for amc in spread(list((cmu_dir / "amc").glob("*.amc"))):
            asf = find_asf(amc)
            if asf is None:
                continue
            amc_bytes = _trim_amc(amc.read_bytes(), SEED_FRAMES)
            asf_bytes = asf.read_bytes()
            seeds.append(Seed("amc", amc.name, amc_bytes, asf_bytes))
            if not any(s.kind == "asf" and s.name == asf.name for s in seeds):
                seeds.append(Seed("asf", asf.name, asf_bytes, amc_bytes))
    if not bvh_files and bundled_bvh_dir is not None and bundled_bvh_dir.is_dir():
        bvh_files = list(bundled_bvh_dir.glob("*.bvh"))
    for p in spread(bvh_files):
        seeds.append(Seed("bvh", p.name, _trim_bvh(p.read_bytes(), SEED_FRAMES)))
    return seeds


# ----------------------------------------------------------------------------- mutators

_NUMBER = re.compile(rb"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")
_NASTY_NUMBERS = [b"5e-324", b"1e-300", b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b"1e308", b"-1e308", b"1e999", b"1e-320",
                  b"0", b"-0", b"0.0", b"1", b"-1", b"99999999999999999999999", b"0x10", b"1_000", b"", b"--1",
                  b"\xd9\xa1", b"\xc2\xb2", b"1e", b".", b"+", b"4294967296", b"9223372036854775808"]
_NASTY_COUNTS = [b"0", b"1", b"2", b"3", b"7", b"-1", b"1000000", b"10000000", b"10000001", b"2147483648",
                 b"18446744073709551616", b"1" + b"0" * 100, b"65", b"64"]
_KEYWORDS = [b"HIERARCHY", b"ROOT", b"JOINT", b"End Site", b"{", b"}", b"OFFSET", b"CHANNELS", b"MOTION",
             b"Frames:", b"Frame Time:", b":root", b":bonedata", b":hierarchy", b":units", b"begin", b"end",
             b"name", b"direction", b"length", b"axis", b"dof", b"order", b"root", b":DEGREES", b":RADIANS",
             b"Xrotation", b"Yposition", b"rx", b"tz", b"l", b"\t", b"\r", b"\n\n", b"#", b"\x00", b"\xff"]


def _m_truncate(rng: np.random.Generator, data: bytes, seeds: list[Seed]) -> bytes:
    return data[: int(rng.integers(0, len(data) + 1))]


def _m_bitflip(rng, data, seeds):
    if not data:
        return data
    buf = bytearray(data)
    for _ in range(int(rng.integers(1, 9))):
        i = int(rng.integers(len(buf)))
        buf[i] ^= 1 << int(rng.integers(8))
    return bytes(buf)


def _m_bytes(rng, data, seeds):
    """Delete, insert or duplicate a span of bytes."""
    n = len(data)
    i = int(rng.integers(0, n + 1))
    j = min(n, i + int(rng.integers(1, 64)))
    op = int(rng.integers(3))
    if op == 0:
        return data[:i] + data[j:]
    if op == 1:
        return data[:i] + bytes(rng.integers(0, 256, int(rng.integers(1, 16)), dtype=np.uint8)) + data[i:]
    return data[:j] + data[i:j] * int(rng.integers(1, 8)) + data[j:]


def _m_number(rng, data, seeds):
    """Replace one to a few numbers with NaN, inf, huge, tiny, empty or non-ASCII digits."""
    spans = [m.span() for m in _NUMBER.finditer(data)]
    if not spans:
        return data
    buf = data
    for _ in range(int(rng.integers(1, 4))):
        a, b = spans[int(rng.integers(len(spans)))]
        new = _NASTY_NUMBERS[int(rng.integers(len(_NASTY_NUMBERS)))]
        buf = buf[:a] + new + buf[b:]
        spans = [m.span() for m in _NUMBER.finditer(buf)] or [(0, 0)]
    return buf


def _m_count(rng, data, seeds):
    """Tamper with a count: ``Frames:``, ``CHANNELS n``, or an AMC frame number."""
    targets = [m.span(1) for m in re.finditer(rb"(?:Frames:|CHANNELS)\s*(\S+)", data)]
    targets += [m.span(1) for m in re.finditer(rb"(?m)^\s*(\d+)\s*$", data)]
    if not targets:
        return data
    a, b = targets[int(rng.integers(len(targets)))]
    return data[:a] + _NASTY_COUNTS[int(rng.integers(len(_NASTY_COUNTS)))] + data[b:]


def _m_header(rng, data, seeds):
    """A nasty ``Frame Time`` (BVH) or ``:units`` length/angle value (ASF)."""
    spans = [m.span(1) for m in re.finditer(rb"(?:Frame Time:|length|mass)[ \t]*(\S+)", data)]
    if not spans:
        return _m_number(rng, data, seeds)
    a, b = spans[int(rng.integers(len(spans)))]
    return data[:a] + _NASTY_NUMBERS[int(rng.integers(len(_NASTY_NUMBERS)))] + data[b:]


def _m_lines(rng, data, seeds):
    """Delete, duplicate or swap lines."""
    lines = data.split(b"\n")
    if len(lines) < 2:
        return data
    i, j = (int(v) for v in rng.integers(0, len(lines), 2))
    op = int(rng.integers(3))
    if op == 0:
        del lines[i]
    elif op == 1:
        lines[i:i] = [lines[j]] * int(rng.integers(1, 4))
    else:
        lines[i], lines[j] = lines[j], lines[i]
    return b"\n".join(lines)


def _m_keyword(rng, data, seeds):
    """Put a format keyword (or a control byte) where another token was."""
    tokens = [m.span() for m in re.finditer(rb"\S+", data)]
    if not tokens:
        return data
    a, b = tokens[int(rng.integers(len(tokens)))]
    return data[:a] + _KEYWORDS[int(rng.integers(len(_KEYWORDS)))] + data[b:]


def _m_splice(rng, data, seeds):
    """The start of this file and the end of another of the same kind."""
    others = [s.data for s in seeds if s.data is not data] or [data]
    other = others[int(rng.integers(len(others)))]
    return data[: int(rng.integers(0, len(data) + 1))] + other[int(rng.integers(0, len(other) + 1)):]


def _m_deep(rng, data, seeds):
    """A hierarchy nested hundreds to thousands deep (a stack-overflow probe)."""
    depth = int(rng.choice([100, 255, 256, 257, 1000, 5000]))
    if data.lstrip().startswith(b"HIERARCHY"):
        body = [b"HIERARCHY", b"ROOT r", b"{", b"OFFSET 0 0 0", b"CHANNELS 6 Xposition Yposition Zposition "
                b"Zrotation Xrotation Yrotation"]
        for k in range(depth):
            body += [b"JOINT j%d" % k, b"{", b"OFFSET 0 1 0", b"CHANNELS 3 Zrotation Xrotation Yrotation"]
        body += [b"End Site", b"{", b"OFFSET 0 1 0", b"}"] + [b"}"] * (depth + 1)
        values = b" ".join([b"0"] * (6 + 3 * depth))
        body += [b"MOTION", b"Frames: 2", b"Frame Time: 0.033333", values, values]
        return b"\n".join(body) + b"\n"
    # ASF (also used for an AMC seed: then the AMC is mutated as-is and the chain is in
    # the companion ASF below, see deep_asf).
    return deep_asf(depth)


def deep_asf(depth: int) -> bytes:
    """An ASF whose bones form one chain ``depth`` long."""
    out = [b":version 1.10", b":name deep", b":units", b"  length 0.45", b"  angle deg", b":root",
           b"  order TX TY TZ RX RY RZ", b"  axis XYZ", b"  position 0 0 0", b"  orientation 0 0 0", b":bonedata"]
    for k in range(depth):
        out += [b"  begin", b"    name b%d" % k, b"    direction 0 1 0", b"    length 1",
                b"    axis 0 0 0 XYZ", b"    dof rx ry rz", b"  end"]
    out += [b":hierarchy", b"  begin", b"    root b0"]
    out += [b"    b%d b%d" % (k, k + 1) for k in range(depth - 1)]
    out += [b"  end"]
    return b"\n".join(out) + b"\n"


MUTATORS: dict[str, Callable[[np.random.Generator, bytes, list[Seed]], bytes]] = {
    "truncate": _m_truncate,
    "bitflip": _m_bitflip,
    "bytes": _m_bytes,
    "number": _m_number,
    "count": _m_count,
    "header": _m_header,
    "lines": _m_lines,
    "keyword": _m_keyword,
    "splice": _m_splice,
    "deep": _m_deep,
}
_MUTATOR_WEIGHTS = {"deep": 0.2}


def mutate(rng: np.random.Generator, seed: Seed, seeds: list[Seed]) -> tuple[bytes, str]:
    """One fuzz input from ``seed``: 1 to 4 stacked mutations; returns (data, names)."""
    names = list(MUTATORS)
    w = np.array([_MUTATOR_WEIGHTS.get(n, 1.0) for n in names])
    picks = rng.choice(len(names), size=int(rng.integers(1, 5)), p=w / w.sum())
    data = seed.data
    same_kind = [s for s in seeds if s.kind == seed.kind]
    for k in picks:
        data = MUTATORS[names[k]](rng, data, same_kind)
    return data, "+".join(names[k] for k in picks)


# ----------------------------------------------------------------------------- one input


@dataclass(frozen=True)
class Outcome:
    status: str  # "loaded" | "rejected" | "crash" | "hang"
    seconds: float
    detail: str = ""


def _alarm(signum, frame):
    raise InputTimeout()


def check_motion(motion) -> None:
    """A loaded motion must be usable: finite numbers, a positive frame rate."""
    if not (np.isfinite(motion.fps) and motion.fps > 0):
        raise AssertionError(f"loaded motion has fps {motion.fps}")
    if motion.n_frames < 1:
        raise AssertionError("loaded motion has no frames")
    for name in ("rotations", "root_translation"):
        if not np.isfinite(getattr(motion, name)).all():
            raise AssertionError(f"loaded motion has non-finite {name}")
    if not np.isfinite(motion.skeleton.offsets).all() or not np.isfinite(motion.skeleton.metres_per_unit):
        raise AssertionError("loaded skeleton has non-finite offsets or units")
    with np.errstate(all="ignore"):
        first = positions(motion.slice(0, 1))  # metres, Y up: what the app uses
    if not np.isfinite(first).all():
        raise AssertionError("joint positions of the loaded motion are not finite")


def load_bytes(kind: str, data: bytes, companion: bytes, workdir: Path):
    """Write the input (and its companion) to ``workdir`` and load it with the real loader."""
    if kind == "bvh":
        path = workdir / "input.bvh"
        path.write_bytes(data)
        return load_bvh(path)
    asf_path, amc_path = workdir / "input.asf", workdir / "input.amc"
    asf_bytes, amc_bytes = (data, companion) if kind == "asf" else (companion, data)
    asf_path.write_bytes(asf_bytes)
    amc_path.write_bytes(amc_bytes)
    return load_amc(amc_path, load_asf(asf_path))


def check_input(kind: str, data: bytes, companion: bytes, workdir: Path,
                time_limit_s: float = INPUT_TIME_LIMIT_S) -> Outcome:
    """Run one input through the loader under a per-input alarm; classify the result.

    ``loaded`` also requires a finite motion (see :func:`check_motion`); anything but a
    :class:`MotionFormatError` is a ``crash`` (the detail is the traceback's tail).
    Must run on the main thread (it uses ``SIGALRM``).
    """
    previous = signal.signal(signal.SIGALRM, _alarm)
    start = time.perf_counter()
    try:
        signal.setitimer(signal.ITIMER_REAL, time_limit_s)
        try:
            motion = load_bytes(kind, data, companion, workdir)
            check_motion(motion)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        return Outcome("loaded", time.perf_counter() - start)
    except MotionFormatError:
        return Outcome("rejected", time.perf_counter() - start)
    except InputTimeout:
        return Outcome("hang", time.perf_counter() - start, f"no result within {time_limit_s} s")
    except BaseException as exc:  # noqa: BLE001 - classifying every other outcome is the point
        if isinstance(exc, KeyboardInterrupt):
            raise
        tail = "".join(traceback.format_exception(exc)[-3:])
        return Outcome("crash", time.perf_counter() - start, tail[-1500:])
    finally:
        signal.signal(signal.SIGALRM, previous)


def peak_rss_mb() -> float:
    """This process's peak resident set size in MB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def fuzz_in_process(seeds: list[Seed], n_inputs: int, rng_seed: int, workdir: Path,
                    crash_dir: Path | None = None, time_limit_s: float = INPUT_TIME_LIMIT_S,
                    on_input: Callable[[Outcome], None] | None = None) -> FuzzStats:
    """Fuzz ``n_inputs`` inputs in this process (deterministic for a given ``rng_seed``)."""
    logging.getLogger("retrieval").setLevel(logging.ERROR)  # "ignoring data after ..." warnings
    rng = np.random.default_rng(rng_seed)
    stats = FuzzStats()
    for _ in range(n_inputs):
        seed = seeds[int(rng.integers(len(seeds)))]
        data, how = mutate(rng, seed, seeds)
        companion = seed.companion
        if how.startswith("deep") and seed.kind == "amc":
            companion = data  # deep_asf output: the ASF is the deep one
            data = seed.data
        outcome = check_input(seed.kind, data, companion, workdir, time_limit_s)
        stats.inputs += 1
        stats.by_kind[seed.kind] = stats.by_kind.get(seed.kind, 0) + 1
        for name in how.split("+"):
            stats.by_mutator[name] = stats.by_mutator.get(name, 0) + 1
        stats.slowest_input_s = max(stats.slowest_input_s, outcome.seconds)
        if outcome.status in ("loaded", "rejected"):
            setattr(stats, outcome.status, getattr(stats, outcome.status) + 1)
        else:
            stats.crashes += outcome.status == "crash"
            stats.hangs += outcome.status == "hang"
            example = {"status": outcome.status, "kind": seed.kind, "seed": seed.name, "mutators": how,
                       "detail": outcome.detail}
            if crash_dir is not None:
                crash_dir.mkdir(parents=True, exist_ok=True)
                stem = f"{outcome.status}-{stats.inputs:07d}-{rng_seed}"
                (crash_dir / f"{stem}.{seed.kind}").write_bytes(data)
                if companion:
                    (crash_dir / f"{stem}.companion").write_bytes(companion)
                example["file"] = str(crash_dir / f"{stem}.{seed.kind}")
            if len(stats.crash_examples) < 20:
                stats.crash_examples.append(example)
        if on_input is not None:
            on_input(outcome)
    stats.peak_rss_mb = peak_rss_mb()
    return stats


# ----------------------------------------------------------------------------- worker campaign


def _worker_main(argv: list[str]) -> int:
    """``python -m lab.stress.fuzz_motion worker CONFIG.json``: fuzz batches, one JSON line each."""
    cfg = json.loads(Path(argv[0]).read_text())
    mem = int(cfg.get("memory_limit", WORKER_MEMORY_LIMIT))
    if mem > 0:
        resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
    seeds = [Seed(s["kind"], s["name"], bytes.fromhex(s["data"]), bytes.fromhex(s["companion"]))
             for s in json.loads(Path(cfg["seeds"]).read_text())]
    workdir = Path(tempfile.mkdtemp(prefix="fuzz-"))
    batch, rng_seed = int(cfg["batch"]), int(cfg["rng_seed"])
    crash_dir = Path(cfg["crash_dir"]) if cfg.get("crash_dir") else None
    for k in range(int(cfg["batches"])):
        stats = fuzz_in_process(seeds, batch, rng_seed + k, workdir, crash_dir, float(cfg["time_limit_s"]))
        sys.stdout.write(json.dumps(stats.to_dict()) + "\n")
        sys.stdout.flush()
    return 0


def run_campaign(seeds: list[Seed], *, inputs: int | None = None, seconds: float | None = None,
                 rng_seed: int = 0, batch: int = 500, crash_dir: Path | None = None,
                 time_limit_s: float = INPUT_TIME_LIMIT_S, memory_limit: int = WORKER_MEMORY_LIMIT,
                 progress: Callable[[int], None] | None = None) -> FuzzStats:
    """Fuzz in one worker subprocess until ``inputs`` inputs or ``seconds`` have passed.

    The worker fuzzes in batches of ``batch`` inputs (each batch a new RNG stream, so a
    batch is reproducible from its seed number) and reports each batch as a JSON line. If
    a batch does not report within ``batch * time_limit_s`` plus a margin, or the worker
    dies (a segfault, the memory cap), the batch is counted as one hang/crash and a fresh
    worker continues with the next batch.
    """
    if inputs is None and seconds is None:
        raise ValueError("give inputs or seconds")
    total = FuzzStats()
    deadline = None if seconds is None else time.monotonic() + seconds
    tmp = Path(tempfile.mkdtemp(prefix="fuzz-campaign-"))
    seeds_file = tmp / "seeds.json"
    seeds_file.write_text(json.dumps([{"kind": s.kind, "name": s.name, "data": s.data.hex(),
                                       "companion": s.companion.hex()} for s in seeds]))
    next_batch = 0

    def wanted() -> bool:
        if inputs is not None and total.inputs >= inputs:
            return False
        return deadline is None or time.monotonic() < deadline

    while wanted():
        remaining = None if inputs is None else inputs - total.inputs
        this_batch = batch if remaining is None else min(batch, remaining)
        n_batches = 1_000_000 if remaining is None else -(-remaining // this_batch)
        cfg = tmp / "config.json"
        cfg.write_text(json.dumps({"seeds": str(seeds_file), "batch": this_batch, "batches": n_batches,
                                   "rng_seed": rng_seed * 1_000_003 + next_batch, "time_limit_s": time_limit_s,
                                   "memory_limit": memory_limit,
                                   "crash_dir": str(crash_dir) if crash_dir else ""}))
        proc = subprocess.Popen([sys.executable, "-m", "lab.stress.fuzz_motion", "worker", str(cfg)],
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            for line in _lines_with_timeout(proc, this_batch * time_limit_s + 60.0):
                stats = FuzzStats(**{**json.loads(line)})
                total.add(stats)
                next_batch += 1
                if progress is not None:
                    progress(stats.inputs)
                if not wanted():
                    break
            else:
                # Timed out or the worker died mid-batch.
                dead = proc.poll()
                total.inputs += 1
                if dead is None:
                    total.hangs += 1
                    total.crash_examples.append({"status": "hang", "detail": f"batch {next_batch} stalled"})
                else:
                    total.crashes += 1
                    total.crash_examples.append({"status": "crash", "detail": f"worker exited {dead} in batch {next_batch}"})
                next_batch += 1
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
    return total


def _lines_with_timeout(proc: subprocess.Popen, timeout: float) -> Iterator[str]:
    """Lines of ``proc.stdout``; stops (without StopIteration being an error) when one
    line takes longer than ``timeout`` or the stream ends."""
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    while True:
        if not sel.select(timeout):
            proc.kill()
            return
        line = proc.stdout.readline()
        if not line:
            return
        yield line


# ----------------------------------------------------------------------------- memory probes


def _probe_files(folder: Path, bvh_seed: bytes | None) -> dict[str, Path]:
    """Large inputs that check the size limits: each is loaded in its own process."""
    folder.mkdir(parents=True, exist_ok=True)
    head = ("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation "
            "Xrotation Yrotation\nEnd Site\n{\nOFFSET 0 100 0\n}\n}\nMOTION\n")
    files = {}
    p = folder / "million_frames.bvh"
    with open(p, "w") as fh:
        fh.write(head + "Frames: 1000000\nFrame Time: 0.033333\n")
        fh.write("0 90 0 1 2 3\n" * 1_000_000)
    files["1e6 frames, 1 joint (loads)"] = p
    p = folder / "million_declared.bvh"
    p.write_text(head + "Frames: 1000000\nFrame Time: 0.033333\n" + "0 90 0 1 2 3\n" * 10)
    files["1e6 frames declared, 10 present"] = p
    parts = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 1 Xrotation"]
    for k in range(2000):
        parts += [f"JOINT j{k}", "{", "OFFSET 0 1 0", "}"]
    p = folder / "joint_bomb.bvh"
    p.write_text("\n".join(parts + ["}", "MOTION", "Frames: 100000", "Frame Time: 0.01"]) + "\n" + "0\n" * 100000)
    files["2000 joints x 1e5 frames in 245 kB"] = p
    if bvh_seed is not None:
        text = bvh_seed.decode("utf-8", "replace")
        header, _, rest = text.partition("MOTION")
        row = [ln for ln in rest.splitlines() if ln.strip() and ":" not in ln][0] + "\n"
        n = (MAX_FILE_BYTES - len(header) - 64) // len(row.encode())
        p = folder / "at_size_limit.bvh"
        with open(p, "w") as fh:
            fh.write(f"{header}MOTION\nFrames: {n}\nFrame Time: 0.033333\n")
            fh.write(row * n)
        files[f"real skeleton at the size limit ({p.stat().st_size / 2**20:.0f} MB)"] = p
    return files


def memory_probes(folder: Path, bvh_seed: bytes | None = None, timeout_s: float = 300.0) -> list[dict]:
    """Load each probe file in a fresh process (capped at :data:`WORKER_MEMORY_LIMIT`);
    report its outcome, seconds and peak RSS. ``ok``: loaded or refused cleanly."""
    if bvh_seed is None:
        bundled = MOTIONS_DIR / "bvh"
        first = next(iter(sorted(bundled.glob("*.bvh"))), None)
        bvh_seed = first.read_bytes() if first else None
    results = []
    for label, path in _probe_files(folder, bvh_seed).items():
        try:
            done = subprocess.run([sys.executable, "-m", "lab.stress.fuzz_motion", "probe", str(path)], capture_output=True,
                                  text=True, timeout=timeout_s)
            info = json.loads(done.stdout.strip().splitlines()[-1]) if done.returncode == 0 else {
                "status": "crash", "detail": done.stderr[-500:]}
        except subprocess.TimeoutExpired:
            info = {"status": "hang"}
        info.update(probe=label, file_mb=round(path.stat().st_size / 2**20, 1))
        info["ok"] = info["status"] in ("loaded", "rejected")
        results.append(info)
        path.unlink(missing_ok=True)
    return results


def _probe_main(path: str) -> int:
    resource.setrlimit(resource.RLIMIT_AS, (WORKER_MEMORY_LIMIT, WORKER_MEMORY_LIMIT))
    outcome = check_input("bvh", Path(path).read_bytes(), b"", Path(tempfile.mkdtemp()), time_limit_s=240.0)
    print(json.dumps({"status": outcome.status, "seconds": round(outcome.seconds, 2),
                      "peak_rss_mb": round(peak_rss_mb(), 1), "detail": outcome.detail[-300:]}))
    return 0


if __name__ == "__main__":  # pragma: no cover - entry point of the worker subprocesses
    if len(sys.argv) >= 3 and sys.argv[1] == "worker":
        sys.exit(_worker_main(sys.argv[2:]))
    if len(sys.argv) == 3 and sys.argv[1] == "probe":
        sys.exit(_probe_main(sys.argv[2]))
    sys.exit("usage: python -m lab.stress.fuzz_motion worker CONFIG.json | probe FILE.bvh")
