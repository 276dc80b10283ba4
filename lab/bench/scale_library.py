"""A CMU-sized library (≥ 2 600 clips, ≥ 9 hours) of *derived* clips, stored as codes.

Built from labelled clips by :mod:`lab.bench.augment` (mirroring, time scaling 0.8–1.25,
same-class splicing) and quantised with a quantiser fitted on the source clips' features;
only the int16 codes are kept (about 2 bytes per frame), so the 9-hour library is a few MB
and builds in seconds. It is cached as an .npz under ``$STORYBEAM_CACHE/scale`` (default
``~/.cache/storybeam/scale``), keyed by the source clips, the quantiser and the settings —
never committed.

This is a *speed* test bed: its clips are honest transformations of 205 real ones, not new
performances, so accuracy measured on it would be optimistic and is not reported.
"""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np
from tqdm import tqdm

from lab.bench.augment import augmented_take
from retrieval.errors import StoryBeamError
from retrieval.library import Clip
from retrieval.codes import Quantizer

CACHE_VERSION = "1"


@dataclass
class ScaleLibrary:
    codes: list[np.ndarray]
    labels: list[str]
    fps: float

    @property
    def clips(self) -> int:
        return len(self.codes)

    @property
    def frames(self) -> int:
        return int(sum(len(c) for c in self.codes))

    @property
    def hours(self) -> float:
        return self.frames / self.fps / 3600.0


def default_cache_dir() -> Path:
    return Path(os.environ.get("STORYBEAM_CACHE", Path.home() / ".cache" / "storybeam")) / "scale"


def _key(sources: Sequence[Clip], quantizer: Quantizer, min_clips: int, min_hours: float, seed: int) -> str:
    h = hashlib.sha1()
    h.update(f"{CACHE_VERSION}|{min_clips}|{min_hours}|{seed}|{quantizer.n}".encode())
    for c in sources:
        h.update(c.trial.encode())
        h.update(np.ascontiguousarray(c.features[:: max(1, len(c.features) // 8)]).tobytes())
    h.update(np.ascontiguousarray(quantizer.pca.components).tobytes())
    h.update(np.ascontiguousarray(quantizer.mu).tobytes())
    return h.hexdigest()[:20]


def derived_takes(sources: Sequence[Clip], min_clips: int, min_hours: float, seed: int = 0,
                  feature_set: str = "mr17") -> Iterator[tuple[str, np.ndarray]]:
    """The derived takes (label, (frames, d) features) of :func:`build_scale_library`, one
    at a time, until both ``min_clips`` and ``min_hours`` are reached; classes drawn in
    proportion to the source clips. Deterministic for a seed: the first takes of a bigger
    library are those of a smaller one. ``feature_set`` names the sources' features (for
    mirroring)."""
    rng = np.random.default_rng(seed)
    by_class: dict[str, list[np.ndarray]] = {}
    for c in sources:
        by_class.setdefault(c.label, []).append(c.features)
    classes = sorted(by_class)
    weights = np.array([len(by_class[k]) for k in classes], dtype=np.float64)
    weights /= weights.sum()
    target_frames = min_hours * 3600 * float(sources[0].fps)
    clips = frames = 0
    while clips < min_clips or frames < target_frames:
        label = classes[int(rng.choice(len(classes), p=weights))]
        feats = augmented_take(by_class, label, rng, feature_set=feature_set)
        clips += 1
        frames += len(feats)
        yield label, feats


def build_scale_library(sources: Sequence[Clip], quantizer: Quantizer, min_clips: int = 2600,
                        min_hours: float = 9.0, seed: int = 0, cache: bool = True,
                        progress: bool = True) -> ScaleLibrary:
    """Derived takes (see :mod:`lab.bench.augment`) until both ``min_clips`` and
    ``min_hours`` are reached; classes drawn in proportion to the source clips."""
    if not sources:
        raise StoryBeamError("scale library: no source clips")
    fps = {round(c.fps, 6) for c in sources}
    if len(fps) != 1:
        raise StoryBeamError(f"scale library: source clips have different frame rates {sorted(fps)}")
    fps_value = float(sources[0].fps)
    path = default_cache_dir() / f"{_key(sources, quantizer, min_clips, min_hours, seed)}.npz"
    if cache and path.is_file():
        try:
            with np.load(path) as z:
                codes_all, off, labels = z["codes"], z["offsets"], [str(s) for s in z["labels"]]
            return ScaleLibrary([codes_all[off[i]:off[i + 1]].astype(np.int32) for i in range(len(labels))],
                                labels, fps_value)
        except Exception:  # a damaged cache entry is rebuilt
            pass
    codes: list[np.ndarray] = []
    labels: list[str] = []
    bar = tqdm(total=min_clips, desc="building scale library", unit="clip", disable=not progress)
    for label, feats in derived_takes(sources, min_clips, min_hours, seed):
        codes.append(quantizer.encode(feats).astype(np.int16 if quantizer.n <= 7 else np.int32))
        labels.append(label)
        bar.update(1)
    bar.close()
    if cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            off = np.concatenate(([0], np.cumsum([len(c) for c in codes]))).astype(np.int64)
            tmp = path.with_suffix(".tmp.npz")
            np.savez(tmp, codes=np.concatenate(codes), offsets=off, labels=np.array(labels))
            os.replace(tmp, path)
        except OSError:
            pass  # caching is an optimisation only
    return ScaleLibrary([c.astype(np.int32) for c in codes], labels, fps_value)
