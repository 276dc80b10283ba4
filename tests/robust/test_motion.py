"""Robustness of the motion-file loaders: fuzzing (short CI version of `storybeam stress
--only fuzz`), property-based tests, and regression tests for each defect the fuzzing
found. The contract: any input loads into a finite motion or raises MotionFormatError."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lab.stress import fuzz_motion as fuzz

from retrieval.motion.formats import textfile
from retrieval.motion.formats import load_amc, load_asf
from retrieval.motion.formats import load_bvh
from retrieval.errors import MotionFormatError

REPO = Path(__file__).resolve().parents[2]
BUNDLED = REPO / "assets" / "motions" / "bvh"
HYPO = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def seeds() -> list[fuzz.Seed]:
    from tests.conftest import CMU

    found = fuzz.collect_seeds(CMU if (CMU / "labels.csv").is_file() else None, BUNDLED)
    assert any(s.kind == "bvh" for s in found)
    return found


@pytest.fixture(scope="module")
def bvh_seed(seeds) -> bytes:
    return next(s.data for s in seeds if s.kind == "bvh")


def _one_joint_bvh(frames: int, frame_time: str = "0.033333", rows: int | None = None) -> str:
    head = ("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation"
            " Yrotation\nEnd Site\n{\nOFFSET 0 100 0\n}\n}\n")
    rows = frames if rows is None else rows
    return head + f"MOTION\nFrames: {frames}\nFrame Time: {frame_time}\n" + "0 90 0 1 2 3\n" * rows


# ----------------------------------------------------------------------------- the fuzz harness


@pytest.mark.slow  # the fuzz campaign
def test_short_fuzz_campaign_has_no_crash_or_hang(seeds, tmp_path):
    """2 000 mutated inputs from real seeds: every one loads or raises MotionFormatError."""
    stats = fuzz.fuzz_in_process(seeds, 2000, rng_seed=20261121, workdir=tmp_path, crash_dir=tmp_path / "crashes")
    assert stats.inputs == 2000
    assert stats.crashes == 0 and stats.hangs == 0, stats.crash_examples[:3]
    # The harness must reach both outcomes, or it is testing nothing.
    assert stats.loaded > 20 and stats.rejected > 1000
    assert set(stats.by_kind) >= {"bvh"}


def test_classifier_reports_crashes_and_hangs(monkeypatch, tmp_path):
    """The harness can fail: a loader raising ValueError is a crash, a stuck one a hang."""
    def raises(*a, **k):
        raise ValueError("boom")

    monkeypatch.setattr(fuzz, "load_bytes", raises)
    assert fuzz.check_input("bvh", b"x", b"", tmp_path).status == "crash"

    def stuck(*a, **k):
        while True:
            pass

    monkeypatch.setattr(fuzz, "load_bytes", stuck)
    outcome = fuzz.check_input("bvh", b"x", b"", tmp_path, time_limit_s=0.2)
    assert outcome.status == "hang"


def test_loaded_motion_with_non_finite_numbers_is_a_failure():
    class Fake:
        fps = float("inf")
    with pytest.raises(AssertionError):
        fuzz.check_motion(Fake())


@pytest.mark.slow  # the fuzz campaign in a child process
def test_worker_campaign_runs_in_a_subprocess(seeds, tmp_path):
    seen = []
    stats = fuzz.run_campaign(seeds, inputs=150, batch=50, rng_seed=3, crash_dir=tmp_path, progress=seen.append)
    assert stats.inputs == 150 and sum(seen) == 150
    assert stats.crashes == 0 and stats.hangs == 0
    assert stats.peak_rss_mb > 10  # measured in the worker


# ----------------------------------------------------------------------------- property-based


@HYPO
@given(data=st.binary(max_size=400))
def test_arbitrary_bytes_load_or_raise_format_error(tmp_path, data):
    for kind in ("bvh", "asf"):
        path = tmp_path / f"x.{kind}"
        path.write_bytes(data)
        try:
            (load_bvh if kind == "bvh" else load_asf)(path)
        except MotionFormatError:
            pass


@HYPO
@given(cut=st.floats(0, 1), flips=st.lists(st.tuples(st.floats(0, 1), st.integers(0, 7)), max_size=6))
def test_truncated_and_bit_flipped_seed(tmp_path, bvh_seed, cut, flips):
    buf = bytearray(bvh_seed[: int(len(bvh_seed) * cut)])
    for where, bit in flips:
        if buf:
            buf[min(len(buf) - 1, int(where * len(buf)))] ^= 1 << bit
    outcome = fuzz.check_input("bvh", bytes(buf), b"", tmp_path)
    assert outcome.status in ("loaded", "rejected"), outcome.detail


_NASTY = st.sampled_from(["nan", "inf", "-inf", "1e309", "1e308", "-1e308", "5e-324", "1e-320", "", "0x1",
                          "1e", "\u0661", "\u00b2", "99999999999999999999999999"])


@HYPO
@given(value=_NASTY, which=st.integers(0, 10_000))
def test_nasty_number_anywhere(tmp_path, bvh_seed, value, which):
    spans = [m.span() for m in re.finditer(rb"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?", bvh_seed)]
    a, b = spans[which % len(spans)]
    data = bvh_seed[:a] + value.encode() + bvh_seed[b:]
    outcome = fuzz.check_input("bvh", data, b"", tmp_path)
    assert outcome.status in ("loaded", "rejected"), outcome.detail


@st.composite
def bvh_documents(draw):
    """A valid random BVH: a random tree, channel layouts and finite values."""
    n = draw(st.integers(1, 12))
    parents = [-1] + [draw(st.integers(0, i - 1)) for i in range(1, n)]
    layouts = [draw(st.permutations(["Xrotation", "Yrotation", "Zrotation"])) for _ in range(n)]
    pos = ["Xposition", "Yposition", "Zposition"]
    frames = draw(st.integers(1, 6))
    lines = ["HIERARCHY"]

    def emit(i, depth):
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if i == 0 else 'JOINT'} j{i}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET 0 {draw(st.floats(1, 50)):.3f} 0")
        chans = (pos if i == 0 else []) + list(layouts[i])
        lines.append(f"{pad}  CHANNELS {len(chans)} " + " ".join(chans))
        kids = [k for k in range(n) if parents[k] == i]
        for k in kids:
            emit(k, depth + 1)
        if not kids:
            lines.extend([pad + "  End Site", pad + "  {", pad + "    OFFSET 0 5 0", pad + "  }"])
        lines.append(pad + "}")

    emit(0, 0)
    n_ch = 3 + 3 * n
    values = draw(st.lists(st.lists(st.floats(-720, 720, allow_nan=False), min_size=n_ch, max_size=n_ch),
                           min_size=frames, max_size=frames))
    lines += ["MOTION", f"Frames: {frames}", "Frame Time: 0.0333333"]
    lines += [" ".join(f"{v:.4f}" for v in row) for row in values]
    return "\n".join(lines) + "\n", n, frames


@settings(HYPO, max_examples=25)
@given(doc=bvh_documents(), nasty=_NASTY, where=st.integers(0, 10_000))
def test_generated_bvh_loads_and_a_poisoned_value_is_refused(tmp_path, doc, nasty, where):
    text, n_joints, frames = doc
    path = tmp_path / "gen.bvh"
    path.write_text(text)
    motion = load_bvh(path, units="cm", up_axis="y", drop_tpose=False)
    assert motion.n_frames == frames
    assert sum(1 for j in motion.skeleton.joints if not j.name.endswith("_end")) == n_joints
    assert np.isfinite(motion.rotations).all()
    # Poison one channel value of the MOTION section: never a crash, and a non-finite
    # or non-numeric value is refused.
    head, body = text.split("Frame Time: 0.0333333\n")
    tokens = body.split(" ")
    k = where % len(tokens)
    tokens[k] = nasty + ("\n" if tokens[k].endswith("\n") else "")
    path.write_text(head + "Frame Time: 0.0333333\n" + " ".join(tokens))
    outcome = fuzz.check_input("bvh", path.read_bytes(), b"", tmp_path)
    assert outcome.status in ("loaded", "rejected"), outcome.detail
    # (Unicode decimal digits such as "\u0661" are numbers to Python and numpy alike.)
    if nasty in ("nan", "inf", "-inf", "1e309", "", "0x1", "1e", "\u00b2"):
        assert outcome.status == "rejected"


# ----------------------------------------------------------------------------- regressions (defects found)


@pytest.mark.parametrize("frame_time", ["1e-320", "5e-324", "1e-300"])
def test_subnormal_frame_time_is_refused_not_overflow(tmp_path, frame_time):
    """Found by fuzzing: 1/5e-324 is inf and round(inf) raised OverflowError."""
    path = tmp_path / "ft.bvh"
    path.write_text(_one_joint_bvh(3, frame_time))
    with pytest.raises(MotionFormatError, match="frame time"):
        load_bvh(path)


def test_tiny_file_asking_for_huge_arrays_is_refused(tmp_path):
    """Found by the memory probe: 2 000 channel-less joints x 100 000 one-value frames
    (a 245 kB file) asked numpy for 13 GB and raised MemoryError."""
    parts = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 1 Xrotation"]
    for k in range(2000):
        parts += [f"JOINT j{k}", "{", "OFFSET 0 1 0", "}"]
    parts += ["}", "MOTION", "Frames: 100000", "Frame Time: 0.01"]
    path = tmp_path / "bomb.bvh"
    path.write_text("\n".join(parts) + "\n" + "0\n" * 100000)
    with pytest.raises(MotionFormatError, match="joint poses"):
        load_bvh(path)


def _flat_asf(n_bones: int) -> str:
    out = [":units", "  length 0.45", "  angle deg", ":root", "  order TX TY TZ RX RY RZ", "  axis XYZ",
           "  position 0 0 0", "  orientation 0 0 0", ":bonedata"]
    for k in range(n_bones):
        out += ["begin", f"name b{k}", "direction 0 1 0", "length 1", "axis 0 0 0 XYZ", "dof rx", "end"]
    out += [":hierarchy", "begin", "root " + " ".join(f"b{k}" for k in range(n_bones)), "end"]
    return "\n".join(out) + "\n"


def test_too_many_bones_is_refused(tmp_path):
    """Found by the hang probe: the two-parents check scanned lists (O(n^2)), so a 7 MB
    ASF with 100 000 sibling bones took minutes. Now a set, and a bone limit."""
    path = tmp_path / "flat.asf"
    path.write_text(_flat_asf(textfile.MAX_JOINTS + 1))
    with pytest.raises(MotionFormatError, match="bones"):
        load_asf(path)


def test_wide_asf_within_limits_loads_and_amc_size_is_checked(tmp_path, monkeypatch):
    asf = tmp_path / "wide.asf"
    asf.write_text(_flat_asf(500))
    skeleton = load_asf(asf)
    assert skeleton.skeleton.n_joints == 1 + 2 * 500
    amc = tmp_path / "wide.amc"
    amc.write_text(":DEGREES\n" + "".join(f"{i}\nroot 0 0 0 0 0 0\n" for i in range(1, 21)))
    assert load_amc(amc, skeleton).n_frames == 20
    monkeypatch.setattr(textfile, "MAX_FRAME_JOINTS", 1000)
    with pytest.raises(MotionFormatError, match="joint poses"):
        load_amc(amc, skeleton)


def test_bvh_with_too_many_joints_is_refused(tmp_path):
    parts = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 1 Xrotation"]
    for k in range(textfile.MAX_JOINTS + 1):
        parts += [f"JOINT j{k}", "{", "OFFSET 0 1 0", "}"]
    parts += ["}", "MOTION", "Frames: 1", "Frame Time: 0.01", "0"]
    path = tmp_path / "wide.bvh"
    path.write_text("\n".join(parts) + "\n")
    with pytest.raises(MotionFormatError, match="joints"):
        load_bvh(path)


def test_declared_million_frames_with_few_rows_is_truncation(tmp_path):
    path = tmp_path / "m.bvh"
    path.write_text(_one_joint_bvh(1_000_000, rows=5))
    with pytest.raises(MotionFormatError, match="truncated"):
        load_bvh(path)


def test_zero_frames_is_refused(tmp_path):
    path = tmp_path / "z.bvh"
    path.write_text(_one_joint_bvh(0))
    with pytest.raises(MotionFormatError, match="no frames"):
        load_bvh(path)


def test_file_size_limit_message_names_the_limit(tmp_path):
    path = tmp_path / "big.bvh"
    with open(path, "wb") as fh:
        fh.truncate(textfile.MAX_FILE_BYTES + 1)  # sparse: no disk used
    with pytest.raises(MotionFormatError, match="64 MB limit"):
        load_bvh(path)


def test_subnormal_asf_length_unit_is_refused(tmp_path):
    """Found by the 100k campaign: ':units length 5e-324' loaded with metres_per_unit = inf."""
    path = tmp_path / "u.asf"
    path.write_text(_flat_asf(2).replace("length 0.45", "length 5e-324"))
    with pytest.raises(MotionFormatError, match="length unit"):
        load_asf(path)


def test_huge_bvh_offsets_are_refused(tmp_path):
    """Found while checking the campaign's finding: OFFSET 1e308 on chained joints loaded,
    then forward kinematics gave inf joint positions."""
    text = _one_joint_bvh(3).replace("OFFSET 0 100 0", "OFFSET 0 1e308 0")
    path = tmp_path / "o.bvh"
    path.write_text(text)
    with pytest.raises(MotionFormatError, match="implausibly large"):
        load_bvh(path)
    path.write_text(_one_joint_bvh(3).replace("0 90 0 1 2 3", "0 1e308 0 1 2 3"))
    with pytest.raises(MotionFormatError, match="position channel"):
        load_bvh(path)


def test_huge_asf_bone_length_and_amc_translation_are_refused(tmp_path):
    asf = tmp_path / "b.asf"
    asf.write_text(_flat_asf(3).replace("length 1\n", "length 1e308\n", 1))
    with pytest.raises(MotionFormatError, match="bone length"):
        load_asf(asf)
    asf.write_text(_flat_asf(3))
    amc = tmp_path / "t.amc"
    amc.write_text(":DEGREES\n1\nroot 1e308 0 0 0 0 0\n2\nroot 0 0 0 0 0 0\n")
    with pytest.raises(MotionFormatError, match="root translation"):
        load_amc(amc, load_asf(asf))
