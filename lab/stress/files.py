"""Bad files: damaged/foreign databases, hostile story packages, broken calibration files,
and a full disk.

Contracts checked (each violation is counted as a crash with its traceback tail):

* **Databases** (:class:`app.story.storage.ProfileStore`): a truncated, bit-flipped, zeroed or
  foreign file opens and reads fine or raises :class:`StorageError`; the good original
  it was copied from is never touched.
* **Story packages** (:meth:`ProfileStore.import_package`): every malformed, oversized,
  path-traversing, bomb or wrong-version package is refused with :class:`StorageError`
  and *nothing is written*: the stories and the assets folder are byte-identical
  before and after. A valid package imports.
* **Calibration files** (:meth:`ar.calibration.CameraCalibration.load`,
  :meth:`~ar.calibration.ProjectorCalibration.load`): load or raise
  :class:`ar.errors.CalibrationError`.
* **Full disk**: saves fail with a :class:`StorageError` that says the storage is full,
  every story saved before still loads unchanged, and saving works again once space is
  freed. A real full filesystem is a small tmpfs (``mount -t tmpfs -o size=...``, needs
  root); elsewhere ``RLIMIT_FSIZE`` in a forked child makes writes past a size fail
  with ``EFBIG`` (SQLite reports it as an I/O error, not as "full": the message then
  says so).
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import random
import resource
import shutil
import signal
import sqlite3
import subprocess
import tempfile
import time
import traceback
import warnings
import zipfile
from pathlib import Path
from typing import Callable, Iterator

from tqdm import tqdm

from ar.calibration import CameraCalibration, ProjectorCalibration
from ar.errors import CalibrationError
from app.story.storage import (MAX_ENTRY_BYTES, MAX_PACKAGE_ENTRIES, PACKAGE_FORMAT_NAME, ProfileStore, StorageError)
from app.story.model import Character, Mark, Story

# ----------------------------------------------------------------------------- shared helpers


def sample_story(rng: random.Random, points: int = 200) -> Story:
    story = Story.new(rng.choice(["short", "classic", "free"]), f"sample {rng.randrange(1000)}")
    for scene in story.scenes:
        ch = Character(kind=rng.choice(["robot", "animal", "child"]))
        ch.path = [(rng.uniform(0, 1.2), rng.uniform(0, 0.8), 0.05 * k) for k in range(points)]
        ch.marks = [Mark("hop", 1.0)]
        scene.characters.append(ch)
    return story


def snapshot(store: ProfileStore) -> tuple[dict, dict]:
    """Everything an import could change: story bodies and the assets folder's files."""
    stories = {s.id: store.load_story(s.id).to_dict() for s in store.list_stories()}
    files = {}
    if store.assets_dir.exists():
        for p in sorted(store.assets_dir.rglob("*")):
            files[str(p.relative_to(store.assets_dir))] = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
    return stories, files


def _crash(kind: str, exc: BaseException) -> dict:
    return {"kind": kind, "error": "".join(traceback.format_exception(exc)[-2:])[-600:]}


# ----------------------------------------------------------------------------- databases


def corrupt_bytes(rng: random.Random, data: bytes) -> tuple[bytes, str]:
    """A damaged copy of a database file: truncated, bit-flipped, a page of noise or zeros."""
    b = bytearray(data)
    how = rng.randrange(5)
    if how == 0:
        return bytes(b[: rng.randrange(len(b))]), "truncate"
    if how == 1:
        for _ in range(rng.randrange(1, 60)):
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
        return bytes(b), "bitflip"
    off = rng.randrange(len(b))
    n = min(4096, len(b) - off)
    if how == 2:
        b[off:off + n] = rng.randbytes(n)
        return bytes(b), "noise page"
    if how == 3:
        b[off:off + n] = bytes(n)
        return bytes(b), "zero page"
    # damage only the schema / header area
    for _ in range(rng.randrange(1, 8)):
        b[rng.randrange(min(len(b), 4096))] = rng.randrange(256)
    return bytes(b), "header"


