"""Build the app's bundled motion library from the shared CMU data.

    storybeam build-library --data ../shared/data/cmu --out assets/motions

(the command, app/commands/build_library_cmd.py, calls :func:`build`; retrieval/ has no CLI).

The app ships a small labelled library (a dataset folder in the same format as the
shared one: ``labels.csv`` + motion files) so it works offline without the 100 MB
research data. Each clip in :data:`SELECTION` is read from its ASF/AMC original, resampled
to 30 fps (plenty for 3-second story animations and a quarter of the size), cut to at most
10 s (after dropping a glitched first frame, see :func:`drop_leading_outlier`),
converted to centimetres and written as BVH with 4 decimals through
:func:`retrieval.motion.formats.bvh.save_bvh`. The skeleton stays CMU's Acclaim one (joints ``root``,
``lfemur``, ...), which :func:`retrieval.motion.body.canonical_joint_map` understands.

**Moves the CMU folder lacks** (``OUT/moves/``, :data:`MOVES_FOLDER`): movements children make
that the shared CMU folder lacks (jumping jacks, a high front kick, dances), from other
studios and from CMU takes outside that folder, taken from public
repositories whose licences allow shipping them (``lab/datasets/act_moves_manifest.csv``,
``scripts/act_moves.py``, which converts each with :func:`convert_move`). When
``OUT/moves/labels.csv`` exists, :func:`build` lists its clips in the library's
``labels.csv`` too, so the app plays them and Act it out finds them.
"""
from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np
from scipy.ndimage import percentile_filter, uniform_filter1d

from retrieval.errors import DatasetError
from retrieval.motion import Motion, Skeleton, canonical_joint_map, positions, resample, world_from_native
from retrieval.motion.formats import detect_tpose, load_motion, save_bvh

#: Trials bundled with the app, chosen by hand from the shared labels for variety: every
#: class has several CMU subjects and styles (straight, turning, stealthy walks; jogs and
#: sprints; standing, forward and running jumps; two dancers; all nine kicks, since the
#: shared data has only nine). All are Acclaim (ASF/AMC) originals, so the library has one
#: skeleton family.
SELECTION: dict[str, tuple[str, ...]] = {
    "walk": ("02_01", "03_01", "05_01", "16_15", "16_17", "16_31", "17_03", "49_01"),
    "run": ("02_03", "09_01", "16_35", "16_42", "16_55", "127_03", "127_07"),
    "jump": ("02_04", "16_01", "16_05", "49_04", "118_01", "118_10", "127_25"),
    "dance": ("05_03", "05_11", "05_15", "05_16", "49_13", "49_14"),
    "kick": ("10_01", "10_02", "10_03", "10_05", "10_06", "11_01", "135_04", "135_07", "135_11"),
}
LABEL_COLUMNS = ("trial", "label", "subject", "file", "skeleton", "seconds", "description", "source")
CMU_CREDIT = (
    "The data used in this project was obtained from mocap.cs.cmu.edu. "
    "The database was created with funding from NSF EIA-0196217."
)


def to_centimetres(motion: Motion) -> Motion:
    """The same motion with lengths in centimetres (the most common BVH unit, so other
    tools such as Blender read the library at the right size)."""
    sk = motion.skeleton
    k = sk.metres_per_unit / 0.01
    joints = [replace(j, offset=j.offset * k) for j in sk.joints]
    skeleton = Skeleton(joints, metres_per_unit=0.01, up_axis=sk.up_axis, name=sk.name)
    jt = None if motion.joint_translations is None else motion.joint_translations * k
    return Motion(skeleton, motion.rotations, motion.root_translation * k, motion.fps, motion.name, jt)


def drop_leading_outlier(motion: Motion) -> Motion:
    """Without its first frame when that frame is a pose unlike the rest (a capture
    glitch: CMU 16_15 starts with two frames 15 cm off). The BVH reader would drop such a
    frame as a T-pose anyway; dropping it here keeps labels.csv's durations exact."""
    return motion.slice(1, motion.n_frames) if detect_tpose(motion) else motion


#: the library's sub-folder of moves from other studios (a labelled folder of its own)
MOVES_FOLDER = "moves"


