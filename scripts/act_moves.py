"""Materialise the bundled library's moves from other studios (``assets/motions/moves``).

    python scripts/act_moves.py [--mirror /work/.mirror] [--out assets/motions/moves]
                                [--manifest lab/datasets/act_moves_manifest.csv] [--sheet PNG]
    storybeam build-library --data ../shared/data/cmu --out assets/motions   # lists them

Why: real children do jumping jacks, high front kicks and step-and-swing dances; the CMU
folder has none of them, and Act it out can only answer with a movement its library holds
(docs/notebook/act-it-out.md, 2026-11-28). These clips come from public repositories whose
licences allow shipping them (MIT, Apache-2.0), so the converted files are committed; this
script is how they were made.

``lab/datasets/act_moves_manifest.csv`` names each clip: its library ``trial``, ``label``
and ``subject`` (the capture set: one performer or studio), the public GitHub ``repository``, the ``commit`` and ``path`` of the file,
its ``skeleton`` (an AMC file's ASF, in the same commit; empty for BVH), the
joint-name prefix to ``keep`` (empty: every joint; ``Character1_`` drops a simulator's
muscle helper joints), where to ``start`` (seconds: a T-pose held at the start is cut)
and ``end`` (seconds into the file; empty: at most 10 s after ``start``), the movement's
window in a longer take,
whether to ``level`` its floor (``yes``: a video capture's drifting floor,
:func:`retrieval.library.bundle.level_floor`), its ``seconds``, a ``description``, the
``licence`` and ``notes``.

Getting the repositories: ``MIRROR/<owner>+<name>/repo`` is a bare git directory, as a
``fetch`` of ``github:<owner>/<name>`` leaves it (or ``git clone --bare``). Each file is
read with ``git show COMMIT:PATH`` and converted by
:func:`retrieval.library.bundle.convert_move` (30 fps, at most 10 s, centimetres, BVH);
the repository's ``LICENSE`` is copied beside the clips. Output: ``OUT/<trial>.bvh``,
``OUT/labels.csv``, ``OUT/CREDITS.md`` and ``OUT/LICENSE-<owner>-<name>.txt``.
``--sheet PNG`` also draws each written clip as stick figures, eight moments each, seen
from the front: how the labels were checked by eye.
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from retrieval.errors import DatasetError  # noqa: E402
from retrieval.library.bundle import convert_move, write_labels  # noqa: E402

MANIFEST = REPO / "lab" / "datasets" / "act_moves_manifest.csv"
COLUMNS = ("trial", "label", "subject", "repository", "commit", "path", "skeleton", "keep", "start", "end", "level",
           "seconds", "description", "licence", "notes")
LABELS = ("walk", "run", "jump", "kick", "dance")


def read_manifest(path: Path) -> list[dict[str, str]]:
    """The manifest's rows, checked (a missing column or an unknown label names the line)."""
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        missing = set(COLUMNS) - set(reader.fieldnames or ())
        if missing:
            raise DatasetError(f"{path}: missing columns {', '.join(sorted(missing))}")
        rows = []
        for line, row in enumerate(reader, start=2):
            if row["label"] not in LABELS:
                raise DatasetError(f"{path}:{line}: label {row['label']!r} is not one of {', '.join(LABELS)}")
            try:
                if float(row["start"] or 0) < 0:
                    raise ValueError
            except ValueError:
                raise DatasetError(f"{path}:{line}: start must be seconds (0 or more), got {row['start']!r}") from None
            try:
                if row["end"] and float(row["end"]) <= float(row["start"] or 0):
                    raise ValueError
            except ValueError:
                raise DatasetError(f"{path}:{line}: end must be seconds after start, got {row['end']!r}") from None
            if row["path"].lower().endswith(".amc") != bool(row["skeleton"]):
                raise DatasetError(f"{path}:{line}: an AMC file needs its ASF in skeleton, and only an AMC file")
            if row["level"].strip().lower() not in ("", "yes"):
                raise DatasetError(f"{path}:{line}: level must be 'yes' or empty, got {row['level']!r}")
            if len(row["commit"]) != 40:
                raise DatasetError(f"{path}:{line}: commit must be 40 hex digits")
            rows.append(row)
    return rows


