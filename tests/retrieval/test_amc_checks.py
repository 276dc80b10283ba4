"""AMC frame numbers are range-checked: the first frame is 1 (or 0), each next one is one
more; anything else is a MotionFormatError naming the file and the line, on both readers
(the fast uniform-layout path and the line-by-line one)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from retrieval.errors import MotionFormatError
from retrieval.motion.formats import load_motion
from tests.retrieval.test_motion_io import TINY_ASF

FRAME = "root 0 0 0 0 0 0\na 10\nb 0 0 0\n"


def _load(tmp_path: Path, numbers: list[str], shuffle: bool = False):
    """An AMC of len(numbers) frames with these frame-number lines; ``shuffle`` lists the
    bones of each frame in another order (legal, and it takes the line-by-line reader)."""
    frame = "b 0 0 0\na 10\nroot 0 0 0 0 0 0\n" if shuffle else FRAME
    text = ":FULLY-SPECIFIED\n:DEGREES\n" + "".join(f"{n}\n{frame}" for n in numbers)
    (tmp_path / "tiny.asf").write_text(TINY_ASF)
    (tmp_path / "take.amc").write_text(text)
    return load_motion(tmp_path / "take.amc", tmp_path / "tiny.asf")


def _line_of(k: int) -> int:
    """The file line of the k-th frame-number line (0-based): 2 header lines, 4 per frame."""
    return 3 + 4 * k


@pytest.mark.parametrize("shuffle", [False, True])
@pytest.mark.parametrize("first", ["1", "0"])
def test_frames_counting_from_one_or_zero_load(tmp_path, first, shuffle):
    numbers = [str(int(first) + k) for k in range(4)]
    m = _load(tmp_path, numbers, shuffle)
    assert m.n_frames == 4
    reference = _load(tmp_path, [str(k + 1) for k in range(4)])  # the usual file
    np.testing.assert_array_equal(m.rotations, reference.rotations)


@pytest.mark.parametrize("shuffle", [False, True])
@pytest.mark.parametrize(("numbers", "bad", "problem"), [
    (["-3", "-2"], 0, "frame number -3 out of range: the first frame is numbered 1 or 0"),
    (["1", "2", "-3"], 2, "frame number -3 out of range: frame 3 comes next"),
    (["5", "6"], 0, "frame number 5 out of range: the first frame is numbered 1 or 0"),
    (["1", "2", "4"], 2, "frame number 4 out of range: frame 3 comes next"),  # a gap
    (["1", "2", "2"], 2, "frame number 2 out of range: frame 3 comes next"),  # a repeat
    (["1", "+2"], 1, None),  # "+2" is the right number written oddly: accepted
    (["1", "9" * 40], 1, f"frame number {'9' * 24} out of range: frame 2 comes next"),
])
def test_bad_frame_numbers_name_the_file_and_line(tmp_path, numbers, bad, problem, shuffle):
    if problem is None:
        assert _load(tmp_path, numbers, shuffle).n_frames == len(numbers)
        return
    with pytest.raises(MotionFormatError) as err:
        _load(tmp_path, numbers, shuffle)
    assert str(err.value) == f"{tmp_path / 'take.amc'}, line {_line_of(bad)}: {problem}"
    assert err.value.line == _line_of(bad)
    assert "bone" not in str(err.value)  # a negative number is no longer read as a bone name
