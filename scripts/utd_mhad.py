"""Materialise the "utd-mhad" gesture studio of issue 31: the skeletons of the UTD
Multimodal Human Action Dataset (Chen, Jafari and Kehtarnavaz, ICIP 2015; University of
Texas at Dallas), 27 actions by 8 subjects, 4 takes each, as one public repository keeps them.

    python scripts/utd_mhad.py --out /work/data/utd-mhad [--mirror /work/.mirror] [--classes a1,a2,a3]
    storybeam eval --data /work/data/utd-mhad --methods storybeam,dtw-storybeam --split random,subject

It is the development studio for upper-body gestures (deliverable 2 of issue 31): a wave,
arm swipes to either side (the nearest thing to a "this way" guiding gesture), a clap, a
push, a knock, throws and swings that differ in where the hand goes and when, beside
walking and jogging in place. The performers are real people; the skeletons were
estimated by a Kinect (v1) depth camera, not by optical motion capture, so they are
noisier (about 2 cm) than the shared sets and carry no joint rotations.

The motions are **not** in this repository. UTD-MHAD is free for research with a
citation of the paper above; the repository that holds it
(``woo-chia-wei/kinect-sequence-classification``, commit :data:`COMMIT`) states no
licence of its own. Nothing is committed from it.

What is read: every ``data/Skeleton/a<action>_s<subject>_t<take>_skeleton.mat`` of that
commit (MATLAB files; ``d_skel`` is 20 joints × xyz × frames, metres, Y up, 30 frames a
second). The label comes from the action number (:data:`CLASSES`, the paper's list); an
unknown action number, a file without ``d_skel`` of that shape, or a non-finite value
stops the script with the path named.

The conversion: joint positions become a BVH whose every joint carries position channels
(as Bandai's files do) and no rotation, so StoryBeam's loader reads each frame's positions
back exactly (centimetres; the rest offsets are each bone's median). The Kinect joints take
the usual BVH names, so the canonical body maps them by name: the hip centre is ``Hips``,
the shoulder centre ``Neck``, the Kinect wrist ``LeftWrist`` (StoryBeam's hand, as CMU's
``lwrist`` is), the Kinect ankle ``LeftFoot`` and the Kinect foot ``LeftToeBase``.

Output: ``OUT/bvh/<trial>.bvh`` and ``OUT/labels.csv`` in the shared-data format
(``trial,label,subject,file,skeleton,seconds,description,source``); the subject is the
performer (s1 ... s8), so ``--split subject`` leaves one performer out.
"""
from __future__ import annotations

import argparse
import io
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from retrieval.library.bundle import write_labels  # noqa: E402
from retrieval.motion.formats.bvh import save_bvh  # noqa: E402
from retrieval.motion.model import Joint, Motion, Skeleton  # noqa: E402

REPOSITORY = "woo-chia-wei/kinect-sequence-classification"
COMMIT = "65e9b13950d7971c8d1e49e960f6796bd0dc9257"
FPS = 30.0
#: UTD-MHAD action number -> (label, what it shows), as the paper lists them
CLASSES: dict[int, tuple[str, str]] = {
    1: ("swipe_left", "right arm swipes to the left"),
    2: ("swipe_right", "right arm swipes to the right"),
    3: ("wave", "right hand waves"),
    4: ("clap", "both hands clap in front"),
    5: ("throw", "right arm throws"),
    6: ("arm_cross", "arms cross in front of the chest"),
    7: ("basketball_shoot", "shoots a basketball"),
    8: ("draw_x", "right hand draws an X"),
    9: ("draw_circle_cw", "right hand draws a circle, clockwise"),
    10: ("draw_circle_ccw", "right hand draws a circle, counter-clockwise"),
    11: ("draw_triangle", "right hand draws a triangle"),
    12: ("bowling", "bowls with the right hand"),
    13: ("boxing", "boxes to the front"),
    14: ("baseball_swing", "swings a baseball bat from the right"),
    15: ("tennis_swing", "tennis forehand swing with the right hand"),
    16: ("arm_curl", "curls both arms"),
    17: ("tennis_serve", "serves at tennis"),
    18: ("push", "pushes with both hands"),
    19: ("knock", "right hand knocks on a door"),
    20: ("catch", "right hand catches an object"),
    21: ("pickup_throw", "picks up and throws with the right hand"),
    22: ("jog", "jogs in place"),
    23: ("walk", "walks in place"),
    24: ("sit_to_stand", "stands up from sitting"),
    25: ("stand_to_sit", "sits down from standing"),
    26: ("lunge", "forward lunge, left foot forward"),
    27: ("squat", "squats, both arms stretched out"),
}
NAME = re.compile(r"^data/Skeleton/a(?P<action>\d+)_s(?P<subject>\d+)_t(?P<take>\d+)_skeleton\.mat$")

