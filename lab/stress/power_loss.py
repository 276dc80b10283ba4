"""Power-loss harness: replay the product's recorded system calls onto simulated
post-crash disks and reopen each with the product's own loading code.

A kill keeps the operating system's page cache; a power cut, a flat battery or a USB
stick pulled early does not. In the spirit of ALICE (Pillai et al., OSDI 2014) and
CrashMonkey (Mohan et al., OSDI 2018):

1. **Record.** A workload process (:func:`~lab.stress.power_workload.workload`, ``python -m
   lab.stress.power_workload workload ...``) drives the real product code through its public API: it creates,
   edits and deletes stories (:class:`~app.story.storage.ProfileStore`), stores assets,
   changes settings, exports and imports story packages, exports the activity CSV and
   saves the rig's calibration (:meth:`ar.calibration.CameraCalibration.save`). It runs
   under ``strace -f -y -xx`` (every byte of every ``write``/``pwrite64``, every
   ``openat``, ``rename``, ``unlink``, ``mkdir``, ``ftruncate``, ``fsync``/``fdatasync``
   with the file each descriptor names). Before each call it writes an *intent* marker
   and after the call returns an *ack* marker to a log file outside the simulated disk;
   those writes are in the same trace, so each marker sits at its exact place among the
   file-system calls. What is recorded is the product's code path: the workload only
   calls the public API.
2. **Model.** The trace under the disk's folder becomes a list of operations on inodes
   (data: write, truncate; names: create, mkdir, rename, unlink; barriers: fsync). At a
   cut point *k* an operation is *durable* when a later barrier before *k* covers it:
   data by an fsync of the same file; a name by an fsync of its folder (**posix** model:
   POSIX and Linux promise nothing more) or by any fsync at all (**ordered** model: a
   journalling file system such as ext4 commits all earlier metadata with any fsync, and
   persists the rest in order). Everything else is volatile, and each cut point gives
   several disks: ``kill`` (all applied: the page cache survives), ``drop`` (only durable
   operations), ``torn`` (volatile operations persist in order up to a random point, the
   write at that point torn at a 512-byte sector: its first sectors new, the rest old or
   zero) and ``reorder`` (a random subset of the volatile operations; the ordered model
   keeps names as a prefix). SQLite's ``-shm`` file is dropped (it lives in memory).
3. **Check.** Each disk is written to a folder and opened with the product's code:
   ``ProfileStore`` (``open_failures``), ``PRAGMA integrity_check``
   (``integrity_failures``), ``load_story``/``get_setting``/``read_asset``,
   ``read_package`` for exported packages and ``CameraCalibration.load``. For every key
   the app had acknowledged before the cut, what is read must be the acknowledged
   version or one in flight at the cut (``acked_lost`` otherwise, per kind); anything a
   loader accepts must be some version the app wrote (``corrupt_accepted`` otherwise);
   an imported story must never be there without its assets.

A **control** run records the same workload with a weakened setting (no folder fsync in
:mod:`retrieval.durable`) and must lose acknowledged data under the posix model: it shows
the harness can see a loss. ``storybeam stress power-loss --json OUT`` runs it all;
``tests/robust/test_power_loss.py`` runs a short version.

The parts: :mod:`lab.stress.power_workload` (the recorded process), :mod:`lab.stress.syscall_trace`
(step 1: strace and the operations), :mod:`lab.stress.crash_states` (step 2: the disks);
this module checks each disk (step 3) and runs the campaign.
"""
from __future__ import annotations

import random
import shutil
import sqlite3
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

from app.story.storage import ProfileStore, StorageError, read_package
from ar.calibration import CameraCalibration
from ar.errors import CalibrationError
from lab.stress.crash_states import MODELS, SECTOR, VARIANTS, Disk, crash_disk, durable_flags, sectors
from lab.stress.power_workload import (
    CALIBRATION,
    EXPORTS,
    FOCUSES,
    KINDS,
    PROFILE,
    WEAKENINGS,
    PowerLossError,
    calibration_digest,
    digest,
    package_digest,
    story_digest,
    workload,
)
from lab.stress.syscall_trace import TRACED, Op, Recorder, record

__all__ = [
    "SECTOR", "VARIANTS", "MODELS", "KINDS", "TRACED", "WEAKENINGS", "FOCUSES", "PROFILE", "CALIBRATION", "EXPORTS",
    "PowerLossError", "digest", "story_digest", "package_digest", "calibration_digest", "workload",
    "Op", "Recorder", "record", "durable_flags", "Disk", "sectors", "crash_disk",
    "Expectation", "expectations", "Tally", "read_key", "check_state", "cut_points", "run_crash_states",
    "run_power_loss",
]


