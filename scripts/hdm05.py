"""Materialise the "hdm05" development studio of issue 31: 287 cut clips of the HDM05
motion database (Müller et al., MPI Informatik / Universität Bonn, captured at the
Hochschule der Medien Stuttgart), 11 classes by 5 actors, as one public repository keeps them.

    python scripts/hdm05.py --out /work/data/hdm05 [--mirror /work/.mirror]
    storybeam eval --data /work/data/hdm05 --methods storybeam,dtw-storybeam --split random,subject

The motions are **not** in this repository. HDM05's site gives the database under CC
BY-SA 3.0 and asks for the acknowledgement "The data used in this project was obtained
from HDM05"; the repository that holds this subset (``zhangchi8620/JointLearning-HDM05``,
commit :data:`COMMIT`) states no licence of its own. Nothing is converted: the ASF/AMC
files are copied as they are, and StoryBeam reads them (120 fps).

What is read: every ``{train,test}/<k>/HDM_<actor>_<class>_<take>_120.amc`` of that
commit, with its actor's ``HDM_<actor>.asf`` from the same folder. The label comes from the
file name's HDM05 class (:data:`CLASSES`). A class outside that table, or an AMC without its
ASF, stops the script with the path named. The subject is the actor (bd, bk, dg, mm, tr), so
``--split subject`` leaves one actor out.

Getting the repository: ``MIRROR/zhangchi8620+JointLearning-HDM05/repo`` is a bare git
directory (what a ``fetch`` of ``github:zhangchi8620/JointLearning-HDM05`` leaves).
Output: ``OUT/amc/<trial>.amc``, ``OUT/asf/HDM_<actor>.asf`` and ``OUT/labels.csv`` in the
shared-data format (``trial,label,subject,file,skeleton,seconds,description,source``).
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from retrieval.library.bundle import write_labels  # noqa: E402

REPOSITORY = "zhangchi8620/JointLearning-HDM05"
COMMIT = "b252ad65598e052c38f49490c1ac9dbadc283fd3"
#: HDM05 class in the file name -> (label, what it shows)
CLASSES: dict[str, tuple[str, str]] = {
    "depositFloorR": ("deposit_floor_right", "puts something on the floor with the right hand"),
    "elbowToKnee1RepsLelbowStart": ("elbow_to_knee", "elbow to the opposite knee, once, left elbow first"),
    "grabHighR": ("grab_high_right", "reaches up and grabs something high with the right hand"),
    "hopBothLegs1hops": ("hop_both_legs", "one hop on both legs"),
    "jogLeftCircle4StepsRstart": ("jog_left_circle", "jogs four steps on a circle to the left"),
    "kickLFront1Reps": ("kick_left_front", "one front kick with the left foot"),
    "lieDownFloor": ("lie_down_floor", "lies down on the floor"),
    "rotateArmsBothBackward1Reps": ("rotate_arms_backward", "both arms circle backwards, once"),
    "sneak2StepsLStart": ("sneak", "sneaks two steps"),
    "squat1Reps": ("squat", "one squat"),
    "throwBasketball": ("throw_basketball", "throws a basketball"),
}
NAME = re.compile(r"^(?:train|test)/\d+/HDM_(?P<actor>[a-z]{2})_(?P<cls>[A-Za-z0-9]+)_(?P<take>\d+)_120\.amc$")
AMC_FPS = 120.0


class SourceError(ValueError):
    """A file of the snapshot that the rules above cannot place (its path in the message)."""


def plan(paths: list[str]) -> list[dict[str, str]]:
    """The clips of a snapshot's file list: one row per AMC (sorted by trial), with the
    ASF it needs; :class:`SourceError` for an AMC whose name or class is unknown or whose
    folder lacks its actor's ASF."""
    present = set(paths)
    rows = []
    for p in sorted(paths):
        if not p.endswith(".amc") or not p.startswith(("train/", "test/")):
            continue
        m = NAME.match(p)
        if not m:
            raise SourceError(f"{p}: not an HDM_<actor>_<class>_<take>_120.amc file name")
        if m["cls"] not in CLASSES:
            raise SourceError(f"{p}: HDM05 class {m['cls']!r} is not one of {', '.join(sorted(CLASSES))}")
        asf = f"{p.rsplit('/', 1)[0]}/HDM_{m['actor']}.asf"
        if asf not in present:
            raise SourceError(f"{p}: its skeleton {asf} is not in the snapshot")
        label, shows = CLASSES[m["cls"]]
        rows.append({"trial": Path(p).stem, "label": label, "subject": m["actor"], "amc": p, "asf": asf,
                     "description": f"{shows} (HDM05 {m['cls']}, actor {m['actor']}, take {m['take']})"})
    if not rows:
        raise SourceError("no HDM_*_120.amc files under train/ or test/")
    if len({r["trial"] for r in rows}) != len(rows):
        raise SourceError("two AMC files share a name")
    return sorted(rows, key=lambda r: r["trial"])


def _git(git_dir: Path, *args: str) -> bytes:
    out = subprocess.run(["git", "--git-dir", str(git_dir), *args], capture_output=True)
    if out.returncode != 0:
        raise SourceError(f"{git_dir}: git {' '.join(args)}: {out.stderr.decode(errors='replace').strip()}")
    return out.stdout


def frames_of(amc: bytes) -> int:
    """Frames of an AMC file: its lines that are a frame number alone."""
    return sum(1 for line in amc.splitlines() if line.strip().isdigit())


def materialise(git_dir: Path, out: Path, commit: str = COMMIT) -> list[dict[str, str]]:
    """Copy the clips of ``commit`` into ``out`` and write its labels.csv; returns the rows."""
    paths = _git(git_dir, "ls-tree", "-r", "--name-only", commit).decode().splitlines()
    rows = plan(paths)
    (out / "amc").mkdir(parents=True, exist_ok=True)
    (out / "asf").mkdir(parents=True, exist_ok=True)
    table = []
    for r in rows:
        amc = _git(git_dir, "show", f"{commit}:{r['amc']}")
        (out / "amc" / f"{r['trial']}.amc").write_bytes(amc)
        asf_name = f"HDM_{r['subject']}.asf"
        if not (out / "asf" / asf_name).is_file():
            (out / "asf" / asf_name).write_bytes(_git(git_dir, "show", f"{commit}:{r['asf']}"))
        table.append({"trial": r["trial"], "label": r["label"], "subject": r["subject"],
                      "file": f"amc/{r['trial']}.amc", "skeleton": f"asf/{asf_name}",
                      "seconds": f"{frames_of(amc) / AMC_FPS:.2f}", "description": r["description"],
                      "source": f"{REPOSITORY}@{commit[:12]}:{r['amc']}"})
    write_labels(out / "labels.csv", table)
    return table


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--mirror", type=Path, default=Path("/work/.mirror"))
    args = ap.parse_args(argv)
    git_dir = args.mirror / REPOSITORY.replace("/", "+") / "repo"
    if not git_dir.is_dir():
        raise SourceError(f"{git_dir}: not found (fetch github:{REPOSITORY} first)")
    table = materialise(git_dir, args.out)
    counts = Counter(r["label"] for r in table)
    print(f"wrote {len(table)} clips of {len(counts)} classes by {len({r['subject'] for r in table})} actors "
          f"to {args.out}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except SourceError as exc:
        sys.exit(f"hdm05: {exc}")
