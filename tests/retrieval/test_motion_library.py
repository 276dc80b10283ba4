"""The bundled motion library in assets/motions (needs no shared data, except the last
test, which checks the clips against their CMU originals)."""
from __future__ import annotations

import csv
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from retrieval.motion import canonical_joint_map
from retrieval.library.bundle import CMU_CREDIT, LABEL_COLUMNS, MOVES_FOLDER, SELECTION, drop_leading_outlier
from retrieval.motion import positions, resample
from retrieval.motion.formats import load_motion

CLASSES = {"walk", "run", "jump", "dance", "kick"}


@pytest.fixture(scope="module")
def library(repo_root) -> Path:
    return repo_root / "assets" / "motions"


@pytest.fixture(scope="module")
def rows(library) -> list[dict]:
    with open(library / "labels.csv", newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        assert tuple(reader.fieldnames) == LABEL_COLUMNS
        return list(reader)


def _is_move(row: dict) -> bool:
    """A move from another studio (``assets/motions/moves``), not a CMU clip."""
    return row["file"].startswith(f"{MOVES_FOLDER}/")


def test_library_has_every_class(rows):
    counts = Counter(r["label"] for r in rows)
    assert set(counts) == CLASSES
    assert min(counts.values()) >= 4, counts
    assert 30 <= len(rows) <= 50
    assert len({r["trial"] for r in rows}) == len(rows)


def test_library_clips_load_and_look_human(library, rows):
    for r in rows:
        m = load_motion(library / r["file"])
        assert m.fps == 30.0, r["trial"]
        assert m.seconds <= 10.0 + 1e-9
        assert m.seconds == pytest.approx(float(r["seconds"]), abs=0.006), r["trial"]
        assert m.skeleton.metres_per_unit == 0.01  # detected
        # CMU's clips are Y up; a move keeps its studio's axis (FAIR's jumps are Z up)
        assert m.skeleton.up_axis == "y" or _is_move(r), r["trial"]
        cmap = canonical_joint_map(m.skeleton)
        p = positions(m)
        head = p[:, cmap["head"], 1]
        ankles = p[:, [cmap["left_ankle"], cmap["right_ankle"]], 1].max(axis=1)
        assert np.median(head - ankles) > 0.9, r["trial"]


def test_library_is_small_and_credited(library, rows):
    size = sum(f.stat().st_size for f in library.rglob("*") if f.is_file())
    assert size < 4_000_000
    assert CMU_CREDIT in (library / "CREDITS.md").read_text(encoding="utf-8")
    cmu = [r["trial"] for r in rows if not _is_move(r)]
    assert sorted(cmu) == sorted(t for ts in SELECTION.values() for t in ts)
    with open(library / MOVES_FOLDER / "labels.csv", newline="", encoding="utf-8") as fh:
        moves = [r["trial"] for r in csv.DictReader(fh)]
    assert [r["trial"] for r in rows if _is_move(r)] == moves


def test_library_matches_cmu_originals(cmu_dir, library, rows):
    """Each bundled clip equals its AMC original resampled to 30 fps (4-decimal BVH in
    centimetres: measured max error 0.004 mm over all clips; tolerance 0.1 mm)."""
    with open(cmu_dir / "labels.csv", newline="") as fh:
        shared = {r["trial"]: r for r in csv.DictReader(fh)}
    for r in rows:
        if _is_move(r):
            continue  # not CMU's (tests/retrieval/test_act_moves.py)
        src = shared[r["trial"]]
        original = drop_leading_outlier(resample(load_motion(cmu_dir / src["file"], cmu_dir / src["skeleton"]), 30.0))
        bundled = load_motion(library / r["file"])
        p = positions(original.slice(0, bundled.n_frames))
        q = positions(bundled)
        assert np.abs(p - q).max() < 1e-4, r["trial"]
