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
"""
from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path
from typing import Callable

from retrieval.errors import DatasetError
from retrieval.motion import Motion, Skeleton, resample
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
        motion = drop_leading_outlier(resample(load_motion(data_dir / src["file"], skeleton), fps))
        keep = min(motion.n_frames, int(round(max_seconds * fps)))
        motion = to_centimetres(motion.slice(0, keep))
        motion.name = trial
        rel = f"bvh/{trial}.bvh"
        save_bvh(motion, out_dir / rel, decimals=decimals)
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
    with open(out_dir / "labels.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=LABEL_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(out_rows)
    (out_dir / "CREDITS.md").write_text(_credits(out_rows, fps, max_seconds), encoding="utf-8")
    return out_rows


def _credits(rows: list[dict], fps: float, max_seconds: float) -> str:
    trials = ", ".join(r["trial"] for r in rows)
    return (
        "# Bundled motions: credits\n\n"
        f"{CMU_CREDIT}\n\n"
        "All clips come from the CMU Graphics Lab Motion Capture Database "
        "(http://mocap.cs.cmu.edu), which places no restriction on their use. They were "
        f"converted from the Acclaim ASF/AMC originals to BVH (CMU skeleton, centimetres, "
        f"Y up), resampled to {fps:g} fps and cut to at most {max_seconds:g} s by "
        "`storybeam build-library --data ../shared/data/cmu --out assets/motions`.\n\n"
        f"Trials: {trials}.\n"
    )