@dataclass
class Expectation:
    """What may be read for one key at a cut: ``accept`` (digests; ``-`` absent, ``*``
    anything), ``acked`` (some version was acknowledged), ``ever`` (every version written)."""

    accept: set[str] = field(default_factory=set)
    acked: bool = False
    ever: set[str] = field(default_factory=set)


def expectations(ops: list[Op], cut: int) -> dict[tuple[str, str], Expectation]:
    """From the markers before the cut: per (kind, key), the acceptable versions."""
    out: dict[tuple[str, str], Expectation] = {}
    for op in ops[:cut]:
        if op.kind != "mark":
            continue
        for line in op.text.splitlines():
            tag, kind, key, value = line.split(" ")
            e = out.setdefault((kind, key), Expectation())
            if tag == "I":
                e.ever.add(value)
                if value == "?":  # the content is only known at the ack (the activity CSV)
                    e.accept.add("*")
                else:
                    e.accept.add(value)
            else:
                e.ever.add(value)
                e.accept = {value}
                e.acked = True
    for e in out.values():
        if not e.acked:
            e.accept |= {"-"}  # never acknowledged: may be absent
    return out


@dataclass
class Tally:
    crash_states: int = 0
    checks: int = 0
    acked_lost: dict[str, int] = field(default_factory=lambda: {k: 0 for k in KINDS})
    corrupt_accepted: int = 0
    open_failures: int = 0
    integrity_failures: int = 0
    by_variant: dict[str, int] = field(default_factory=dict)
    lost_by_variant: dict[str, int] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)

    def fail(self, what: str, where: str, serious: bool = False) -> None:
        """Keep an example: the first 20 of each sort (losses; damage, open and integrity)."""
        if sum(p.startswith("!") for p in self.problems) < 20 if serious else len(
                [p for p in self.problems if not p.startswith("!")]) < 20:
            self.problems.append(f"{'!' if serious else ''}{where}: {what}")

    def to_dict(self) -> dict:
        return {"crash_states": self.crash_states, "checks": self.checks, "acked_lost": dict(self.acked_lost),
                "corrupt_accepted": self.corrupt_accepted, "open_failures": self.open_failures,
                "integrity_failures": self.integrity_failures, "by_variant": dict(self.by_variant),
                "lost_by_variant": dict(self.lost_by_variant), "problems": list(self.problems)}


def read_key(kind: str, key: str, folder: Path, store: ProfileStore | None) -> str:
    """What the product's own loading code reads for one key: a digest, ``-`` (absent)
    or ``!`` (refused as damaged)."""
    if kind == "stories":
        if store is None or not store.has_story(key):
            return "-"
        try:
            return story_digest(store.load_story(key))
        except StorageError:
            return "!"
    if kind == "settings":
        value = store.get_setting(key) if store is not None else None
        return "-" if value is None else digest(value)
    if kind == "assets":
        sid, name = key.split("/")
        try:
            return digest(store.read_asset(sid, name)) if store is not None else "-"
        except StorageError:
            return "-"
    if kind == "packages":
        if not (folder / key).exists():
            return "-"
        try:
            story, files = read_package(folder / key)
        except StorageError:
            return "!"
        return package_digest(story, files)
    if kind == "calibration":
        if not (folder / key).exists():
            return "-"
        try:
            return calibration_digest(CameraCalibration.load(folder / key))
        except CalibrationError:
            return "!"
    if kind == "exports":
        return digest((folder / key).read_bytes()) if (folder / key).exists() else "-"
    raise PowerLossError(f"unknown kind {kind}")


def check_state(disk: Disk, expected: dict[tuple[str, str], Expectation], folder: Path, tally: Tally,
                where: str) -> None:
    """Write the disk to ``folder``, open it with the product's code and check every key."""
    shutil.rmtree(folder, ignore_errors=True)
    disk.write_to(folder)
    tally.crash_states += 1
    store = None
    db = folder / PROFILE
    try:
        store = ProfileStore(db)
    except StorageError as exc:
        tally.open_failures += 1
        tally.fail(f"open failed: {exc}", where, serious=True)
    try:
        if store is not None:
            with sqlite3.connect(db) as conn:
                result = conn.execute("PRAGMA integrity_check").fetchone()[0]
            if result != "ok":
                tally.integrity_failures += 1
                tally.fail(f"integrity_check: {result}", where, serious=True)
        for (kind, key), e in sorted(expected.items()):
            if kind == "imports":
                continue
            got = read_key(kind, key, folder, store)
            tally.checks += 1
            if got not in ("-", "!") and "*" not in e.accept and got not in e.ever:
                tally.corrupt_accepted += 1
                tally.fail(f"{kind} {key}: accepted content that was never written", where, serious=True)
            elif "*" not in e.accept and got not in e.accept and e.acked:
                tally.acked_lost[kind] += 1
                tally.fail(f"{kind} {key}: acknowledged {sorted(e.accept)}, read {got}", where)
        for (kind, key), e in expected.items():  # an imported story is never there without its assets
            if kind != "imports" or store is None:
                continue
            tally.checks += 1
            names = [n for v in e.accept if v != "-" for n in v.split(",") if n != "none"]
            if read_key("stories", key, folder, store) != "-":
                missing = [n for n in names if read_key("assets", f"{key}/{n}", folder, store) == "-"]
                if missing:
                    tally.integrity_failures += 1
                    tally.fail(f"imported story {key} without its assets {missing}", where, serious=True)
    finally:
        if store is not None:
            store.close()



