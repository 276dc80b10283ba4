"""Crash-safety of story saves: SIGKILL the storage process at random moments, then check
that every story reopens and equals its last acknowledged state (or the one in flight).

A forked child runs the app's real storage code (:class:`app.story.storage.ProfileStore`) in a
loop of autosaves, deletes and close/reopen cycles (a close checkpoints the WAL into the
main file, another moment worth killing). Before each write it sends the parent an
*intent* line with the full story JSON, and after the call returns an *ack* line, over a
pipe. The parent kills it after a random delay, then opens the database with a fresh
``ProfileStore`` and checks, for every story it has heard of:

* acknowledged and no write in flight -> the stored story equals the acknowledged one;
* a write in flight -> the stored story equals the acknowledged one *or* the in-flight one
  (a delete in flight: the story is there unchanged or gone);
* ``PRAGMA integrity_check`` is ``ok`` and the store opens without :class:`StorageError`.

Anything else counts as a lost story. The database carries over from kill to kill, so
later children also recover (replay the WAL of) earlier crashes. Forking instead of
starting a new interpreter makes a kill cycle take milliseconds, so 1 000 kills take
about a minute.
"""
from __future__ import annotations

import json
import os
import random
import signal
import sqlite3
import selectors
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from app.story.storage import ProfileStore, StorageError
from app.story.model import Character, Mark, MotionChoice, Story

#: Stories the child edits (a class of children sharing one tablet).
N_STORIES = 6


def random_edit(rng: random.Random, story: Story) -> None:
    """One realistic edit: a sketched path, a new character, a title, a motion, a mark."""
    scene = rng.choice(story.scenes)
    op = rng.randrange(5)
    if op == 0 or not scene.characters:
        if len(scene.characters) < 6:
            scene.characters.append(Character(kind=rng.choice(["robot", "animal", "child"])))
        return
    ch = rng.choice(scene.characters)
    if op == 1:
        t0 = ch.path[-1][2] if ch.path else 0.0
        n = rng.randrange(5, 120)
        ch.path = ch.path[-2000:] + [(rng.uniform(0, 1.2), rng.uniform(0, 0.8), t0 + 0.05 * (k + 1)) for k in range(n)]
    elif op == 2:
        story.title = "".join(rng.choice("abcdefgh アイウ") for _ in range(rng.randrange(0, 30)))
    elif op == 3:
        ch.motion = MotionChoice(rng.choice(["walk", "run", "jump", "dance", "kick"]))
    else:
        ch.marks = ch.marks[-10:] + [Mark(rng.choice(["hop", "spin"]), rng.uniform(0, 10))]


def _child(db: Path, seed: int, out_fd: int) -> None:
    """The storage process: autosave edits forever, reporting intents and acks."""
    rng = random.Random(seed)
    out = os.fdopen(out_fd, "w", buffering=1)
    store = ProfileStore(db)
    stories = {s.id: store.load_story(s.id) for s in store.list_stories()}
    out.write("R\n")
    while True:
        r = rng.random()
        if r < 0.03 and stories:  # delete a story
            sid = rng.choice(sorted(stories))
            out.write(f"D {sid}\n")
            store.delete_story(sid)
            del stories[sid]
        elif r < 0.06:  # app goes to background: close (WAL checkpoint) and reopen
            out.write("C\n")
            store.close()
            store = ProfileStore(db)
        else:
            if len(stories) < N_STORIES:
                story = Story.new(rng.choice(["short", "classic", "free"]), f"story {rng.randrange(1000)}")
            else:
                story = stories[rng.choice(sorted(stories))]
                random_edit(rng, story)
            body = json.dumps(story.to_dict(), ensure_ascii=False, separators=(",", ":"))
            out.write(f"I {story.id} {body}\n")
            store.save_story(story)
            stories[story.id] = story
        out.write("A\n")


@dataclass
class _Expected:
    """What the parent knows about one story."""

    acked: dict | None = None  # last acknowledged body (None: never saved, or deleted)
    pending: dict | None = None  # body in flight
    pending_delete: bool = False


@dataclass
class KillReport:
    kills: int = 0
    saves_acked: int = 0
    deletes_acked: int = 0
    reopens_acked: int = 0
    in_flight_at_kill: int = 0
    in_flight_committed: int = 0
    stories_checked: int = 0
    stories_lost: int = 0
    open_failures: int = 0
    integrity_failures: int = 0
    max_stories: int = 0
    problems: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def _apply_lines(lines: list[str], expected: dict[str, _Expected], report: KillReport) -> tuple[str, str | None]:
    """Update ``expected`` from the child's complete lines; returns the op in flight."""
    in_flight: tuple[str, str | None] = ("", None)
    for line in lines:
        tag, _, rest = line.partition(" ")
        if tag == "I":
            sid, _, body = rest.partition(" ")
            e = expected.setdefault(sid, _Expected())
            e.pending = json.loads(body)
            in_flight = ("I", sid)
        elif tag == "D":
            expected[rest].pending_delete = True
            in_flight = ("D", rest)
        elif tag == "C":
            in_flight = ("C", None)
        elif tag == "A":
            op, sid = in_flight
            if op == "I":
                e = expected[sid]
                e.acked, e.pending = e.pending, None
                report.saves_acked += 1
            elif op == "D":
                e = expected[sid]
                e.acked, e.pending_delete = None, False
                report.deletes_acked += 1
            elif op == "C":
                report.reopens_acked += 1
            in_flight = ("", None)
    return in_flight