def foreign_files() -> dict[str, bytes]:
    """Files a child or teacher might pick instead of a profile database."""
    out = {"empty": b"", "text": b"hello\n" * 100, "png": b"\x89PNG\r\n\x1a\n" + bytes(500),
           "zip": _zip_bytes({"a.txt": b"x"}), "sqlite header only": b"SQLite format 3\x00" + bytes(84),
           "random": random.Random(1).randbytes(8192)}
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "other.db"
        conn = sqlite3.connect(p)
        conn.execute("CREATE TABLE contacts (name TEXT)")
        conn.execute("INSERT INTO contacts VALUES ('x')")
        conn.commit()
        conn.close()
        out["another program's sqlite"] = p.read_bytes()
        p2 = Path(tmp) / "newer.db"
        with ProfileStore(p2) as st:
            st._conn.execute("PRAGMA user_version=99")
        out["newer StoryBeam schema"] = p2.read_bytes()
    return out


def _try_store(path: Path) -> str:
    """Open, list, load every story, save one: 'ok' or 'refused' (StorageError)."""
    try:
        with ProfileStore(path) as store:
            for s in store.list_stories():
                store.load_story(s.id)
            store.save_story(Story.new())
        return "ok"
    except StorageError:
        return "refused"


def run_db_corruption(work: Path, n: int, seed: int = 0) -> dict:
    rng = random.Random(seed)
    work.mkdir(parents=True, exist_ok=True)
    good = work / "good.db"
    for suffix in ("", "-wal", "-shm"):
        Path(f"{good}{suffix}").unlink(missing_ok=True)
    with ProfileStore(good) as store:
        for _ in range(20):
            store.save_story(sample_story(rng))
    original = good.read_bytes()
    # A profile left by a crash: its recent commits still in an un-checkpointed WAL.
    crashed = work / "crashed.db"
    for suffix in ("", "-wal", "-shm"):
        Path(f"{crashed}{suffix}").unlink(missing_ok=True)
    store = ProfileStore(crashed)
    store._conn.execute("PRAGMA wal_autocheckpoint=0")
    for _ in range(10):
        store.save_story(sample_story(rng))
    crashed_main, crashed_wal = crashed.read_bytes(), Path(f"{crashed}-wal").read_bytes()
    store.close()
    out = {"inputs": 0, "opened": 0, "refused": 0, "crashes": 0, "crash_examples": [], "by_damage": {}}

    def one(label: str, data: bytes, wal: bytes | None = None) -> None:
        path = work / "damaged.db"
        for suffix in ("", "-wal", "-shm"):
            Path(f"{path}{suffix}").unlink(missing_ok=True)
        path.write_bytes(data)
        if wal is not None:
            Path(f"{path}-wal").write_bytes(wal)
        out["inputs"] += 1
        try:
            result = _try_store(path)
            out["opened" if result == "ok" else "refused"] += 1
        except Exception as exc:  # noqa: BLE001 - anything but StorageError is a defect
            out["crashes"] += 1
            if len(out["crash_examples"]) < 10:
                out["crash_examples"].append({"damage": label, **_crash("db", exc)})
        out["by_damage"][label] = out["by_damage"].get(label, 0) + 1

    for label, data in foreign_files().items():
        one(f"foreign: {label}", data)
    for k in range(n):
        if k % 4 == 3:  # damage the WAL of a crashed profile instead of the main file
            wal, label = corrupt_bytes(rng, crashed_wal)
            one(f"wal {label}", crashed_main, wal)
        else:
            data, label = corrupt_bytes(rng, original)
            one(label, data)
    out["original_unchanged"] = good.read_bytes() == original
    return out


# ----------------------------------------------------------------------------- story packages


def _zip_bytes(files: dict[str, bytes], compression: int = zipfile.ZIP_DEFLATED) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=compression) as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return buf.getvalue()


def _manifest(story_bytes: bytes, extra: dict[str, bytes] | None = None, **overrides) -> bytes:
    files = {"story.json": story_bytes, **(extra or {})}
    manifest = {"format": PACKAGE_FORMAT_NAME, "version": 1, "story_id": json.loads(story_bytes)["id"],
                "title": "x", "files": [{"name": n, "size": len(b), "sha256": hashlib.sha256(b).hexdigest()}
                                        for n, b in files.items()]}
    manifest.update(overrides)
    return json.dumps(manifest).encode()


