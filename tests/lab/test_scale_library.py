"""lab.bench.scale_library: the derived library reaches both size targets, holds valid
codes of its source classes in proportion, is reproducible from its seed, and is cached
as an .npz under $STORYBEAM_CACHE/scale (a damaged entry is rebuilt)."""
from __future__ import annotations

import numpy as np
import pytest

from lab.bench import scale_library
from lab.bench.scale_library import ScaleLibrary, build_scale_library, default_cache_dir
from retrieval.codes import Quantizer
from retrieval.errors import StoryBeamError
from retrieval.library import Clip

N_FEATURES = 17
FPS = 30.0


def _sources(per_class: dict[str, int], frames: int = 40, fps: float = FPS) -> list[Clip]:
    rng = np.random.default_rng(0)
    clips = []
    for k, (label, count) in enumerate(per_class.items()):
        for i in range(count):
            features = rng.normal(loc=3.0 * k, size=(frames, N_FEATURES))
            clips.append(Clip(trial=f"{label}_{i:02d}", label=label, features=features, pose=None, fps=fps))
    return clips


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("STORYBEAM_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache" / "scale"


@pytest.fixture(scope="module")
def sources() -> list[Clip]:
    return _sources({"walk": 3, "kick": 1})


@pytest.fixture(scope="module")
def quantizer(sources) -> Quantizer:
    return Quantizer.fit(np.concatenate([c.features for c in sources]), n=3)


def _build(sources, quantizer, **kw) -> ScaleLibrary:
    kw.setdefault("cache", False)
    return build_scale_library(sources, quantizer, progress=False, **kw)


def test_default_cache_dir_follows_storybeam_cache(cache_dir):
    assert default_cache_dir() == cache_dir


@pytest.mark.parametrize("min_clips, min_hours", [(30, 0.001), (3, 0.02)])
def test_the_library_reaches_both_targets_and_stops_there(sources, quantizer, cache_dir, min_clips, min_hours):
    lib = _build(sources, quantizer, min_clips=min_clips, min_hours=min_hours)
    assert lib.clips >= min_clips and lib.hours >= min_hours
    assert lib.fps == FPS and lib.frames == sum(len(c) for c in lib.codes)
    assert lib.hours == pytest.approx(lib.frames / FPS / 3600)
    # one clip fewer would have missed a target: no clips beyond what was asked for
    assert lib.clips - 1 < min_clips or (lib.frames - len(lib.codes[-1])) / FPS / 3600 < min_hours
    assert not cache_dir.exists(), "cache=False must not write the cache"


def test_codes_are_valid_and_classes_follow_the_sources(sources, quantizer, cache_dir):
    lib = _build(sources, quantizer, min_clips=400, min_hours=0.0)
    assert len(lib.labels) == lib.clips
    assert set(lib.labels) == {"walk", "kick"}
    assert 0.65 < lib.labels.count("walk") / lib.clips < 0.85  # 3 walk sources : 1 kick
    for codes in lib.codes:
        assert codes.dtype == np.int32 and codes.ndim == 1 and len(codes) >= 2
        assert codes.min() >= 0 and codes.max() < 4 ** quantizer.n


def test_the_library_is_reproducible_from_its_seed(sources, quantizer, cache_dir):
    a = _build(sources, quantizer, min_clips=20, min_hours=0.0, seed=5)
    b = _build(sources, quantizer, min_clips=20, min_hours=0.0, seed=5)
    c = _build(sources, quantizer, min_clips=20, min_hours=0.0, seed=6)
    assert a.labels == b.labels and all(np.array_equal(x, y) for x, y in zip(a.codes, b.codes))
    assert a.labels != c.labels or any(not np.array_equal(x, y) for x, y in zip(a.codes, c.codes))


def test_the_cache_is_written_reused_and_rebuilt_when_damaged(sources, quantizer, cache_dir, monkeypatch):
    first = _build(sources, quantizer, min_clips=25, min_hours=0.0, cache=True)
    entries = list(cache_dir.glob("*.npz"))
    assert len(entries) == 1

    def no_build(*_args, **_kw):
        raise AssertionError("a cached library must not be rebuilt")

    with monkeypatch.context() as m:
        m.setattr(scale_library, "augmented_take", no_build)
        cached = _build(sources, quantizer, min_clips=25, min_hours=0.0, cache=True)
    assert cached.labels == first.labels and all(np.array_equal(x, y) for x, y in zip(first.codes, cached.codes))
    assert all(c.dtype == np.int32 for c in cached.codes)

    entries[0].write_bytes(b"not an npz")
    rebuilt = _build(sources, quantizer, min_clips=25, min_hours=0.0, cache=True)
    assert rebuilt.labels == first.labels and all(np.array_equal(x, y) for x, y in zip(first.codes, rebuilt.codes))
    with np.load(entries[0]) as z:  # the damaged entry was replaced by a valid one
        assert len(z["labels"]) == rebuilt.clips

    other_seed = _build(sources, quantizer, min_clips=25, min_hours=0.0, cache=True, seed=1)
    assert len(list(cache_dir.glob("*.npz"))) == 2, "the seed is part of the cache key"
    assert other_seed.clips >= 25


def test_no_sources_or_mixed_frame_rates_are_errors(sources, quantizer, cache_dir):
    with pytest.raises(StoryBeamError, match="no source clips"):
        _build([], quantizer)
    mixed = sources + _sources({"run": 1}, fps=60.0)
    with pytest.raises(StoryBeamError, match="frame rates"):
        _build(mixed, quantizer)
