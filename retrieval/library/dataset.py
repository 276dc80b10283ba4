"""Labelled motion folders -> :class:`~retrieval.library.clip.Clip` lists.

A folder holds ``labels.csv`` with at least the columns ``trial``, ``label``, ``file`` and
``skeleton`` (the ASF for AMC files; empty for BVH); an optional ``subject`` column (the
performer, or the style) is kept for the leave-one-subject-out protocol; other columns
are ignored and paths are relative to the folder. The ``label`` column may be empty on
a row: an **unlabelled clip** (a teacher's import), loaded with label ``""`` — search,
the catalogue and :mod:`~retrieval.library.grouping` (which names a group by its
members' labels, else by a picture) work on it; ``storybeam eval`` refuses it, naming
the row, since accuracy needs a label. Every unusable row raises :class:`DatasetError` naming the CSV,
the row and the problem, before any slow loading starts.

Loading runs forward kinematics once per clip and keeps the 17-D features, and the
Forbes–Fiume pose vectors only when asked for (``pose=True``: the baseline is their one
reader). Results are cached as .npz files keyed by the motion file's path, size and
mtime, the skeleton's, the frame rate and the feature set, under
``$STORYBEAM_CACHE`` (default ``~/.cache/storybeam/clips``) — the shared data folders are
read-only, so the cache never lives beside the data.
"""
from __future__ import annotations

import csv
import hashlib
import os
import tempfile
from dataclasses import MISSING, dataclass, fields
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from retrieval.errors import DatasetError, StoryBeamError
from retrieval.features import HEADING_SMOOTH_SECONDS, FeatureSet, get_feature_set, leg_length, pose_frames
from retrieval.library.clip import Clip
from retrieval.motion import (
    CANONICAL_POSE_VERSION,
    Motion,
    canonical_joint_map,
    load_motion,
    positions,
    resample,
    rest_positions,
)

REQUIRED_COLUMNS = ("trial", "label", "file", "skeleton")
CACHE_VERSION = "1"


@dataclass(frozen=True)
class LabelRow:
    trial: str
    label: str
    file: Path
    skeleton: Path | None
    line: int
    subject: str = ""


def default_cache_dir() -> Path:
    return Path(os.environ.get("STORYBEAM_CACHE", Path.home() / ".cache" / "storybeam")) / "clips"