def _package(story: dict, assets: dict[str, bytes] | None = None, manifest: bytes | None = None,
             compression: int = zipfile.ZIP_DEFLATED) -> bytes:
    story_bytes = json.dumps(story).encode()
    extra = {f"assets/{k}": v for k, v in (assets or {}).items()}
    files = {"manifest.json": manifest if manifest is not None else _manifest(story_bytes, extra), "story.json": story_bytes,
             **extra}
    return _zip_bytes(files, compression)


#: Crafted packages that are valid (other zip compression methods with correct content):
#: importing them is right.
VALID_VARIANTS = {"bzip2 entries", "lzma entries"}


def crafted_packages(rng: random.Random) -> dict[str, bytes]:
    """Hand-made hostile packages: each must be refused (except :data:`VALID_VARIANTS`)."""
    story = sample_story(rng).to_dict()
    sb = json.dumps(story).encode()
    out: dict[str, bytes] = {}
    for name in ["../evil.txt", "/etc/passwd", "assets/../../x", "assets/..", "C:\\x", "assets\\x.png",
                 "assets/sub/x.png", "assets/.hidden", "other/x.png", "assets/" + "a" * 300, "./story.json",
                 "assets/x.png\x00.txt", "assets/\u00e9.png"]:
        out[f"traversal name {name[:30]!r}"] = _zip_bytes({"manifest.json": _manifest(sb), "story.json": sb, name: b"x"})
    bomb = bytes(MAX_ENTRY_BYTES + 1)  # compresses to about 16 kB
    out["zip bomb (one entry over the entry limit)"] = _package(story, {"bg.png": bomb})
    many = {f"a{i}.png": bytes(10 * 1024 * 1024) for i in range(10)}  # 100 MB unpacked, small zip
    out["zip bomb (total over the unpack limit)"] = _package(story, many)
    out["too many entries"] = _package(story, {f"a{i}.png": b"x" for i in range(MAX_PACKAGE_ENTRIES + 1)})
    for v in (0, 2, 99, -1, "1", 1.0, None, True, [1]):
        out[f"wrong version {v!r}"] = _package(story, manifest=_manifest(sb, version=v))
    out["wrong format name"] = _package(story, manifest=_manifest(sb, format="something.else"))
    out["manifest not an object"] = _package(story, manifest=b"[1, 2]")
    out["manifest not JSON"] = _package(story, manifest=b"{oops")
    out["manifest deeply nested"] = _package(story, manifest=b"[" * 100_000 + b"]" * 100_000)
    out["manifest files not a list"] = _package(story, manifest=_manifest(sb, files={"a": 1}))
    out["manifest unhashable name"] = _package(story, manifest=_manifest(sb, files=[{"name": ["story.json"]}]))
    out["manifest wrong checksum"] = _package(story, manifest=_manifest(sb, files=[
        {"name": "story.json", "size": len(sb), "sha256": "0" * 64}]))
    out["manifest lists a missing file"] = _package(story, manifest=_manifest(sb, {"assets/x.png": b"1"}))
    out["manifest story_id mismatch"] = _package(story, manifest=_manifest(sb, story_id="other"))
    deep_story = b"{" + b'"a":{' * 50_000 + b"}" * 50_001
    deep_manifest = json.dumps({"format": PACKAGE_FORMAT_NAME, "version": 1, "story_id": "x", "files": [
        {"name": "story.json", "size": len(deep_story), "sha256": hashlib.sha256(deep_story).hexdigest()}]}).encode()
    out["story.json deeply nested"] = _zip_bytes({"manifest.json": deep_manifest, "story.json": deep_story})
    huge_int = dict(story)
    huge_int["scenes"] = json.loads(json.dumps(story["scenes"]))
    huge_int["scenes"][0]["characters"][0]["path"][0][0] = 10**400
    hb = json.dumps(huge_int).encode()
    out["story with a 400-digit integer"] = _zip_bytes({"manifest.json": _manifest(hb), "story.json": hb})
    mark_int = json.loads(json.dumps(story))
    mark_int["scenes"][0]["characters"][0]["marks"][0]["at"] = 10**400
    mb = json.dumps(mark_int).encode()
    out["mark time a 400-digit integer"] = _zip_bytes({"manifest.json": _manifest(mb), "story.json": mb})
    newer = dict(story, version=2)
    nb = json.dumps(newer).encode()
    out["story from a newer app"] = _zip_bytes({"manifest.json": _manifest(nb), "story.json": nb})
    nan = json.dumps(story).replace("1.0}", "NaN}", 1).encode()
    out["story with NaN"] = _zip_bytes({"manifest.json": _manifest(nan), "story.json": nan})
    out["not a zip"] = b"PK\x03\x04" + rng.randbytes(2000)
    out["empty file"] = b""
    out["encrypted-flag entry"] = _flag_encrypted(_package(story))
    out["bzip2 entries"] = _package(story, compression=zipfile.ZIP_BZIP2)
    out["lzma entries"] = _package(story, compression=zipfile.ZIP_LZMA)
    out["duplicate names"] = _dup_names(story)
    out["lying size header"] = _lying_size(_package(story, {"bg.png": bytes(100_000)}))
    return {k: v for k, v in out.items() if v}


