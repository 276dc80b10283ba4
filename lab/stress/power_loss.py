"""Power-loss harness: replay the product's recorded system calls onto simulated
post-crash disks and reopen each with the product's own loading code.

A kill keeps the operating system's page cache; a power cut, a flat battery or a USB
stick pulled early does not. In the spirit of ALICE (Pillai et al., OSDI 2014) and
CrashMonkey (Mohan et al., OSDI 2018):

1. **Record.** A workload process (:func:`workload`, ``python -m lab.stress.power_loss
   workload ...``) drives the real product code through its public API: it creates,
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
"""
from __future__ import annotations

import hashlib
import json
import os
import random
import re
import shutil
import sqlite3
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

import app.story.storage.database as storage_module  # the controls swap its durable_write
import ar.calibration as calibration_module  # (likewise)
import retrieval.durable as durable  # (and its fsync_dir)
from app.paths import REPO_ROOT
from app.story.model import Story
from app.story.storage import ProfileStore, StorageError, read_package
from lab.stress.kill import random_edit
from ar.calibration import CameraCalibration
from ar.errors import CalibrationError
from retrieval.errors import StoryBeamError

#: Sector size for torn writes.
SECTOR = 512
#: Crash-state variants per cut point: kill once, the others under each model.
VARIANTS = ("drop", "torn", "reorder")
MODELS = ("ordered", "posix")
#: The kinds of acknowledged data checked (the JSON's ``acked_lost`` keys).
KINDS = ("stories", "assets", "packages", "calibration", "settings", "exports")
#: System calls recorded (strace ``-e trace=``).
TRACED = ("open,openat,creat,write,pwrite64,writev,pwritev,lseek,ftruncate,truncate,fsync,fdatasync,"
          "rename,renameat,renameat2,unlink,unlinkat,mkdir,mkdirat,rmdir,close,link,linkat,symlink")
#: The weakened settings a control run can use: no folder fsync in retrieval.durable; the
#: writes before issue 17 (``write_bytes`` in place: no temporary file, no fsync) for
#: calibration files, assets and the activity CSV; or SQLite's ``synchronous=NORMAL``
#: instead of ``FULL`` (a WAL commit is no longer fsynced).
WEAKENINGS = ("no-dir-fsync", "plain-write", "synchronous-normal")
#: What a workload step may do (``focus`` picks one).
FOCUSES = ("", "calibration")

PROFILE = "profile/profile.db"
CALIBRATION = "rig/camera.json"
EXPORTS = "exports"


class PowerLossError(StoryBeamError):
    """The harness itself cannot run (no strace, a workload that failed, an unknown syscall)."""


def digest(data: bytes | str) -> str:
    """Short SHA-256 of bytes or text (what markers and checks compare)."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    return hashlib.sha256(data).hexdigest()[:20]


def story_digest(story: Story) -> str:
    return digest(json.dumps(story.to_dict(), sort_keys=True))


def package_digest(story: Story, assets: dict[str, bytes]) -> str:
    return digest(story_digest(story) + "".join(f"|{n}:{digest(assets[n])}" for n in sorted(assets)))


def calibration_digest(calib: CameraCalibration) -> str:
    return digest(json.dumps(calib.to_dict(), sort_keys=True))


# ----------------------------------------------------------------------------- workload


def _random_calibration(rng: random.Random) -> CameraCalibration:
    w, h = 640, 480
    f = rng.uniform(500, 900)
    K = np.array([[f, 0.0, w / 2 + rng.uniform(-20, 20)], [0.0, f * rng.uniform(0.98, 1.02), h / 2], [0.0, 0.0, 1.0]])
    dist = np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.1, 0.1), 0.0, 0.0, 0.0])
    views = {f"view_{k:02d}": round(rng.uniform(0.1, 0.5), 4) for k in range(rng.randrange(3, 40))}
    return CameraCalibration(K, dist, (w, h), rng.uniform(0.1, 0.5), views, {}, "charuco")


def _plain_write(path: str | Path, data: bytes) -> Path:
    """The write a control replaces durable writes with (what the code did before)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path


