"""Step 1 of the power-loss harness (:mod:`lab.stress.power_loss`): record the workload's
system calls and turn them into operations on a simulated disk.

:func:`record` runs :func:`lab.stress.power_workload.workload` under ``strace -f -y -xx``
(every byte of every write, the file each descriptor names); :class:`Recorder` replays the
trace's calls on the paths under the disk's folder into :class:`Op` s on inodes (data:
write, truncate; names: create, mkdir, rename, unlink; barriers: fsync) with the workload's
intent/ack markers at their exact places among them.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from app.paths import REPO_ROOT
from lab.stress.power_workload import PowerLossError

#: System calls recorded (strace ``-e trace=``).
TRACED = ("open,openat,creat,write,pwrite64,writev,pwritev,lseek,ftruncate,truncate,fsync,fdatasync,"
          "rename,renameat,renameat2,unlink,unlinkat,mkdir,mkdirat,rmdir,close,link,linkat,symlink")


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
           sys.executable, "-m", "lab.stress.power_workload", "workload", str(root), str(acks), str(seed), str(steps),
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