def _flag_encrypted(data: bytes) -> bytes:
    b = bytearray(data)
    i = b.find(b"PK\x01\x02")  # central directory: general purpose flag at +8
    while i >= 0:
        b[i + 8] |= 1
        i = b.find(b"PK\x01\x02", i + 4)
    return bytes(b)


def _dup_names(story: dict) -> bytes:
    sb = json.dumps(story).encode()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf, contextlib.suppress(UserWarning):
        warnings.simplefilter("ignore")
        zf.writestr("manifest.json", _manifest(sb))
        zf.writestr("story.json", sb)
        zf.writestr("story.json", sb)
    return buf.getvalue()


def _lying_size(data: bytes) -> bytes:
    """Set the uncompressed size of the last central-directory entry to 10 bytes."""
    b = bytearray(data)
    i = b.rfind(b"PK\x01\x02")
    b[i + 24:i + 28] = (10).to_bytes(4, "little")
    return bytes(b)


def run_package_campaign(work: Path, n_mutants: int, seed: int = 0) -> dict:
    """Crafted hostile packages plus ``n_mutants`` byte-mutated copies of a valid one."""
    rng = random.Random(seed)
    work.mkdir(parents=True, exist_ok=True)
    for suffix in ("", "-wal", "-shm"):
        Path(f"{work / 'pkg.db'}{suffix}").unlink(missing_ok=True)
    shutil.rmtree(work / "pkg.db.assets", ignore_errors=True)
    store = ProfileStore(work / "pkg.db")
    out = {"inputs": 0, "imported": 0, "refused": 0, "crashes": 0, "wrote_on_refusal": 0,
           "crafted_accepted": [], "crash_examples": []}
    try:
        for _ in range(3):
            store.save_story(sample_story(rng))
        src = sample_story(rng)
        store.save_story(src)
        store.put_asset(src.id, "bg.png", b"\x89PNG" + rng.randbytes(3000))
        good = work / "good.sbpkg"
        store.export_package(src.id, good)
        good_bytes = good.read_bytes()

        def one(label: str, data: bytes, must_refuse: bool) -> None:
            path = work / "input.sbpkg"
            path.write_bytes(data)
            before = snapshot(store)
            out["inputs"] += 1
            try:
                story = store.import_package(path)
            except StorageError:
                out["refused"] += 1
                if snapshot(store) != before:
                    out["wrote_on_refusal"] += 1
                    out["crash_examples"].append({"kind": "package", "input": label, "error": "wrote before refusing"})
                return
            except Exception as exc:  # noqa: BLE001
                out["crashes"] += 1
                if len(out["crash_examples"]) < 12:
                    out["crash_examples"].append({"input": label, **_crash("package", exc)})
                return
            out["imported"] += 1
            if must_refuse:
                out["crafted_accepted"].append(label)
            store.delete_story(story.id)  # keep the store small

        one("valid package", good_bytes, False)
        if out["imported"] != 1:
            out["crash_examples"].append({"input": "valid package", "error": "a valid package was refused"})
            out["crashes"] += 1
        for label, data in crafted_packages(rng).items():
            one(label, data, label not in VALID_VARIANTS)
        for _ in range(n_mutants):
            data = bytearray(good_bytes)
            how = rng.randrange(3)
            if how == 0:
                data = data[: rng.randrange(len(data))]
            elif how == 1:
                for _ in range(rng.randrange(1, 20)):
                    data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
            else:
                off = rng.randrange(len(data))
                data[off:off + 64] = rng.randbytes(min(64, len(data) - off))
            one("mutant", bytes(data), False)
    finally:
        store.close()
    return out


