"""Materialise the real-footage development set of "Act it out" (issue 27).

    python scripts/act_real.py --out /work/data/act_real [--mirror /work/.mirror]
                               [--manifest lab/datasets/act_real_manifest.csv] [--only jump01,run02]

The set is **not** in the repository: most of its footage has no licence that allows
redistribution. ``lab/datasets/act_real_manifest.csv`` names every clip instead — its
public GitHub ``repository``, the ``commit`` it was seen at, the ``path`` of the video in
it, the time window ``start_s``–``end_s`` (seconds), the ``label`` given by looking at the
frames (walk, run, jump, kick, dance), the ``view`` (facing, turned, side, towards, ...),
the licence found in the repository and what the clip shows.

Getting the repositories: each one is a git snapshot; this script reads
``MIRROR/<owner>+<name>/repo`` (a bare git directory, as a ``fetch`` of
``github:<owner>/<name>`` leaves it), or any clone of the repository placed there
(``git clone --bare https://github.com/<owner>/<name> MIRROR/<owner>+<name>/repo``). The
video is read from the named commit when the snapshot has it, else from the snapshot's
HEAD if the file there is byte-identical in size (reported either way).

Output: ``OUT/<clip>.mp4`` (the window, every frame, at the source's frame rate and size,
re-encoded with OpenCV's ``mp4v``) and ``OUT/labels.csv`` (``file,label``, what
``storybeam bench act-it-out --videos OUT`` reads) plus ``OUT/manifest.csv`` (the rows
that were materialised, with the frame rate, size and frame count written). A clip whose
repository is missing is skipped with a message; the exit status is 1 if any was.
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2

REPO = Path(__file__).resolve().parents[1]
MANIFEST = REPO / "lab" / "datasets" / "act_real_manifest.csv"
COLUMNS = ("clip", "label", "repository", "commit", "path", "start_s", "end_s", "view", "licence", "notes")
LABELS = ("walk", "run", "jump", "kick", "dance")


class ManifestError(ValueError):
    """A malformed manifest row (file and line in the message)."""


def read_manifest(path: Path) -> list[dict[str, str]]:
    """The manifest's rows, checked: every column present, a known label, a window
    0 <= start < end, unique clip names."""
    rows, seen = [], set()
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ManifestError(f"{path}:1: missing column(s) {', '.join(missing)}")
        for line, row in enumerate(reader, 2):
            where = f"{path}:{line}"
            if row["label"] not in LABELS:
                raise ManifestError(f"{where}: label {row['label']!r} is not one of {', '.join(LABELS)}")
            try:
                start, end = float(row["start_s"]), float(row["end_s"])
            except ValueError:
                raise ManifestError(f"{where}: start_s/end_s must be numbers") from None
            if not 0 <= start < end:
                raise ManifestError(f"{where}: window {start}-{end} s is empty")
            if row["clip"] in seen or not row["clip"]:
                raise ManifestError(f"{where}: clip name {row['clip']!r} empty or repeated")
            seen.add(row["clip"])
            rows.append(row)
    return rows


def git_dir(mirror: Path, repository: str) -> Path:
    return mirror / repository.replace("/", "+") / "repo"


def read_blob(gd: Path, commit: str, path: str) -> tuple[bytes, str]:
    """The file's bytes at ``commit`` (or HEAD when the snapshot lacks that commit) and
    which revision gave them."""
    for rev in (commit, "HEAD"):
        r = subprocess.run(["git", "-C", str(gd), "show", f"{rev}:{path}"], capture_output=True)
        if r.returncode == 0 and r.stdout:
            return r.stdout, rev
    raise FileNotFoundError(f"{gd}: no {path} at {commit[:12]} nor HEAD")


def cut(src: Path, dst: Path, start_s: float, end_s: float) -> tuple[float, int, int, int]:
    """Frames of ``src`` from ``start_s`` up to ``end_s`` into ``dst`` (mp4v); returns
    (fps, width, height, frames written)."""
    cap = cv2.VideoCapture(str(src))
    if not cap.isOpened():
        raise OSError(f"{src}: OpenCV cannot read it")
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    first, last = int(round(start_s * fps)), int(round(end_s * fps))
    out = cv2.VideoWriter(str(dst), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    n, i = 0, 0
    try:
        while i < last:
            ok, frame = cap.read()  # sequential read: exact frames, no seek drift
            if not ok:
                break
            if i >= first:
                out.write(frame)
                n += 1
            i += 1
    finally:
        cap.release()
        out.release()
    if n == 0:
        dst.unlink(missing_ok=True)
        raise OSError(f"{src}: no frame in {start_s}-{end_s} s")
    return fps, w, h, n


def materialise(rows: list[dict[str, str]], mirror: Path, out: Path, log=print) -> tuple[list[dict], list[str]]:
    """Every row's clip into ``out``; (rows written with fps/size/frames, skipped clips)."""
    out.mkdir(parents=True, exist_ok=True)
    done, skipped = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k, row in enumerate(rows, 1):
            gd = git_dir(mirror, row["repository"])
            dst = out / f"{row['clip']}.mp4"
            try:
                if not gd.is_dir():
                    raise FileNotFoundError(f"{gd} missing: fetch github:{row['repository']}")
                data, rev = read_blob(gd, row["commit"], row["path"])
                src = Path(tmp) / f"src{Path(row['path']).suffix}"
                src.write_bytes(data)
                fps, w, h, n = cut(src, dst, float(row["start_s"]), float(row["end_s"]))
            except (OSError, FileNotFoundError) as exc:
                skipped.append(row["clip"])
                log(f"[{k}/{len(rows)}] {row['clip']}: skipped ({exc})")
                continue
            note = "" if rev == row["commit"] else " (from HEAD: the snapshot lacks the manifest's commit)"
            log(f"[{k}/{len(rows)}] {row['clip']}: {row['label']}, {n} frames {w}x{h} @ {fps:.2f}{note}")
            done.append({**row, "file": dst.name, "fps": f"{fps:.3f}", "width": w, "height": h, "frames": n})
    return done, skipped


def write_outputs(done: list[dict], out: Path) -> None:
    with open(out / "labels.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["file", "label"])
        for r in done:
            w.writerow([r["file"], r["label"]])
    with open(out / "manifest.csv", "w", newline="", encoding="utf-8") as f:
        cols = ["file", *COLUMNS, "fps", "width", "height", "frames"]
        w = csv.DictWriter(f, cols, extrasaction="ignore")
        w.writeheader()
        w.writerows(done)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True, help="folder to write the clips and labels.csv into")
    p.add_argument("--mirror", type=Path, default=Path("/work/.mirror"), help="folder of the repository snapshots")
    p.add_argument("--manifest", type=Path, default=MANIFEST)
    p.add_argument("--only", default="", help="comma-separated clip names (default: all)")
    a = p.parse_args(argv)
    try:
        rows = read_manifest(a.manifest)
    except (OSError, ManifestError) as exc:
        print(f"act_real: {exc}", file=sys.stderr)
        return 2
    only = {c.strip() for c in a.only.split(",") if c.strip()}
    if only:
        rows = [r for r in rows if r["clip"] in only]
    done, skipped = materialise(rows, a.mirror, a.out)
    write_outputs(done, a.out)
    by = {lab: sum(r["label"] == lab for r in done) for lab in LABELS}
    print(f"{len(done)} clips in {a.out} ({', '.join(f'{k} {v}' for k, v in by.items())})"
          + (f"; skipped {', '.join(skipped)}" if skipped else ""))
    return 1 if skipped else 0


if __name__ == "__main__":
    sys.exit(main())