def verify(db: Path, expected: dict[str, _Expected], report: KillReport) -> None:
    """Open the store as the app would and compare every story with what was acked."""
    try:
        store = ProfileStore(db)
    except StorageError as exc:
        report.open_failures += 1
        report.problems.append(f"kill {report.kills}: store does not open: {exc}")
        report.stories_lost += sum(1 for e in expected.values() if e.acked is not None)
        return
    try:
        check = store._conn.execute("PRAGMA integrity_check").fetchone()[0]
        if check != "ok":
            report.integrity_failures += 1
            report.problems.append(f"kill {report.kills}: integrity_check {check}")
        present = {s.id for s in store.list_stories()}
        for sid, e in expected.items():
            report.stories_checked += 1
            allowed = [e.acked, e.pending] if e.pending is not None else [e.acked]
            if e.pending_delete:
                allowed.append(None)
            actual = store.load_story(sid).to_dict() if sid in present else None
            if actual not in allowed:
                report.stories_lost += 1
                report.problems.append(f"kill {report.kills}: story {sid} differs from the acknowledged state")
                continue
            if e.pending is not None and actual == e.pending and actual != e.acked:
                report.in_flight_committed += 1
            # What is on disk is now the truth for the next round.
            e.acked, e.pending, e.pending_delete = actual, None, False
        unknown = present - set(expected)
        if unknown:
            report.stories_lost += len(unknown)
            report.problems.append(f"kill {report.kills}: stories nobody saved: {sorted(unknown)[:3]}")
        report.max_stories = max(report.max_stories, len(present))
    finally:
        store.close()


def run_kill_campaign(work: Path, kills: int | None = None, seconds: float | None = None, seed: int = 0,
                      max_delay_s: float = 0.25, progress: bool = True) -> dict:
    """Kill the storage child ``kills`` times (or for ``seconds``) at random delays.

    Delays are uniform in [0, ``max_delay_s``] after the child reports it is ready, so
    kills land while opening/recovering, mid-transaction, mid-fsync and between saves.
    """
    if kills is None and seconds is None:
        raise ValueError("give kills or seconds")
    work.mkdir(parents=True, exist_ok=True)
    db = work / "kill.db"
    for suffix in ("", "-wal", "-shm"):
        Path(f"{db}{suffix}").unlink(missing_ok=True)
    ProfileStore(db).close()
    rng = random.Random(seed)
    expected: dict[str, _Expected] = {}
    report = KillReport()
    deadline = None if seconds is None else time.monotonic() + seconds
    bar = None
    if progress:
        bar = tqdm(total=kills, desc="kill story saves", unit="kill")
    try:
        while (kills is None or report.kills < kills) and (deadline is None or time.monotonic() < deadline):
            _one_kill(db, rng, expected, report, max_delay_s)
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    out = report.to_dict()
    out["problems"] = out["problems"][:20]
    out["failures"] = report.stories_lost + report.open_failures + report.integrity_failures
    return out


def _one_kill(db: Path, rng: random.Random, expected: dict[str, _Expected], report: KillReport,
              max_delay_s: float) -> None:
    read_fd, write_fd = os.pipe()
    child_seed = rng.randrange(2**31)
    pid = os.fork()
    if pid == 0:  # child: never returns into the caller's code
        code = 0
        try:
            os.close(read_fd)
            _child(db, child_seed, write_fd)
        except BaseException:  # noqa: BLE001 - report the failure through the exit code
            traceback.print_exc()
            code = 70
        finally:
            os._exit(code)
    os.close(write_fd)
    buf = b""
    delay = rng.uniform(0.0, max_delay_s)
    # Wait for "ready" (so most kills land in saves, not in interpreter start-up), then kill.
    deadline = time.monotonic() + 10.0
    while b"R\n" not in buf and time.monotonic() < deadline:
        chunk = os.read(read_fd, 65536)
        if not chunk:
            break
        buf += chunk
    # Keep draining the pipe while waiting, so the child never blocks on a full pipe.
    kill_at = time.monotonic() + delay
    with selectors.DefaultSelector() as sel:
        sel.register(read_fd, selectors.EVENT_READ)
        while (left := kill_at - time.monotonic()) > 0:
            if sel.select(left):
                chunk = os.read(read_fd, 1 << 20)
                if not chunk:
                    break
                buf += chunk
    os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    while True:
        chunk = os.read(read_fd, 1 << 20)
        if not chunk:
            break
        buf += chunk
    os.close(read_fd)
    report.kills += 1
    if os.WIFEXITED(status):  # the child died on its own: that is a crash of the storage code
        report.problems.append(f"kill {report.kills}: storage child exited {os.WEXITSTATUS(status)} before the kill")
        report.open_failures += 1
    text = buf.decode("utf-8", "replace")
    complete = text[: text.rfind("\n") + 1].splitlines()
    op, _ = _apply_lines(complete, expected, report)
    report.in_flight_at_kill += op in ("I", "D", "C")
    verify(db, expected, report)


def _sqlite_version() -> str:
    return sqlite3.sqlite_version
