"""A saved, searchable motion library: the proposed quantised method over labelled clips.

:class:`MotionIndex` keeps, per clip, its trial name, label and 2-bit code sequence, plus
the fitted PCA/quantiser; the 4ⁿ×4ⁿ table is rebuilt from the contribution ratios on load
(it is a pure function of them), so a saved index is small. On disk an index is a folder
with ``index.json`` (format version, settings, trials, labels) and ``index.npz``
(quantiser arrays, all codes concatenated, per-clip offsets). Anything unreadable or
inconsistent raises :class:`IndexFormatError` naming the file.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .dataset import clip_from_motion, load_dataset
from .errors import IndexFormatError, StoryBeamError
from .matchers import Clip, QuantizedMatcher
from .motion import Motion
from .quantize import Quantizer

FORMAT = "storybeam-motion-index"
VERSION = 1
JSON_NAME = "index.json"
NPZ_NAME = "index.npz"


@dataclass(frozen=True)
class Match:
    trial: str
    label: str
    distance: float

    def as_dict(self) -> dict:
        return {"trial": self.trial, "label": self.label, "distance": self.distance}


class MotionIndex:
    """Nearest-clip search by table-look-up DTW over 2-bit PCA codes."""

    def __init__(self, matcher: QuantizedMatcher, trials: list[str], labels: list[str],
                 fps: float, feature_set: str = "mr17"):
        if not (len(trials) == len(labels) == len(matcher.reference_codes)):
            raise StoryBeamError("index: trials, labels and codes differ in length")
        self.matcher = matcher
        self.trials = trials
        self.labels = labels
        self.fps = float(fps)
        self.feature_set = feature_set

    # ------------------------------------------------------------------ building
    @classmethod
    def from_clips(cls, clips: Sequence[Clip], dims: int = 6, band: int | None = None,
                   feature_set: str = "mr17") -> "MotionIndex":
        if not clips:
            raise StoryBeamError("cannot build an index from no clips")
        fps = {round(c.fps, 6) for c in clips}
        if len(fps) != 1:
            raise StoryBeamError(f"clips have different frame rates {sorted(fps)}: resample them to one fps")
        matcher = QuantizedMatcher(dims, band).fit(clips)
        return cls(matcher, [c.trial for c in clips], [c.label for c in clips], clips[0].fps, feature_set)

    @classmethod
    def build(cls, folder: str | Path, dims: int = 6, fps: float = 30.0, band: int | None = None,
              feature_set: str = "mr17", progress: bool = True) -> "MotionIndex":
        """Index every clip of a labelled folder (see :mod:`retrieval.dataset`) at ``fps``."""
        clips = load_dataset(folder, fps=fps, feature_set=feature_set, progress=progress)
        return cls.from_clips(clips, dims, band, feature_set)

    @classmethod
    def from_motions(cls, motions: Sequence[Motion], labels: Sequence[str] | None = None, dims: int = 6,
                     fps: float = 30.0, band: int | None = None) -> "MotionIndex":
        labels = list(labels) if labels is not None else [""] * len(motions)
        clips = [clip_from_motion(m, m.name or f"clip{i}", labels[i], fps) for i, m in enumerate(motions)]
        return cls.from_clips(clips, dims, band)

    # ------------------------------------------------------------------ searching
    def __len__(self) -> int:
        return len(self.trials)

    @property
    def dims(self) -> int:
        return self.matcher.dims

    def _features(self, query: Motion | Clip | np.ndarray) -> np.ndarray:
        if isinstance(query, Motion):
            return clip_from_motion(query, query.name or "query", "", self.fps, self.feature_set).features
        if isinstance(query, Clip):
            return query.features
        arr = np.asarray(query, dtype=np.float64)
        width = self.matcher.quantizer.pca.mean.shape[0]
        if arr.ndim != 2 or arr.shape[1] != width or arr.shape[0] == 0:
            raise StoryBeamError(f"query features must be (frames, {width}), got {arr.shape}")
        return arr

    def _ranked(self, dist: np.ndarray, k: int, exclude: int | None = None) -> list[Match]:
        order = np.argsort(dist, kind="stable")
        out = [Match(self.trials[i], self.labels[i], float(dist[i])) for i in order if i != exclude]
        return out[: max(0, k)]

    def query(self, query: Motion | Clip | np.ndarray, k: int = 5) -> list[Match]:
        """The ``k`` nearest clips to a motion (resampled to the index's fps) or to a
        (frames, 17) feature array, nearest first."""
        return self._ranked(self.matcher.distances(self._features(query)), k)

    def similar_to(self, trial: str, k: int = 5) -> list[Match]:
        """The ``k`` clips nearest to an indexed clip (itself excluded)."""
        try:
            i = self.trials.index(trial)
        except ValueError:
            raise StoryBeamError(f"no clip {trial!r} in the index") from None
        m = self.matcher
        from .dtw import dtw_codes

        codes = m.reference_codes[i]
        dist = np.array([dtw_codes(codes, r, m.table, m.band, m.backend) for r in m.reference_codes])
        return self._ranked(dist, k, exclude=i)

    # ------------------------------------------------------------------ disk
    def save(self, folder: str | Path) -> Path:
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        codes = self.matcher.reference_codes
        offsets = np.cumsum([0] + [len(c) for c in codes]).astype(np.int64)
        arrays = self.matcher.quantizer.to_arrays()
        np.savez_compressed(folder / NPZ_NAME, codes=np.concatenate(codes).astype(np.int32), offsets=offsets, **arrays)
        meta = {
            "format": FORMAT, "version": VERSION, "fps": self.fps, "dims": self.dims,
            "band": self.matcher.band, "feature_set": self.feature_set,
            "trials": self.trials, "labels": self.labels,
        }
        (folder / JSON_NAME).write_text(json.dumps(meta, indent=1))
        return folder

    @staticmethod
    def is_index(path: str | Path) -> bool:
        return (Path(path) / JSON_NAME).is_file()

    @classmethod
    def load(cls, folder: str | Path) -> "MotionIndex":
        folder = Path(folder)
        jpath, npath = folder / JSON_NAME, folder / NPZ_NAME
        try:
            meta = json.loads(jpath.read_text())
        except FileNotFoundError:
            raise IndexFormatError(f"{jpath}: not found") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise IndexFormatError(f"{jpath}: unreadable ({exc})") from None
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise IndexFormatError(f"{jpath}: not a StoryBeam motion index")
        if meta.get("version") != VERSION:
            raise IndexFormatError(f"{jpath}: index version {meta.get('version')!r}, expected {VERSION}")
        try:
            trials, labels = list(meta["trials"]), list(meta["labels"])
            fps, band, fset = float(meta["fps"]), meta.get("band"), str(meta.get("feature_set", "mr17"))
            with np.load(npath) as z:
                arrays = {k: z[k] for k in z.files}
            quantizer = Quantizer.from_arrays(arrays)
            codes_all, offsets = arrays["codes"], arrays["offsets"]
        except FileNotFoundError:
            raise IndexFormatError(f"{npath}: not found") from None
        except (KeyError, ValueError, TypeError, OSError) as exc:
            raise IndexFormatError(f"{folder}: damaged index ({type(exc).__name__}: {exc})") from None
        n_codes = 4 ** quantizer.n
        if (len(offsets) != len(trials) + 1 or len(labels) != len(trials) or offsets[0] != 0
                or offsets[-1] != len(codes_all) or np.any(np.diff(offsets) <= 0)
                or (len(codes_all) and (codes_all.min() < 0 or codes_all.max() >= n_codes))):
            raise IndexFormatError(f"{npath}: codes, offsets and trials are inconsistent")
        codes = [codes_all[offsets[i]:offsets[i + 1]] for i in range(len(trials))]
        matcher = QuantizedMatcher.from_quantizer(quantizer, codes, band)
        return cls(matcher, trials, labels, fps, fset)
