"""Subsequence search finds a clip planted inside a longer take (numba and numpy agree)."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.codes import DiffTable
from retrieval.errors import StoryBeamError
from retrieval.codes import Quantizer
from retrieval.dtw import find_subsequence


@pytest.fixture(scope="module")
def setup():
    rng = np.random.default_rng(0)
    frames = np.cumsum(rng.normal(size=(6000, 17)), axis=0) * 0.2  # slowly varying "features"
    q = Quantizer.fit(frames, 6)
    return q, DiffTable.from_ratios(q.ratios), frames


def _same_code_run(take: np.ndarray, i: int, step: int) -> int:
    """How many frames beyond i (in direction step) repeat take[i]'s code: within such a
    run the boundary of a planted clip is invisible in code space."""
    n = 0
    j = i + step
    while 0 <= j < len(take) and take[j] == take[i]:
        n += 1
        j += step
    return n


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("start,length", [(0, 60), (700, 90), (1500, 120)])
def test_planted_clip_is_found_with_its_frames(setup, backend, start, length):
    q, table, frames = setup
    take = q.encode(frames[2000:3620])  # a long take (1620 frames)
    clip = take[start:start + length].copy()
    end = start + length - 1
    m = find_subsequence(clip, take, table, backend=backend)
    assert start - _same_code_run(take, start, -1) <= m.start <= start
    assert end <= m.end <= end + _same_code_run(take, end, +1)
    assert m.raw == 0.0


def test_planted_clip_found_when_time_scaled_and_surrounded_by_other_motion(setup):
    q, table, frames = setup
    take = q.encode(frames[:2400])
    src = frames[1000:1100]
    slow = src[np.repeat(np.arange(100), 2)[:180]]  # played ~1.8x slower
    planted = np.concatenate([frames[3000:3400], slow, frames[4000:4300]])
    take = q.encode(planted)
    m = find_subsequence(q.encode(src), take, table)
    assert 400 - 5 - _same_code_run(take, 400, -1) <= m.start <= 400 + 5
    assert 579 - 10 <= m.end <= 579 + 10 + _same_code_run(take, 579, +1)


def test_numba_and_numpy_paths_agree(setup):
    q, table, frames = setup
    rng = np.random.default_rng(3)
    for _ in range(10):
        s = int(rng.integers(0, 5000))
        query = q.encode(frames[s:s + int(rng.integers(5, 60))])
        take = q.encode(frames[int(rng.integers(0, 3000)):][:int(rng.integers(50, 900))])
        a = find_subsequence(query, take, table, backend="numba")
        b = find_subsequence(query, take, table, backend="numpy")
        assert a == b


def test_bad_codes_raise(setup):
    _, table, _ = setup
    with pytest.raises(StoryBeamError):
        find_subsequence(np.array([], np.int32), np.array([1, 2], np.int32), table)
    with pytest.raises(StoryBeamError):
        find_subsequence(np.array([1], np.int32), np.array([99999], np.int32), table)