class _NormalSyncConnection(sqlite3.Connection):
    """The synchronous-normal control's connection: the store's ``PRAGMA synchronous=FULL``
    becomes ``NORMAL``."""

    def execute(self, sql: str, *args: object) -> sqlite3.Cursor:  # type: ignore[override]
        if sql.replace(" ", "").lower() == "pragmasynchronous=full":
            sql = "PRAGMA synchronous=NORMAL"
        return super().execute(sql, *args)


def workload(root: Path, acks: Path, seed: int, steps: int, weaken: str = "", focus: str = "") -> None:
    """The recorded process: ``steps`` random product operations on a profile under ``root``,
    each between an intent (``I kind key digest``) and an ack (``A ...``) marker written to
    ``acks``. ``weaken`` names a control setting (:data:`WEAKENINGS`); ``focus="calibration"``
    makes every step a calibration save."""
    if weaken not in ("", *WEAKENINGS):
        raise PowerLossError(f"unknown weakening {weaken!r} (choose from {', '.join(WEAKENINGS)})")
    if focus not in FOCUSES:
        raise PowerLossError(f"unknown focus {focus!r}")
    if weaken == "no-dir-fsync":
        durable.fsync_dir = lambda folder: None  # the control: renames and creates are never made durable
    elif weaken == "plain-write":
        calibration_module.durable_write = _plain_write
        storage_module.durable_write = _plain_write
    elif weaken == "synchronous-normal":
        real_connect = sqlite3.connect
        sqlite3.connect = lambda *a, **k: real_connect(*a, factory=_NormalSyncConnection, **k)
    rng = random.Random(seed)
    fd = os.open(acks, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)

    def mark(tag: str, kind: str, key: str, value: str) -> None:
        os.write(fd, f"{tag} {kind} {key} {value}\n".encode())

    def open_store() -> ProfileStore:
        return ProfileStore(root / PROFILE)

    store = open_store()
    stories: dict[str, Story] = {}
    assets: dict[str, dict[str, bytes]] = {}
    store.set_activity_logging(True)
    for n in range(steps):
        r = 0.8 if focus == "calibration" else rng.random()
        if focus != "calibration" and (r < 0.40 or not stories):  # autosave of an edit (or a new story)
            if len(stories) < 4 or rng.random() < 0.1:
                story = Story.new(rng.choice(["short", "classic", "free"]), f"story {n}")
            else:
                story = stories[rng.choice(sorted(stories))]
                random_edit(rng, story)
            d = story_digest(story)
            mark("I", "stories", story.id, d)
            store.save_story(story)
            mark("A", "stories", story.id, d)
            stories[story.id] = story
            assets.setdefault(story.id, {})
            store.log_activity("save", story.id)
        elif r < 0.52:  # a background drawn for a story
            sid = rng.choice(sorted(stories))
            name = rng.choice(["bg.png", "sky.png", "thumb.png"])
            data = b"\x89PNG" + rng.randbytes(rng.randrange(200, 5000))
            key = f"{sid}/{name}"
            mark("I", "assets", key, digest(data))
            store.put_asset(sid, name, data)
            mark("A", "assets", key, digest(data))
            assets[sid][name] = data
        elif r < 0.57:  # delete a story
            sid = rng.choice(sorted(stories))
            for name in assets.get(sid, {}):
                mark("I", "assets", f"{sid}/{name}", "*")  # a deleted story's files: anything goes
            mark("I", "stories", sid, "-")
            store.delete_story(sid)
            mark("A", "stories", sid, "-")
            del stories[sid]
            assets.pop(sid, None)
        elif r < 0.64:  # a teacher setting
            key, value = rng.choice(["lang", "class", "volume"]), str(rng.randrange(10 ** 6))
            mark("I", "settings", key, digest(value))
            store.set_setting(key, value)
            mark("A", "settings", key, digest(value))
        elif r < 0.74:  # export a package; sometimes move it back in (export, delete, import)
            sid = rng.choice(sorted(stories))
            zip_rel = f"{EXPORTS}/story_{sid}.zip"
            d = package_digest(stories[sid], assets[sid])
            mark("I", "packages", zip_rel, d)
            store.export_package(sid, root / zip_rel)
            mark("A", "packages", zip_rel, d)
            if rng.random() < 0.5:
                story, files = stories.pop(sid), assets.pop(sid)
                for name in files:
                    mark("I", "assets", f"{sid}/{name}", "*")
                mark("I", "stories", sid, "-")
                store.delete_story(sid)
                mark("A", "stories", sid, "-")
                for name, data in files.items():
                    mark("I", "assets", f"{sid}/{name}", digest(data))
                mark("I", "stories", sid, story_digest(story))
                mark("I", "imports", sid, ",".join(sorted(files)) or "none")
                imported = store.import_package(root / zip_rel)
                assert imported.id == sid
                mark("A", "imports", sid, ",".join(sorted(files)) or "none")
                mark("A", "stories", sid, story_digest(story))
                for name, data in files.items():
                    mark("A", "assets", f"{sid}/{name}", digest(data))
                stories[sid], assets[sid] = story, files
        elif r < 0.86:  # the rig is (re)calibrated
            calib = _random_calibration(rng)
            d = calibration_digest(calib)
            mark("I", "calibration", CALIBRATION, d)
            calib.save(root / CALIBRATION)
            mark("A", "calibration", CALIBRATION, d)
        elif r < 0.93:  # the teacher exports the activity log
            rel = f"{EXPORTS}/activity.csv"
            mark("I", "exports", rel, "?")
            store.export_activity_csv(root / rel)
            mark("A", "exports", rel, digest((root / rel).read_bytes()))
        else:  # the app is closed and opened again
            store.close()
            store = open_store()
    store.close()
    os.close(fd)