def read_labels(folder: str | Path) -> list[LabelRow]:
    """Parse and check ``folder/labels.csv`` (files must exist; a row's label may be
    empty: an unlabelled clip, label ``""``)."""
    folder = Path(folder)
    csv_path = folder / "labels.csv"
    if not folder.is_dir():
        raise DatasetError(f"{folder}: not a folder")
    if not csv_path.is_file():
        raise DatasetError(f"{csv_path}: no labels.csv in the dataset folder")
    with open(csv_path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in REQUIRED_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise DatasetError(f"{csv_path}: missing column(s) {', '.join(missing)} (found: {', '.join(reader.fieldnames or [])})")
        rows: list[LabelRow] = []
        seen: set[str] = set()
        for line, rec in enumerate(reader, start=2):
            trial, label, file = ((rec.get(k) or "").strip() for k in ("trial", "label", "file"))
            skel = (rec.get("skeleton") or "").strip()
            if not trial or not file:  # an empty label is allowed: an unlabelled clip
                raise DatasetError(f"{csv_path}, line {line}: empty trial or file")
            if trial in seen:
                raise DatasetError(f"{csv_path}, line {line}: duplicate trial {trial!r}")
            seen.add(trial)
            path = folder / file
            if not path.is_file():
                raise DatasetError(f"{csv_path}, line {line}: motion file {path} not found")
            skel_path = folder / skel if skel else None
            if skel_path is not None and not skel_path.is_file():
                raise DatasetError(f"{csv_path}, line {line}: skeleton file {skel_path} not found")
            if skel_path is None and path.suffix.lower() == ".amc":
                raise DatasetError(f"{csv_path}, line {line}: AMC file {file} needs a skeleton (ASF) column")
            rows.append(LabelRow(trial, label, path, skel_path, line, (rec.get("subject") or "").strip()))
    if not rows:
        raise DatasetError(f"{csv_path}: no rows")
    return rows


def clip_from_motion(motion: Motion, trial: str, label: str = "", fps: float | None = None,
                     feature_set: str = "mr17", source: str = "", pose: bool = False) -> Clip:
    """Features (and, with ``pose``, pose vectors) of a motion, resampled to ``fps`` when given."""
    if fps is not None and abs(motion.fps - fps) > 1e-9:
        motion = resample(motion, fps)
    jm = canonical_joint_map(motion.skeleton)
    size = leg_length(motion.skeleton, jm)
    pos = positions(motion)
    feats = get_feature_set(feature_set).from_positions(pos, jm, size, float(motion.fps),
                                                        rest_positions(motion.skeleton))
    return Clip(trial, label, feats, pose_frames(pos, jm, size) if pose else None, float(motion.fps), source)


def _plain(fs: FeatureSet) -> bool:
    """Whether ``fs`` is a plain :class:`FeatureSet` with every setting at its default
    (its features then depend on its name and specs alone, as MR17's do)."""
    return type(fs) is FeatureSet and all(
        getattr(fs, f.name) == f.default for f in fields(FeatureSet)
        if f.default is not MISSING and f.name != "description")


def _cache_key(row: LabelRow, fps: float | None, feature_set: str) -> str:
    parts = [CACHE_VERSION, feature_set, repr(fps)]
    fs = get_feature_set(feature_set)
    if fs.needs_fps:  # a set with a rate: every field and the rate's smoothing are part of what is cached
        parts.append(repr(fs) + repr(HEADING_SMOOTH_SECONDS))
    elif not _plain(fs):  # a subclass (the frontal sets) or a setting off its default: every field
        parts.append(repr(fs))
    if fs.body == "canonical":
        parts.append(f"canonical-pose-{CANONICAL_POSE_VERSION}")
    for p in (row.file, row.skeleton):
        if p is not None:
            st = p.stat()
            parts += [str(p.resolve()), str(st.st_size), str(st.st_mtime_ns)]
    return hashlib.sha1("|".join(parts).encode()).hexdigest()


def load_row(row: LabelRow, fps: float | None = None, feature_set: str = "mr17",
             cache_dir: Path | None = None, loader: Callable | None = None, pose: bool = False) -> Clip:
    """One row -> Clip, through the cache when ``cache_dir`` is given (an entry saved
    without pose vectors is rebuilt when ``pose`` asks for them)."""
    cache_file = None
    if cache_dir is not None:
        cache_file = cache_dir / f"{_cache_key(row, fps, feature_set)}.npz"
        if cache_file.is_file():
            try:
                with np.load(cache_file) as z:
                    cached_pose = z["pose"] if z["pose"].ndim == 2 else None
                    if cached_pose is not None or not pose:
                        return Clip(row.trial, row.label, z["features"], cached_pose, float(z["fps"]), str(row.file),
                                    row.subject)
            except Exception:  # a damaged cache entry is rebuilt, never fatal
                pass
    load = loader or load_motion
    try:
        motion = load(row.file, row.skeleton) if row.skeleton else load(row.file)
        clip = clip_from_motion(motion, row.trial, row.label, fps, feature_set, str(row.file), pose=pose)
        clip.subject = row.subject
    except StoryBeamError as exc:
        raise DatasetError(f"trial {row.trial} ({row.file}): {exc}") from exc
    if clip.n_frames < 2:
        raise DatasetError(f"trial {row.trial} ({row.file}): fewer than 2 frames")
    if cache_file is not None:
        _write_cache(cache_file, clip)
    return clip


def _write_cache(cache_file: Path, clip: Clip) -> None:
    """Save ``clip``'s features to ``cache_file`` through a temporary file of its own in
    the same folder, renamed into place: two processes or threads filling the same entry
    at once (the app's background load beside a command, parallel test workers) each
    write their own file and the last rename wins whole, never a mix of the two. Caching
    is an optimisation only: any OS error leaves no entry and no temporary file. Not
    :func:`retrieval.durable.durable_file`: an entry lost to a power cut is rebuilt, so
    its two fsyncs per entry (and its scan of the folder for stale temporaries, which
    holds every cached clip) would only slow the first load of a library."""
    tmp = None
    try:
        cache_file.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{cache_file.stem}.", suffix=".tmp", dir=cache_file.parent)
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, features=clip.features, pose=clip.pose if clip.pose is not None else np.zeros(0),
                     fps=clip.fps)
        os.replace(tmp, cache_file)
        tmp = None
    except OSError:
        pass
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def load_dataset(folder: str | Path, fps: float | None = None, feature_set: str = "mr17",
                 cache: bool = True, progress: Callable[[int, int], None] | None = None,
                 loader: Callable | None = None, rows: Sequence[LabelRow] | None = None,
                 pose: bool = False) -> list[Clip]:
    """All clips of a labelled folder, in labels.csv order; ``progress(done, total)`` is
    called after each clip (the command line shows a bar with it)."""
    if fps is not None and not fps > 0:
        raise DatasetError(f"fps must be positive, got {fps}")
    rows = list(rows) if rows is not None else read_labels(folder)
    cache_dir = default_cache_dir() if cache else None
    clips = []
    for i, r in enumerate(rows):
        clips.append(load_row(r, fps, feature_set, cache_dir, loader, pose))
        if progress is not None:
            progress(i + 1, len(rows))
    return clips