def git_show(mirror: Path, repository: str, commit: str, path: str) -> bytes:
    git_dir = mirror / repository.replace("/", "+") / "repo"
    if not git_dir.is_dir():
        raise DatasetError(f"{git_dir}: not found (fetch github:{repository} first)")
    out = subprocess.run(["git", "--git-dir", str(git_dir), "show", f"{commit}:{path}"], capture_output=True)
    if out.returncode != 0:
        raise DatasetError(f"{repository}@{commit[:7]}:{path}: {out.stderr.decode(errors='replace').strip()}")
    return out.stdout


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mirror", type=Path, default=Path("/work/.mirror"))
    ap.add_argument("--out", type=Path, default=REPO / "assets" / "motions" / "moves")
    ap.add_argument("--manifest", type=Path, default=MANIFEST)
    ap.add_argument("--sheet", type=Path, help="draw the written clips as stick figures into this PNG")
    args = ap.parse_args(argv)
    rows = read_manifest(args.manifest)
    args.out.mkdir(parents=True, exist_ok=True)
    labels, licences = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in rows:
            src = Path(tmp) / f"{r['trial']}{Path(r['path']).suffix}"
            src.write_bytes(git_show(args.mirror, r["repository"], r["commit"], r["path"]))
            skeleton = None
            if r["skeleton"]:
                skeleton = Path(tmp) / f"{r['trial']}.asf"
                skeleton.write_bytes(git_show(args.mirror, r["repository"], r["commit"], r["skeleton"]))
            start = float(r["start"] or 0)
            length = min(10.0, float(r["end"]) - start) if r["end"] else 10.0
            motion = convert_move(src, args.out / f"{r['trial']}.bvh", r["trial"], r["keep"], start,
                                  max_seconds=length, level=r["level"].strip().lower() == "yes", skeleton=skeleton)
            licences.setdefault(r["repository"], (r["commit"], r["licence"]))
            labels.append({"trial": r["trial"], "label": r["label"], "subject": r["subject"],
                           "file": f"{r['trial']}.bvh", "skeleton": "", "seconds": f"{motion.seconds:.2f}",
                           "description": r["description"],
                           "source": f"{r['repository']}@{r['commit'][:7]}:{r['path']} ({r['licence']})"})
            print(f"{r['trial']}: {motion.n_frames} frames, {motion.seconds:.2f} s, "
                  f"{motion.skeleton.n_joints} joints <- {r['repository']}:{r['path']}")
    for repository, (commit, _) in licences.items():
        text = git_show(args.mirror, repository, commit, "LICENSE")
        (args.out / f"LICENSE-{repository.replace('/', '-')}.txt").write_bytes(text)
    write_labels(args.out / "labels.csv", labels)
    (args.out / "CREDITS.md").write_text(credits(rows), encoding="utf-8")
    if args.sheet:
        contact_sheet([args.out / f"{r['trial']}.bvh" for r in rows], args.sheet)
        print(f"wrote {args.sheet}")
    return 0


#: the stick figure's bones, canonical joint names
BONES = (("hips", "spine"), ("spine", "neck"), ("neck", "head"), ("neck", "left_shoulder"),
         ("left_shoulder", "left_elbow"), ("left_elbow", "left_hand"), ("neck", "right_shoulder"),
         ("right_shoulder", "right_elbow"), ("right_elbow", "right_hand"), ("hips", "left_hip"),
         ("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("hips", "right_hip"),
         ("right_hip", "right_knee"), ("right_knee", "right_ankle"))


def contact_sheet(files: list[Path], png: Path, moments: int = 8) -> None:
    """Each clip a row of ``moments`` stick figures (metres, Y up, x across; the right side
    red), evenly spaced in time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from retrieval.motion import canonical_joint_map, load_motion, positions

    fig, axes = plt.subplots(len(files), moments, figsize=(2 * moments, 2.4 * len(files)), squeeze=False)
    for row, path in zip(axes, files):
        m = load_motion(path)
        p, jm = positions(m), canonical_joint_map(m.skeleton)
        for ax, t in zip(row, np.linspace(0, len(p) - 1, moments).astype(int)):
            q = p[t]
            for a, b in BONES:
                ax.plot(q[[jm[a], jm[b]], 0], q[[jm[a], jm[b]], 1], "r" if "right" in a + b else "k")
            ax.set_xlim(q[jm["hips"], 0] - 1, q[jm["hips"], 0] + 1)
            ax.set_ylim(-0.1, 2.2)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{path.stem} {t / m.fps:.1f} s", fontsize=8)
    fig.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=60)
    plt.close(fig)


def credits(rows: list[dict[str, str]]) -> str:
    lines = ["# Moves the CMU folder lacks: credits", "",
             "Movements children make that the shared CMU folder lacks, converted by `scripts/act_moves.py` from",
             "`lab/datasets/act_moves_manifest.csv` (30 fps, at most 10 s, centimetres, BVH). Each",
             "repository's licence is copied beside the clips (`LICENSE-<owner>-<name>.txt`).", ""]
    for repository in dict.fromkeys(r["repository"] for r in rows):
        mine = [r for r in rows if r["repository"] == repository]
        lines.append(f"- **{repository}** (https://github.com/{repository}, commit {mine[0]['commit'][:7]}), "
                     f"licence {mine[0]['licence']}: " + "; ".join(f"`{r['trial']}` from `{r['path']}` "
                                                                    f"({r['notes']})" for r in mine) + ".")
    cmu = [r["trial"] for r in rows if "CMU" in r["licence"] + r["notes"]]
    if cmu:
        lines += ["", ", ".join(f"`{t}`" for t in cmu) + " are CMU captures: \"The data used in this project was "
                  "obtained", "from mocap.cs.cmu.edu. The database was created with funding from NSF EIA-0196217.\""]
    lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    try:
        sys.exit(main())
    except DatasetError as exc:
        sys.exit(f"act_moves: {exc}")
