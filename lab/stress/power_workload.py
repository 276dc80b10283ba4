"""The process the power-loss harness records (:mod:`lab.stress.power_loss`): random
product operations on a profile, each between an intent and an ack marker.

``python -m lab.stress.power_workload workload ROOT ACKS SEED STEPS [WEAKEN [FOCUS]]`` runs
:func:`workload`; :func:`lab.stress.syscall_trace.record` starts it under strace. It calls the
product's public API only (:class:`~app.story.storage.ProfileStore`,
:meth:`ar.calibration.CameraCalibration.save`), so what is recorded is the product's write
path; a *control* run weakens one setting first (:data:`WEAKENINGS`). The digests here are
what the markers carry and what the checks compare.
"""
from __future__ import annotations

import hashlib
import json
import os
import random
import sqlite3
import sys
from pathlib import Path

import numpy as np

import app.story.storage.database as storage_module  # the controls swap its durable_write
import ar.calibration as calibration_module  # (likewise)
import retrieval.durable as durable  # (and its fsync_dir)
from app.story.model import Story
from app.story.storage import ProfileStore
from ar.calibration import CameraCalibration
from lab.stress.kill import random_edit
from retrieval.errors import StoryBeamError

#: The kinds of acknowledged data checked (the JSON's ``acked_lost`` keys).
KINDS = ("stories", "assets", "packages", "calibration", "settings", "exports")
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
        elif r < 0.57:  # delete a story: at once, or the child's way (to the bin, then the teacher empties it)
            sid = rng.choice(sorted(stories))
            for name in assets.get(sid, {}):
                mark("I", "assets", f"{sid}/{name}", "*")  # a deleted story's files: anything goes
            mark("I", "stories", sid, "-")
            if rng.random() < 0.5:
                store.delete_story(sid)
            else:
                store.bin_story(sid)
                store.empty_bin()
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


def _main(argv: list[str]) -> int:
    if len(argv) >= 5 and argv[0] == "workload":
        workload(Path(argv[1]), Path(argv[2]), int(argv[3]), int(argv[4]), *argv[5:7])
        return 0
    print("usage: python -m lab.stress.power_workload workload ROOT ACKS SEED STEPS [WEAKEN [FOCUS]]", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