#: The Kinect v1 joints in the file's order (Skeleton_joint_order.txt): BVH name and
#: parent (a Kinect index; -1 for the root).
KINECT: tuple[tuple[str, int], ...] = (
    ("Head", 1), ("Neck", 2), ("Spine", 3), ("Hips", -1),
    ("LeftArm", 1), ("LeftForeArm", 4), ("LeftWrist", 5), ("LeftHandTip", 6),
    ("RightArm", 1), ("RightForeArm", 8), ("RightWrist", 9), ("RightHandTip", 10),
    ("LeftUpLeg", 3), ("LeftLeg", 12), ("LeftFoot", 13), ("LeftToeBase", 14),
    ("RightUpLeg", 3), ("RightLeg", 16), ("RightFoot", 17), ("RightToeBase", 18),
)
_CHANNELS = ["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"]
#: End sites' length (cm) beyond the head, the hand tips and the toes.
_TIP_CM = 5.0


class SourceError(ValueError):
    """A file of the snapshot that the rules above cannot place (its path in the message)."""


def plan(paths: list[str], actions: set[int] | None = None) -> list[dict[str, str]]:
    """The clips of a snapshot's file list, one row per skeleton file (sorted by trial),
    keeping only ``actions`` when given; :class:`SourceError` for an unknown action."""
    rows = []
    for p in sorted(paths):
        if not (p.startswith("data/Skeleton/") and p.endswith(".mat")):
            continue
        m = NAME.match(p)
        if not m:
            raise SourceError(f"{p}: not an a<action>_s<subject>_t<take>_skeleton.mat file name")
        action = int(m["action"])
        if action not in CLASSES:
            raise SourceError(f"{p}: action a{action} is not one of UTD-MHAD's a1-a{len(CLASSES)}")
        if actions is not None and action not in actions:
            continue
        label, shows = CLASSES[action]
        trial = f"a{action:02d}_s{int(m['subject'])}_t{int(m['take'])}"
        rows.append({"trial": trial, "label": label, "subject": f"s{int(m['subject'])}", "path": p,
                     "description": f"{shows} (UTD-MHAD a{action}, subject {m['subject']}, take {m['take']})"})
    if not rows:
        raise SourceError("no data/Skeleton/a*_s*_t*_skeleton.mat files" + (" of those actions" if actions else ""))
    return sorted(rows, key=lambda r: r["trial"])


def read_skeleton(data: bytes, where: str) -> np.ndarray:
    """(T, 20, 3) joint positions in metres from a UTD-MHAD skeleton file's bytes."""
    from scipy.io import loadmat

    try:
        mat = loadmat(io.BytesIO(data))
    except Exception as exc:  # scipy raises several kinds for a damaged file
        raise SourceError(f"{where}: not a MATLAB file ({exc})") from exc
    d = mat.get("d_skel")
    if d is None or d.ndim != 3 or d.shape[:2] != (len(KINECT), 3) or d.shape[2] < 2:
        raise SourceError(f"{where}: no d_skel of shape (20, 3, frames)")
    if not np.isfinite(d).all():
        raise SourceError(f"{where}: d_skel holds a non-finite value")
    return np.ascontiguousarray(np.transpose(d, (2, 0, 1)), dtype=np.float64)