# ----------------------------------------------------------------------------- recording


@dataclass
class Op:
    """One operation on the simulated disk (``kind``: write, trunc, create, mkdir, rename,
    unlink, fsync, mark)."""

    kind: str
    ino: int = -1  # the file (or folder) written, fsynced, created, renamed or removed
    data: bytes = b""
    offset: int = 0
    size: int = 0
    dirs: tuple[int, ...] = ()  # folders whose entries change
    names: tuple[tuple[int, str], ...] = ()  # (folder, name) pairs: create/unlink one, rename src then dst
    text: str = ""  # a marker line


_LINE = re.compile(r"^(\d+)\s+(\w+)\((.*)\)\s+=\s+(-?\d+)(?:<([^>]*)>)?")
_HEX = re.compile(r"\\x([0-9a-f]{2})")


def _unhex(text: str) -> bytes:
    return bytes(int(h, 16) for h in _HEX.findall(text))


def _split_args(args: str) -> list[str]:
    return [a.strip() for a in args.split(", ")]  # -xx: strings hold only \xNN, never ", "


def _arg_path(arg: str) -> bytes:
    """A path argument: ``"\\x2f..."``."""
    return _unhex(arg[arg.index('"'):])


def _fd_path(arg: str) -> tuple[int | None, bytes]:
    """A descriptor argument as strace -y prints it: ``3<\\x2f...>`` / ``AT_FDCWD<...>``."""
    head, _, rest = arg.partition("<")
    fd = None if head == "AT_FDCWD" else int(head) if head.lstrip("-").isdigit() else None
    return fd, _unhex(rest)


