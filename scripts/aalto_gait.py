"""Materialise the "aalto-gait" development studio of issue 31 (styles: walk, limp and run
in several styles by two actors, captured by another studio than the shared sets).

    python scripts/aalto_gait.py --out /work/data/aalto-gait [--mirror /work/.mirror]
                                 [--manifest lab/datasets/aalto_gait_manifest.csv]

The motions are **not** in the repository (no licence for the BVH files is stated).
``lab/datasets/aalto_gait_manifest.csv`` names every clip: the public GitHub
``repository`` (Klaus Förger's Aalto University set of "Impact of Varying Vocabularies on
Controlling Motion of a Virtual Actor", as kept in sergioisidoro/MultimodalTranslation),
the ``commit`` and ``path`` of the BVH file, its ``label`` (walk, limp, run), ``subject``
(the actor: k or t) and ``style``. The files are the actors' own takes (regular, fast,
slow, angry, sad; a single style name) and the set's blends of takes *of one class by one
actor* (``style`` lists the weights, e.g. ``angry25+sad75``) — blends across classes
(a walk mixed with a limp) are left out, so every label is unambiguous; files with the
same bytes or the same blend are listed once.

Getting the repository: ``MIRROR/sergioisidoro+MultimodalTranslation/repo`` is a bare git
directory (what a ``fetch`` of ``github:sergioisidoro/MultimodalTranslation`` leaves), or
``git clone --bare https://github.com/sergioisidoro/MultimodalTranslation`` placed there.

Output: ``OUT/bvh/<trial>.bvh`` and ``OUT/labels.csv`` in the shared-data format
(``trial,label,subject,file,skeleton,seconds,description,source``), which ``storybeam
eval --data OUT`` reads; ``--split subject`` then leaves one actor out.
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MANIFEST = REPO / "lab" / "datasets" / "aalto_gait_manifest.csv"
COLUMNS = ("trial", "label", "subject", "style", "repository", "commit", "path", "blend")
LABELS = ("walk", "limp", "run")


class ManifestError(ValueError):
    """A malformed manifest row (file and line in the message)."""


def read_manifest(path: Path) -> list[dict[str, str]]:
    """The manifest's rows, checked: every column, a known label, unique trial names."""
    with open(path, newline="", encoding="utf-8") as f:
        header = next(csv.reader(f), [])
        f.seek(0)
        rows = list(csv.DictReader(f))
    if set(COLUMNS) - set(header):
        raise ManifestError(f"{path}:1: missing column(s) {', '.join(c for c in COLUMNS if c not in header)}")
    names = Counter(r["trial"] for r in rows)
    for line, row in enumerate(rows, 2):
        if row["label"] not in LABELS:
            raise ManifestError(f"{path}:{line}: label {row['label']!r} is not one of {', '.join(LABELS)}")
        if not row["trial"] or names[row["trial"]] > 1:
            raise ManifestError(f"{path}:{line}: trial name {row['trial']!r} empty or repeated")
    return rows


def bvh_seconds(text: str) -> float:
    """Duration of a BVH file: ``Frames`` × ``Frame Time``."""
    frames = frame_time = None
    for line in text.splitlines():
        if line.startswith("Frames:"):
            frames = int(line.split(":")[1])
        elif line.startswith("Frame Time:"):
            frame_time = float(line.split(":")[1])
            break
    if frames is None or frame_time is None:
        raise ValueError("no Frames / Frame Time lines")
    return frames * frame_time


def materialise(rows: list[dict[str, str]], mirror: Path, out: Path, log=print) -> int:
    """Every row's BVH into ``out/bvh`` and ``out/labels.csv``; returns the clips written."""
    (out / "bvh").mkdir(parents=True, exist_ok=True)
    written = []
    for row in rows:
        gd = mirror / row["repository"].replace("/", "+") / "repo"
        text = None
        for rev in (row["commit"], "HEAD"):
            r = subprocess.run(["git", "-C", str(gd), "show", f"{rev}:{row['path']}"], capture_output=True)
            if r.returncode == 0 and r.stdout:
                text = r.stdout.decode("utf-8", "replace")
                break
        if text is None:
            log(f"skip {row['trial']}: {row['path']} not in {gd}")
            continue
        (out / "bvh" / f"{row['trial']}.bvh").write_text(text, encoding="utf-8")
        written.append({
            "trial": row["trial"], "label": row["label"], "subject": row["subject"],
            "file": f"bvh/{row['trial']}.bvh", "skeleton": "", "seconds": f"{bvh_seconds(text):.2f}",
            "description": f"{row['label']} ({row['style']}, actor {row['subject']})",
            "source": f"{row['repository']}@{row['commit'][:12]}:{row['path']}",
        })
    with open(out / "labels.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=list(written[0]) if written else ["trial"])
        w.writeheader()
        w.writerows(written)
    log(f"{len(written)} of {len(rows)} clips -> {out}")
    return len(written)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--mirror", type=Path, default=Path("/work/.mirror"))
    ap.add_argument("--manifest", type=Path, default=MANIFEST)
    args = ap.parse_args(argv)
    rows = read_manifest(args.manifest)
    return 0 if materialise(rows, args.mirror, args.out) == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