def keep_joints(motion: Motion, prefix: str) -> Motion:
    """The motion on the joints whose names start with ``prefix`` (an end site ``X_end``
    counts as ``X``), each under its nearest kept ancestor: a rig's helper joints (a
    simulator's muscle bones beside the animation rig) dropped. The kept joints' world
    positions do not change when every dropped joint is a leaf or hangs off a dropped one."""
    sk = motion.skeleton
    if not sk.joints[0].name.startswith(prefix):
        raise DatasetError(f"{motion.name or 'motion'}: its root {sk.joints[0].name!r} is not a {prefix}* joint")
    new_index: dict[int, int] = {}
    joints = []
    for i, j in enumerate(sk.joints):
        base = j.name[:-4] if j.name.endswith("_end") else j.name
        if not base.startswith(prefix):
            continue
        parent = j.parent
        while parent >= 0 and parent not in new_index:
            parent = sk.joints[parent].parent
        new_index[i] = len(joints)
        joints.append(replace(j, parent=new_index[parent] if parent >= 0 else -1))
    keep = np.array(sorted(new_index), dtype=np.int64)
    skeleton = Skeleton(joints, metres_per_unit=sk.metres_per_unit, up_axis=sk.up_axis, name=sk.name)
    jt = None if motion.joint_translations is None else motion.joint_translations[:, keep]
    return Motion(skeleton, motion.rotations[:, keep], motion.root_translation, motion.fps, motion.name, jt)


#: the window (seconds) and percentile of :func:`level_floor`'s running floor
FLOOR_WINDOW_SECONDS = 1.0
FLOOR_PERCENTILE = 10.0


def level_floor(motion: Motion, window_seconds: float = FLOOR_WINDOW_SECONDS,
                percentile: float = FLOOR_PERCENTILE) -> Motion:
    """The motion with its floor made level: a capture made from video drifts (a Rokoko
    dance's lower foot rises from 0.14 m to 0.6 m over ten seconds while the dancer keeps
    a foot down). The running floor is the ``percentile`` of the lower foot's height over a
    centred ``window_seconds``, smoothed by a running mean over the same window; the root
    comes down by that floor's rise above its lowest value, so a real jump (under a third
    of a second in the air) stays a jump."""
    jm = canonical_joint_map(motion.skeleton)
    feet = [jm[j] for j in ("left_ankle", "right_ankle", "left_toe", "right_toe") if j in jm]
    lowest = positions(motion)[:, feet, 1].min(axis=1)
    size = max(1, int(round(window_seconds * motion.fps)) | 1)
    floor = uniform_filter1d(percentile_filter(lowest, percentile, size=size, mode="nearest"), size, mode="nearest")
    rise = (floor - floor.min()) / motion.skeleton.metres_per_unit  # native units, world up
    native_up = world_from_native(motion.skeleton).T @ np.array([0.0, 1.0, 0.0])
    root = motion.root_translation - rise[:, None] * native_up[None, :]
    return Motion(motion.skeleton, motion.rotations, root, motion.fps, motion.name, motion.joint_translations)


def convert_move(src: Path, out: Path, trial: str, keep: str = "", start: float = 0.0, fps: float = 30.0,
                 max_seconds: float = 10.0, decimals: int = 4, level: bool = False,
                 skeleton: Path | None = None) -> Motion:
    """One move from another studio as the library keeps its clips: read ``src`` (any
    format :func:`load_motion` reads; an AMC file with its ASF ``skeleton``), keep the
    joints named ``keep*`` (empty: all), with ``level`` its floor made level
    (:func:`level_floor`), resample to ``fps``, start ``start`` seconds in, cut to
    ``max_seconds``, centimetres, BVH with ``decimals`` decimals at ``out``. Returns the
    written motion."""
    motion = load_motion(src, skeleton)
    if keep:
        motion = keep_joints(motion, keep)
    if level:
        motion = level_floor(motion)
    return write_clip(motion, out, trial, fps, max_seconds, decimals, start)


def write_clip(motion: Motion, out: Path, trial: str, fps: float, max_seconds: float, decimals: int,
               start: float = 0.0) -> Motion:
    """A clip as the library keeps it: resampled to ``fps`` (a glitched first frame
    dropped, :func:`drop_leading_outlier`), from ``start`` seconds for at most
    ``max_seconds``, in centimetres, named ``trial``, written as BVH with ``decimals``
    decimals at ``out``. Returns the written motion."""
    motion = drop_leading_outlier(resample(motion, fps))
    first = int(round(start * fps))
    if not 0 <= first < motion.n_frames:
        raise DatasetError(f"{trial}: start {start:g} s is outside the clip ({motion.seconds:.2f} s)")
    motion = to_centimetres(motion.slice(first, min(motion.n_frames, first + int(round(max_seconds * fps)))))
    motion.name = trial
    out.parent.mkdir(parents=True, exist_ok=True)
    save_bvh(motion, out, decimals=decimals)
    return motion