def cut_points(ops: list[Op], n: int, rng: random.Random) -> list[int]:
    """``n`` cut points (op counts), spread over the trace: every op boundary is a
    candidate, and the ends are always included."""
    total = len(ops)
    if n >= total + 1:
        return list(range(total + 1))
    picks = set(rng.sample(range(1, total), max(0, n - 2)))
    return sorted(picks | {0, total})


def run_crash_states(ops: list[Op], cuts: int, seed: int, work: Path, label: str,
                     progress: Callable[[int], None] | None = None,
                     variants: Iterable[str] = ("kill",) + tuple(f"{v}/{m}" for m in MODELS for v in VARIANTS)
                     ) -> Tally:
    """Build and check the crash states of one recorded trace."""
    rng = random.Random(seed)
    tally = Tally()
    folder = work / f"state-{label}"
    for cut in cut_points(ops, cuts, rng):
        expected = expectations(ops, cut)
        for v in variants:
            variant, _, model = v.partition("/")
            disk = crash_disk(ops, cut, variant, model or "posix", rng)
            lost = sum(tally.acked_lost.values())
            check_state(disk, expected, folder, tally, f"{label} cut {cut}/{len(ops)} {v}")
            tally.by_variant[v] = tally.by_variant.get(v, 0) + 1
            tally.lost_by_variant[v] = tally.lost_by_variant.get(v, 0) + sum(tally.acked_lost.values()) - lost
            if progress:
                progress(1)
    shutil.rmtree(folder, ignore_errors=True)
    return tally


def _merge(a: Tally, b: Tally) -> Tally:
    a.crash_states += b.crash_states
    a.checks += b.checks
    for k in KINDS:
        a.acked_lost[k] += b.acked_lost[k]
    a.corrupt_accepted += b.corrupt_accepted
    a.open_failures += b.open_failures
    a.integrity_failures += b.integrity_failures
    for k, v in b.by_variant.items():
        a.by_variant[k] = a.by_variant.get(k, 0) + v
    for k, v in b.lost_by_variant.items():
        a.lost_by_variant[k] = a.lost_by_variant.get(k, 0) + v
    a.problems += [p for p in b.problems if p not in a.problems][: max(0, 40 - len(a.problems))]
    return a


def run_power_loss(work: Path, workloads: int = 2, steps: int = 60, cuts: int = 150, seed: int = 0,
                   control: str = "no-dir-fsync", control_cuts: int | None = None,
                   progress: Callable[[int], None] | None = None) -> dict:
    """The campaign: ``workloads`` recorded runs of ``steps`` operations, ``cuts`` cut
    points each, 7 disks per cut point (kill; drop/torn/reorder under ordered and posix);
    then the control. Returns the JSON summary."""
    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    total = Tally()
    ops_recorded = 0
    for w in range(workloads):
        ops = record(work / "disk", seed + w, steps, work=work)
        ops_recorded += len(ops)
        _merge(total, run_crash_states(ops, cuts, seed + w, work, f"workload {seed + w}", progress))
    ctl_ops = record(work / "disk", seed, steps, weaken=control, work=work)
    ctl = run_crash_states(ctl_ops, control_cuts or cuts, seed, work, f"control {control}", progress)
    out = total.to_dict()
    out.update({"workloads": workloads, "steps_per_workload": steps, "cut_points_per_workload": cuts,
                "ops_recorded": ops_recorded, "seed": seed, "recording": "strace -f -y -xx (every byte written)",
                "models": list(MODELS), "variants": ["kill", *VARIANTS],
                "control": {"setting": control, **ctl.to_dict()},
                "seconds": round(time.time() - t0, 1)})
    out["failures"] = (sum(out["acked_lost"].values()) + out["corrupt_accepted"] + out["open_failures"]
                       + out["integrity_failures"] + (0 if sum(ctl.acked_lost.values()) > 0 else 1))
    return out