class Recorder:
    """Turns an strace log into :class:`Op` s on the inodes under ``root``."""

    def __init__(self, root: Path, acks: Path):
        self.root = os.fsencode(os.path.realpath(root))
        self.acks = os.fsencode(os.path.realpath(acks))
        self.ops: list[Op] = []
        self.next_ino = 1
        self.dirs: dict[int, dict[str, int]] = {0: {}}  # the namespace as the process saw it (kill model)
        self.sizes: dict[int, int] = {}
        self.fds: dict[int, tuple[int, int, bool]] = {}  # fd -> (ino, position, append)
        self.pending: dict[str, str] = {}

    def _rel(self, path: bytes) -> list[str] | None:
        path = os.path.normpath(path)
        if path == self.root:
            return []
        if not path.startswith(self.root + b"/"):
            return None
        return [os.fsdecode(p) for p in path[len(self.root) + 1:].split(b"/")]

    def _lookup(self, parts: list[str]) -> tuple[int, str, int | None] | None:
        """(parent folder inode, name, inode or None) of a path under root."""
        d = 0
        for part in parts[:-1]:
            nxt = self.dirs.get(d, {}).get(part)
            if nxt is None or nxt not in self.dirs:
                return None
            d = nxt
        return d, parts[-1], self.dirs[d].get(parts[-1])

    def _join(self, dirarg: str | None, patharg: str) -> bytes:
        path = _arg_path(patharg)
        if path.startswith(b"/") or dirarg is None:
            return path
        _fd, base = _fd_path(dirarg)
        return os.path.join(base, path)

    def feed(self, line: str) -> None:
        if "<unfinished ...>" in line:
            pid = line.split()[0]
            self.pending[pid] = line.split("<unfinished ...>")[0]
            return
        m = re.match(r"^(\d+)\s+<\.\.\. \w+ resumed>(.*)$", line)
        if m:
            line = self.pending.pop(m.group(1), "") + m.group(2)
        m = _LINE.match(line)
        if not m:
            return
        _pid, call, args, result, result_path = m.groups()
        res = int(result)
        if res < 0:
            return
        a = _split_args(args)
        getattr(self, f"_{call}", self._other)(call, a, res, result_path)

    # -- system calls -----------------------------------------------------------------
    def _other(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        paths = [x for x in a if x.startswith('"') or "<" in x]
        for x in paths:
            raw = _arg_path(x) if x.startswith('"') else _fd_path(x)[1]
            if self._rel(raw) is not None and raw != self.root and call not in ("lseek", "close"):
                raise PowerLossError(f"system call {call} on {raw!r} is not modelled")

    def _openat(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._do_open(self._join(a[0], a[1]), a[2], res)

    def _open(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._do_open(self._join(None, a[0]), a[1], res)

    def _do_open(self, path: bytes, flags: str, fd: int) -> None:
        self.fds.pop(fd, None)
        parts = self._rel(path)
        if parts is None:
            return
        if not parts:  # the recorded folder itself (opened to fsync it)
            self.fds[fd] = (0, 0, False)
            return
        found = self._lookup(parts)
        if found is None:
            return
        d, name, ino = found
        if ino is None:
            if "O_CREAT" not in flags:
                return
            ino = self.next_ino
            self.next_ino += 1
            self.dirs[d][name] = ino
            self.sizes[ino] = 0
            self.ops.append(Op("create", ino, dirs=(d,), names=((d, name),)))
        if ino in self.dirs:
            self.fds[fd] = (ino, 0, False)
            return
        if "O_TRUNC" in flags and self.sizes.get(ino, 0):
            self.sizes[ino] = 0
            self.ops.append(Op("trunc", ino, size=0))
        self.fds[fd] = (ino, 0, "O_APPEND" in flags)

    def _creat(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._do_open(self._join(None, a[0]), "O_CREAT|O_TRUNC", res)

    def _close(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        fd, _ = _fd_path(a[0])
        self.fds.pop(fd, None)

    def _lseek(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        fd, _ = _fd_path(a[0])
        if fd in self.fds:
            ino, _pos, app = self.fds[fd]
            self.fds[fd] = (ino, res, app)

    def _write(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        fd, path = _fd_path(a[0])
        data = _unhex(a[1])[:res]
        if path == self.acks:
            self.ops.append(Op("mark", text=data.decode()))
            return
        if fd not in self.fds:
            if self._rel(path) is not None:
                raise PowerLossError(f"write to {path!r} through a descriptor opened before recording")
            return
        ino, pos, app = self.fds[fd]
        if app:
            pos = self.sizes[ino]
        self._data(ino, pos, data)
        self.fds[fd] = (ino, pos + len(data), app)

    def _pwrite64(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        fd, _ = _fd_path(a[0])
        if fd in self.fds:
            self._data(self.fds[fd][0], int(a[3]), _unhex(a[1])[:res])

    def _data(self, ino: int, offset: int, data: bytes) -> None:
        if data:
            self.ops.append(Op("write", ino, data=data, offset=offset))
            self.sizes[ino] = max(self.sizes.get(ino, 0), offset + len(data))

    def _ftruncate(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        fd, _ = _fd_path(a[0])
        if fd in self.fds:
            ino = self.fds[fd][0]
            self.sizes[ino] = int(a[1])
            self.ops.append(Op("trunc", ino, size=int(a[1])))

    def _fsync(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        fd, _ = _fd_path(a[0])
        if fd in self.fds:
            self.ops.append(Op("fsync", self.fds[fd][0]))

    _fdatasync = _fsync

    def _mkdir(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._mkdir_path(self._join(None, a[0]))

    def _mkdirat(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._mkdir_path(self._join(a[0], a[1]))

    def _mkdir_path(self, path: bytes) -> None:
        parts = self._rel(path)
        found = self._lookup(parts) if parts else None
        if found is None:
            return
        d, name, _ = found
        ino = self.next_ino
        self.next_ino += 1
        self.dirs[ino] = {}
        self.dirs[d][name] = ino
        self.ops.append(Op("mkdir", ino, dirs=(d,), names=((d, name),)))

    def _rename(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._rename_paths(self._join(None, a[0]), self._join(None, a[1]))

    def _renameat(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._rename_paths(self._join(a[0], a[1]), self._join(a[2], a[3]))

    _renameat2 = _renameat

    def _rename_paths(self, src: bytes, dst: bytes) -> None:
        sp, dp = self._rel(src), self._rel(dst)
        if sp is None and dp is None:
            return
        s, d = self._lookup(sp or []), self._lookup(dp or [])
        if not sp or not dp or s is None or d is None or s[2] is None:
            raise PowerLossError(f"rename {src!r} -> {dst!r} crosses the recorded folder")
        (sd, sn, ino), (dd, dn, _old) = s, d
        del self.dirs[sd][sn]
        self.dirs[dd][dn] = ino
        self.ops.append(Op("rename", ino, dirs=(sd, dd), names=((sd, sn), (dd, dn))))

    def _unlink(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._unlink_path(self._join(None, a[0]))

    _rmdir = _unlink

    def _unlinkat(self, call: str, a: list[str], res: int, rp: str | None) -> None:
        self._unlink_path(self._join(a[0], a[1]))

    def _unlink_path(self, path: bytes) -> None:
        parts = self._rel(path)
        found = self._lookup(parts) if parts else None
        if found is None or found[2] is None:
            return
        d, name, ino = found
        del self.dirs[d][name]
        self.ops.append(Op("unlink", ino, dirs=(d,), names=((d, name),)))


def record(root: Path, seed: int, steps: int, weaken: str = "", work: Path | None = None,
           focus: str = "") -> list[Op]:
    """Run :func:`workload` under strace and return its operations on ``root``."""
    strace = shutil.which("strace")
    if strace is None:
        raise PowerLossError("strace is not installed (apt-get install strace; scripts/setup.sh does)")
    work = work or root.parent
    acks = work / f"acks-{seed}-{weaken or 'full'}.log"
    trace = work / f"trace-{seed}-{weaken or 'full'}.txt"
    for p in (acks, trace):
        p.unlink(missing_ok=True)
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    repo = REPO_ROOT
    env = {**os.environ, "PYTHONPATH": str(repo) + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    cmd = [strace, "-f", "-qq", "-y", "-xx", "-s", str(1 << 24), "-e", f"trace={TRACED}", "-o", str(trace),
           sys.executable, "-m", "lab.stress.power_loss", "workload", str(root), str(acks), str(seed), str(steps),
           weaken, focus]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=str(repo), timeout=600)
    if proc.returncode != 0:
        raise PowerLossError(f"the recorded workload failed (exit {proc.returncode}): {proc.stderr[-2000:]}")
    rec = Recorder(root, acks)
    with open(trace, encoding="ascii", errors="replace") as fh:
        for line in fh:
            rec.feed(line.rstrip("\n"))
    trace.unlink(missing_ok=True)
    return rec.ops


# ----------------------------------------------------------------------------- crash states


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


# ----------------------------------------------------------------------------- checking


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


def _main(argv: list[str]) -> int:
    if len(argv) >= 5 and argv[0] == "workload":
        workload(Path(argv[1]), Path(argv[2]), int(argv[3]), int(argv[4]), *argv[5:7])
        return 0
    print("usage: python -m lab.stress.power_loss workload ROOT ACKS SEED STEPS [WEAKEN [FOCUS]]", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