# ----------------------------------------------------------------------------- calibration files


def _valid_calibrations() -> dict[str, dict]:
    camera = {"camera_matrix": [[900.0, 0, 640], [0, 900.0, 360], [0, 0, 1]], "dist_coeffs": [0.01, -0.02, 0, 0, 0],
              "image_size": [1280, 720], "rms": 0.3, "board": "charuco", "per_view_errors": {"v1": 0.2},
              "rejected_views": {}}
    projector = {"projector": {"camera_matrix": [[1300.0, 0, 512], [0, 1300.0, 384], [0, 0, 1]],
                               "dist_coeffs": [0, 0, 0, 0, 0], "image_size": [1024, 768]},
                 "proj_from_cam": {"R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0.1, 0, 0]},
                 "rms": 0.5, "stereo_rms": 0.6, "per_view_errors": {}, "rejected_views": {}}
    return {"camera": camera, "projector": projector}


_JSON_NASTIES = [None, True, 0, -1, 1e308, 10**400, float("nan"), float("inf"), "", "x", "1", [], {}, [[]],
                 [1, 2], [[1, 2], [3]], {"a": 1}, [None] * 3, "\u0000", [[float("nan")] * 3] * 3,
                 [[1, 0, 0], [0, 1, 0], [0, 0, -1]], [0, 0], [-5, 10], [1e9, 1e9], list(range(14))]


def _json_paths(obj, prefix=()) -> list[tuple]:
    paths = [prefix]
    if isinstance(obj, dict):
        for k, v in obj.items():
            paths += _json_paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            paths += _json_paths(v, prefix + (i,))
    return paths


def _set_path(obj, path: tuple, value):
    if not path:
        return value
    obj = json.loads(json.dumps(obj))
    cur = obj
    for k in path[:-1]:
        cur = cur[k]
    if isinstance(cur, dict) and path[-1] is None:
        return obj
    cur[path[-1]] = value
    return obj


def mutate_calibration(rng: random.Random, doc: dict) -> bytes:
    how = rng.randrange(4)
    if how == 0:  # replace a value anywhere with a nasty one
        path = rng.choice(_json_paths(doc))
        value = _set_path(doc, path, rng.choice(_JSON_NASTIES)) if path else rng.choice(_JSON_NASTIES)
        return json.dumps(value).encode()
    if how == 1:  # delete a key
        paths = [p for p in _json_paths(doc) if p and isinstance(p[-1], str)]
        p = rng.choice(paths)
        d = json.loads(json.dumps(doc))
        cur = d
        for k in p[:-1]:
            cur = cur[k]
        del cur[p[-1]]
        return json.dumps(d).encode()
    text = bytearray(json.dumps(doc, indent=1).encode())
    if how == 2:
        return bytes(text[: rng.randrange(len(text))])
    for _ in range(rng.randrange(1, 10)):
        text[rng.randrange(len(text))] ^= 1 << rng.randrange(8)
    return bytes(text)


def run_calibration_campaign(work: Path, n: int, seed: int = 0) -> dict:
    rng = random.Random(seed)
    work.mkdir(parents=True, exist_ok=True)
    loaders = {"camera": CameraCalibration.load, "projector": ProjectorCalibration.load}
    docs = _valid_calibrations()
    out = {"inputs": 0, "loaded": 0, "refused": 0, "crashes": 0, "crash_examples": []}

    def one(kind: str, label: str, data: bytes) -> None:
        path = work / f"{kind}.json"
        path.write_bytes(data)
        out["inputs"] += 1
        try:
            loaders[kind](path)
            out["loaded"] += 1
        except CalibrationError:
            out["refused"] += 1
        except Exception as exc:  # noqa: BLE001
            out["crashes"] += 1
            if len(out["crash_examples"]) < 12:
                out["crash_examples"].append({"input": f"{kind}: {label}", **_crash("calibration", exc)})

    for kind, doc in docs.items():
        one(kind, "valid", json.dumps(doc).encode())
        one(kind, "deeply nested", b"[" * 100_000 + b"]" * 100_000)
        one(kind, "oversized (64 MB of whitespace)", b" " * (64 * 1024 * 1024) + json.dumps(doc).encode())
        one(kind, "not UTF-8", b"\xff\xfe" + json.dumps(doc).encode("utf-16-le"))
        one(kind, "empty", b"")
    for _ in range(n):
        kind = rng.choice(list(docs))
        one(kind, "mutant", mutate_calibration(rng, docs[kind]))
    return out


# ----------------------------------------------------------------------------- full disk


@contextlib.contextmanager
def small_tmpfs(folder: Path, size_kb: int) -> Iterator[Path | None]:
    """A tmpfs of ``size_kb`` mounted at ``folder`` (None when mounting is not allowed)."""
    folder.mkdir(parents=True, exist_ok=True)
    ok = os.geteuid() == 0 and subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size_kb}k", "tmpfs", str(folder)],
        capture_output=True).returncode == 0
    try:
        yield folder if ok else None
    finally:
        if ok:
            subprocess.run(["umount", "-l", str(folder)], capture_output=True)