def moves_rows(out_dir: Path) -> list[dict]:
    """The rows of ``out_dir/moves/labels.csv`` with their files relative to ``out_dir``
    (none when there is no such folder)."""
    folder = out_dir / MOVES_FOLDER
    if not (folder / "labels.csv").is_file():
        return []
    rows = list(read_labels(folder).values())
    for r in rows:
        if not (folder / r["file"]).is_file():
            raise DatasetError(f"{folder / 'labels.csv'}: {r['trial']}: file {r['file']} not found")
    return [{**{k: r[k] for k in LABEL_COLUMNS}, "file": f"{MOVES_FOLDER}/{r['file']}"} for r in rows]


def read_labels(data_dir: Path) -> dict[str, dict[str, str]]:
    """The shared dataset's rows by trial."""
    labels = data_dir / "labels.csv"
    if not labels.is_file():
        raise DatasetError(f"{labels}: not found (is --data the CMU folder with labels.csv?)")
    with open(labels, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    missing = set(LABEL_COLUMNS) - set(rows[0] if rows else {})
    if missing:
        raise DatasetError(f"{labels}: missing columns {', '.join(sorted(missing))}")
    return {r["trial"]: r for r in rows}


def build(data_dir: Path, out_dir: Path, fps: float = 30.0, max_seconds: float = 10.0, decimals: int = 4,
          progress: Callable[[int, int], None] | None = None) -> list[dict]:
    """Write the library into ``out_dir``; returns its label rows. ``progress(done, total)``
    is called after each clip."""
    rows = read_labels(data_dir)
    wanted = [(label, trial) for label, trials in SELECTION.items() for trial in trials]
    absent = [t for _, t in wanted if t not in rows]
    if absent:
        raise DatasetError(f"{data_dir / 'labels.csv'}: trials not listed: {', '.join(absent)}")
    (out_dir / "bvh").mkdir(parents=True, exist_ok=True)
    out_rows = []
    for done, (label, trial) in enumerate(wanted):
        src = rows[trial]
        if src["label"] != label:
            raise DatasetError(f"{trial}: labelled {src['label']!r} in the shared data, {label!r} here")
        skeleton = data_dir / src["skeleton"] if src["skeleton"] else None
        rel = f"bvh/{trial}.bvh"
        motion = write_clip(load_motion(data_dir / src["file"], skeleton), out_dir / rel, trial, fps, max_seconds,
                            decimals)
        out_rows.append({
            "trial": trial,
            "label": label,
            "subject": src["subject"],
            "file": rel,
            "skeleton": "",
            "seconds": f"{motion.seconds:.2f}",
            "description": src["description"],
            "source": f"CMU mocap {trial} (from {src['file']}; {src['source']})",
        })
        if progress is not None:
            progress(done + 1, len(wanted))
    moves = moves_rows(out_dir)
    clash = sorted({r["trial"] for r in moves} & {r["trial"] for r in out_rows})
    if clash:
        raise DatasetError(f"{out_dir / MOVES_FOLDER / 'labels.csv'}: trials also in the CMU selection: "
                           f"{', '.join(clash)}")
    out_rows += moves
    write_labels(out_dir / "labels.csv", out_rows)
    (out_dir / "CREDITS.md").write_text(_credits(out_rows, fps, max_seconds), encoding="utf-8")
    return out_rows


def write_labels(path: Path, rows: list[dict]) -> None:
    """A labelled folder's ``labels.csv`` (:mod:`retrieval.library.dataset`): a header of
    :data:`LABEL_COLUMNS`, then ``rows`` (dicts with those keys) in order, UTF-8, ``\\n`` line ends."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=LABEL_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


def _credits(rows: list[dict], fps: float, max_seconds: float) -> str:
    cmu = [r for r in rows if not r["file"].startswith(f"{MOVES_FOLDER}/")]
    moves = [r for r in rows if r["file"].startswith(f"{MOVES_FOLDER}/")]
    trials = ", ".join(r["trial"] for r in cmu)
    extra = "" if not moves else (
        f"\n## Moves the CMU folder lacks ({MOVES_FOLDER}/)\n\n"
        f"Trials: {', '.join(r['trial'] for r in moves)}. Their sources, licences and credits: "
        f"`{MOVES_FOLDER}/CREDITS.md`.\n")
    return (
        "# Bundled motions: credits\n\n"
        f"{CMU_CREDIT}\n\n"
        "The CMU clips come from the CMU Graphics Lab Motion Capture Database "
        "(http://mocap.cs.cmu.edu), which places no restriction on their use. They were "
        f"converted from the Acclaim ASF/AMC originals to BVH (CMU skeleton, centimetres, "
        f"Y up), resampled to {fps:g} fps and cut to at most {max_seconds:g} s by "
        "`storybeam build-library --data ../shared/data/cmu --out assets/motions`.\n\n"
        f"Trials: {trials}.\n"
        f"{extra}"
    )