def to_motion(xyz: np.ndarray, name: str = "") -> Motion:
    """A :class:`Motion` whose joints sit exactly at ``xyz`` ((T, 20, 3) metres, Y up):
    every joint's position channels hold its offset from its parent, rotations are
    identity, and the rest offsets are each bone's median."""
    cm = xyz * 100.0
    t = cm.shape[0]
    joints: list[Joint] = []
    index: dict[int, int] = {}
    local = []
    # parents before children: the root, then the rest in an order that respects KINECT's parents
    order = [3, 2, 1, 0, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19]
    for k in order:
        bvh_name, parent = KINECT[k]
        rel = cm[:, k] if parent < 0 else cm[:, k] - cm[:, parent]
        index[k] = len(joints)
        joints.append(Joint(bvh_name, -1 if parent < 0 else index[parent],
                            np.zeros(3) if parent < 0 else np.median(rel, axis=0), list(_CHANNELS), "ZXY"))
        local.append(rel)
        if k in (0, 7, 11, 15, 19):  # head, hand tips, toes: an end site beyond them
            if k == 0:
                direction = np.array([0.0, 1.0, 0.0])
            else:
                bone = np.median(rel, axis=0)
                direction = bone / max(float(np.linalg.norm(bone)), 1e-9)
            joints.append(Joint("End Site", index[k], direction * _TIP_CM))
            local.append(np.broadcast_to(direction * _TIP_CM, (t, 3)))
    skeleton = Skeleton(joints, metres_per_unit=0.01, up_axis="y", name="kinect-v1")
    translations = np.stack(local, axis=1)
    rotations = np.broadcast_to(np.eye(3), (t, len(joints), 3, 3)).copy()
    return Motion(skeleton, rotations, translations[:, 0].copy(), FPS, name=name,
                  joint_translations=translations.copy())


def _git(git_dir: Path, *args: str) -> bytes:
    out = subprocess.run(["git", "--git-dir", str(git_dir), *args], capture_output=True)
    if out.returncode != 0:
        raise SourceError(f"{git_dir}: git {' '.join(args)}: {out.stderr.decode(errors='replace').strip()}")
    return out.stdout


def materialise(git_dir: Path, out: Path, commit: str = COMMIT, actions: set[int] | None = None,
                progress=None) -> list[dict[str, str]]:
    """Convert the clips of ``commit`` into ``out/bvh`` and write its labels.csv; returns the rows."""
    paths = _git(git_dir, "ls-tree", "-r", "--name-only", commit).decode().splitlines()
    rows = plan(paths, actions)
    (out / "bvh").mkdir(parents=True, exist_ok=True)
    table = []
    for i, r in enumerate(rows):
        xyz = read_skeleton(_git(git_dir, "show", f"{commit}:{r['path']}"), r["path"])
        save_bvh(to_motion(xyz, r["trial"]), out / "bvh" / f"{r['trial']}.bvh", decimals=3)
        table.append({"trial": r["trial"], "label": r["label"], "subject": r["subject"],
                      "file": f"bvh/{r['trial']}.bvh", "skeleton": "",
                      "seconds": f"{xyz.shape[0] / FPS:.2f}", "description": r["description"],
                      "source": f"{REPOSITORY}@{commit[:12]}:{r['path']}"})
        if progress is not None:
            progress(i + 1, len(rows))
    write_labels(out / "labels.csv", table)
    return table


def _actions(text: str) -> set[int]:
    out = set()
    for word in text.split(","):
        m = re.fullmatch(r"a?(\d+)", word.strip())
        if not m or int(m[1]) not in CLASSES:
            raise SourceError(f"--classes: {word.strip()!r} is not an action a1-a{len(CLASSES)}")
        out.add(int(m[1]))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--mirror", type=Path, default=Path("/work/.mirror"))
    ap.add_argument("--classes", default=None, help="only these actions, e.g. a1,a2,a3,a22,a23")
    args = ap.parse_args(argv)
    actions = _actions(args.classes) if args.classes else None
    git_dir = args.mirror / REPOSITORY.replace("/", "+") / "repo"
    if not git_dir.is_dir():
        raise SourceError(f"{git_dir}: not found (fetch github:{REPOSITORY} first)")

    def progress(done: int, total: int) -> None:
        if done % 50 == 0 or done == total:
            print(f"  {done}/{total} clips", file=sys.stderr)

    table = materialise(git_dir, args.out, actions=actions, progress=progress)
    counts = Counter(r["label"] for r in table)
    print(f"wrote {len(table)} clips of {len(counts)} classes by {len({r['subject'] for r in table})} subjects "
          f"to {args.out}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except SourceError as exc:
        sys.exit(f"utd_mhad: {exc}")