def fill_until_full(store: ProfileStore, rng: random.Random, max_saves: int = 10_000) -> tuple[dict, StorageError | None]:
    """Save new stories until a save fails; returns the saved stories and the error."""
    saved: dict[str, dict] = {}
    for _ in range(max_saves):
        story = sample_story(rng, points=400)
        try:
            store.save_story(story)
        except StorageError as exc:
            return saved, exc
        saved[story.id] = story.to_dict()
    return saved, None


def full_disk_check(work: Path, seed: int = 0) -> dict:
    """Fill a real small filesystem (tmpfs) or a size-limited process (RLIMIT_FSIZE)."""
    mount = work / "tiny-disk"
    with small_tmpfs(mount, 768) as disk:
        if disk is not None:
            result = _full_disk_on(disk, seed)
            result["mode"] = "tmpfs 768 kB (real ENOSPC)"
            return result
    result = full_disk_rlimit(work / "rlimit", seed)
    result["mode"] = "RLIMIT_FSIZE (EFBIG; tmpfs mount not permitted here)"
    return result


def _full_disk_on(folder: Path, seed: int) -> dict:
    """Fill the filesystem with stories (after a ballast file), check nothing saved is lost
    while full or on reopening, then free space (delete the ballast) and save again."""
    rng = random.Random(seed)
    db = folder / "profile.db"
    ballast = folder / "other-app-files.bin"
    ballast.write_bytes(bytes(192 * 1024))
    store = ProfileStore(db)
    saved, error = fill_until_full(store, rng)
    out = {"saved_before_full": len(saved), "error": str(error) if error else None,
           "says_full": bool(error and "full" in str(error))}
    # A second save may fit into the space the rolled-back one freed; either it is kept
    # or it is refused with a StorageError (anything else propagates as a crash).
    second = sample_story(rng, points=400)
    try:
        store.save_story(second)
        saved[second.id] = second.to_dict()
    except StorageError:
        pass
    out["second_save_refused_cleanly"] = True
    out["lost_while_full"] = sum(1 for sid, body in saved.items() if store.load_story(sid).to_dict() != body)
    store.close()
    try:
        store = ProfileStore(db)
        out["reopens_while_full"] = True
        out["lost_after_reopen"] = sum(1 for sid, body in saved.items() if store.load_story(sid).to_dict() != body)
        store.close()
    except StorageError as exc:
        out["reopens_while_full"] = False
        out["reopen_error"] = str(exc)
    ballast.unlink()  # the user frees some space
    with ProfileStore(db) as store:
        extra = sample_story(rng, points=50)
        try:
            store.save_story(extra)
            saved[extra.id] = extra.to_dict()
            out["saves_after_freeing_space"] = True
        except StorageError as exc:
            out["saves_after_freeing_space"] = False
            out["error_after_freeing"] = str(exc)
    return _finish_full(out, db, saved)


