"""Step 2 of the power-loss harness (:mod:`lab.stress.power_loss`): the disks a power cut
can leave after a recorded trace.

At a cut point an operation is *durable* when a later barrier before the cut covers it
(:func:`durable_flags`, under the **posix** or the **ordered** model); :func:`crash_disk`
builds one :class:`Disk` per variant: ``kill`` (all applied), ``drop`` (only durable
operations), ``torn`` (volatile operations in order up to a random point, that write torn
at a :data:`SECTOR` boundary) and ``reorder`` (a random subset of the volatile ones).
"""
from __future__ import annotations

import random
from dataclasses import dataclass, field
from pathlib import Path

from lab.stress.syscall_trace import Op

#: Sector size for torn writes.
SECTOR = 512
#: Crash-state variants per cut point: kill once, the others under each model.
VARIANTS = ("drop", "torn", "reorder")
MODELS = ("ordered", "posix")


def durable_flags(ops: list[Op], cut: int, model: str) -> list[bool]:
    """For ops[:cut]: whether a later barrier before the cut makes each one durable."""
    flags = [False] * cut
    synced_data: set[int] = set()  # inodes fsynced later (scanning backwards)
    synced_dirs: set[int] = set()
    any_sync = False
    for i in range(cut - 1, -1, -1):
        op = ops[i]
        if op.kind == "fsync":
            synced_data.add(op.ino)
            synced_dirs.add(op.ino)
            any_sync = True
            flags[i] = True
        elif op.kind in ("write", "trunc"):
            flags[i] = op.ino in synced_data
        elif op.kind in ("create", "mkdir", "rename", "unlink"):
            flags[i] = any_sync if model == "ordered" else all(d in synced_dirs for d in op.dirs)
        else:
            flags[i] = True  # markers
    return flags


@dataclass
class Disk:
    """A simulated disk: file contents by inode, folder entries by folder inode (0: the
    recorded folder). Files not linked from a folder exist but are not written out."""

    data: dict[int, bytearray] = field(default_factory=dict)
    dirs: dict[int, dict[str, int]] = field(default_factory=lambda: {0: {}})

    def apply(self, op: Op, torn_sectors: int | None = None) -> None:
        if op.kind == "write":
            buf = self.data.setdefault(op.ino, bytearray())
            end = op.offset + len(op.data)
            if len(buf) < end:
                buf.extend(bytes(end - len(buf)))
            if torn_sectors is None:
                buf[op.offset:end] = op.data
            else:  # the first sectors (by file offset) reach the disk, the rest stay old/zero
                keep = min(end, (op.offset // SECTOR + torn_sectors) * SECTOR) - op.offset
                if keep > 0:
                    buf[op.offset:op.offset + keep] = op.data[:keep]
        elif op.kind == "trunc":
            buf = self.data.setdefault(op.ino, bytearray())
            del buf[op.size:]
            buf.extend(bytes(max(0, op.size - len(buf))))
        elif op.kind in ("create", "mkdir"):
            (d, name), = op.names
            if op.kind == "mkdir":
                self.dirs.setdefault(op.ino, {})
            else:
                self.data.setdefault(op.ino, bytearray())
            self.dirs.setdefault(d, {})[name] = op.ino
        elif op.kind == "rename":
            (sd, sn), (dd, dn) = op.names
            if self.dirs.setdefault(sd, {}).get(sn) == op.ino:
                del self.dirs[sd][sn]
            self.dirs.setdefault(dd, {})[dn] = op.ino
        elif op.kind == "unlink":
            (d, name), = op.names
            if self.dirs.setdefault(d, {}).get(name) == op.ino:
                del self.dirs[d][name]

    def write_to(self, folder: Path, ino: int = 0, seen: frozenset = frozenset()) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        for name, child in self.dirs.get(ino, {}).items():
            if name.endswith("-shm"):
                continue  # SQLite's shared memory: rebuilt by the first connection
            if child in self.dirs:
                if child not in seen:
                    self.write_to(folder / name, child, seen | {child})
            else:
                (folder / name).write_bytes(bytes(self.data.get(child, b"")))


def sectors(op: Op) -> int:
    return (op.offset + len(op.data) - 1) // SECTOR - op.offset // SECTOR + 1


def crash_disk(ops: list[Op], cut: int, variant: str, model: str, rng: random.Random) -> Disk:
    """The disk after a power cut just after ``ops[cut - 1]``."""
    disk = Disk()
    if variant == "kill":
        for op in ops[:cut]:
            disk.apply(op)
        return disk
    flags = durable_flags(ops, cut, model)
    volatile = [i for i in range(cut) if not flags[i]]
    keep: set[int] = set()
    torn: dict[int, int] = {}
    if variant == "torn" and volatile:
        upto = rng.randrange(len(volatile) + 1)
        keep = set(volatile[:upto])
        if upto < len(volatile) and ops[volatile[upto]].kind == "write":
            op = ops[volatile[upto]]
            keep.add(volatile[upto])
            torn[volatile[upto]] = rng.randrange(sectors(op))
    elif variant == "reorder" and volatile:
        meta = [i for i in volatile if ops[i].kind in ("create", "mkdir", "rename", "unlink")]
        if model == "ordered":
            keep = set(meta[:rng.randrange(len(meta) + 1)])
        else:
            keep = {i for i in meta if rng.random() < 0.5}
        keep |= {i for i in volatile if ops[i].kind in ("write", "trunc") and rng.random() < 0.5}
    for i in range(cut):
        if flags[i] or i in keep:
            disk.apply(ops[i], torn.get(i))
    return disk