def _finish_full(out: dict, db: Path, saved: dict) -> dict:
    with ProfileStore(db) as store:
        out["stories_lost"] = sum(1 for sid, body in saved.items()
                                  if not store.has_story(sid) or store.load_story(sid).to_dict() != body)
    out["ok"] = bool(out["says_full"] and out["second_save_refused_cleanly"] and out["stories_lost"] == 0
                     and out.get("lost_while_full", 0) == 0 and out.get("lost_after_reopen", 0) == 0
                     and out.get("saves_after_freeing_space", True))
    return out


def full_disk_rlimit(folder: Path, seed: int, limit_bytes: int = 600 * 1024) -> dict:
    """A forked child fills a store under ``RLIMIT_FSIZE``; the parent checks the file."""
    folder.mkdir(parents=True, exist_ok=True)
    db = folder / "profile.db"
    for suffix in ("", "-wal", "-shm"):
        Path(f"{db}{suffix}").unlink(missing_ok=True)
    ProfileStore(db).close()
    read_fd, write_fd = os.pipe()
    pid = os.fork()
    if pid == 0:
        code = 0
        try:
            os.close(read_fd)
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # get EFBIG instead of being killed
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
            store = ProfileStore(db)
            saved, error = fill_until_full(store, random.Random(seed))
            lost = sum(1 for sid, body in saved.items() if store.load_story(sid).to_dict() != body)
            msg = {"saved": saved, "error": str(error) if error else None, "lost_while_full": lost}
            with os.fdopen(write_fd, "w") as fh:
                fh.write(json.dumps(msg))
        except BaseException:  # noqa: BLE001
            traceback.print_exc()
            code = 70
        finally:
            os._exit(code)
    os.close(write_fd)
    with os.fdopen(read_fd) as fh:
        text = fh.read()
    _, status = os.waitpid(pid, 0)
    if not text:
        return {"ok": False, "error": f"child exited with status {status}", "stories_lost": None}
    msg = json.loads(text)
    out = {"saved_before_full": len(msg["saved"]), "error": msg["error"], "lost_while_full": msg["lost_while_full"],
           "says_full": bool(msg["error"]), "second_save_refused_cleanly": True}
    return _finish_full(out, db, msg["saved"])


# ----------------------------------------------------------------------------- campaign


def run_bad_file_campaign(work: Path, seconds: float = 60.0, seed: int = 0,
                          progress: Callable[[str], None] | None = None) -> dict:
    """Databases, packages and calibration files, about a third of ``seconds`` each,
    plus the full-disk check."""
    out: dict = {}
    t0 = time.monotonic()
    with tqdm(total=4, desc="bad files", unit="part") as bar:
        # Rates measured here: ~100 damaged DBs/s, ~15 packages/s, ~1000 calibration files/s.
        out["databases"] = run_db_corruption(work / "db", n=max(50, int(seconds / 3 * 60)), seed=seed)
        bar.update(1)
        out["packages"] = run_package_campaign(work / "pkg", n_mutants=max(50, int(seconds / 3 * 10)), seed=seed)
        bar.update(1)
        out["calibration"] = run_calibration_campaign(work / "calib", n=max(200, int(seconds / 3 * 500)), seed=seed)
        bar.update(1)
        out["full_disk"] = full_disk_check(work / "disk", seed=seed)
        bar.update(1)
    out["inputs"] = sum(out[k]["inputs"] for k in ("databases", "packages", "calibration"))
    out["crashes"] = sum(out[k]["crashes"] for k in ("databases", "packages", "calibration"))
    out["stories_lost"] = out["full_disk"].get("stories_lost") or 0
    out["failures"] = (out["crashes"] + out["packages"]["wrote_on_refusal"] + len(out["packages"]["crafted_accepted"])
                       + (0 if out["full_disk"]["ok"] else 1) + (0 if out["databases"]["original_unchanged"] else 1))
    out["seconds"] = round(time.monotonic() - t0, 1)
    return out
