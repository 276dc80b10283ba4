"""Motion file loading (Acclaim ASF/AMC, BVH), the BVH writer and malformed input."""
from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from retrieval.motion.formats import textfile
from retrieval.motion import canonical_joint_map
from retrieval.motion.formats import detect_tpose, load_bvh, save_bvh
from retrieval.errors import MotionFormatError
from retrieval.motion import global_transforms, positions, rest_positions
from retrieval.motion import Motion, Skeleton
from retrieval.motion.formats import clear_skeleton_cache, load_motion, load_skeleton
from tests.support.synthetic_motion import TINY_ASF

ACCLAIM_M = 0.0254 / 0.45  # metres per unit of CMU's ASF files (":units length 0.45")

# ----------------------------------------------------------------------------- Acclaim on a tiny hand-made skeleton
# (TINY_ASF, from tests/support/synthetic_motion.py)


def _write(tmp_path: Path, name: str, text: str | bytes) -> Path:
    p = tmp_path / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text)
    return p


def test_acclaim_axis_and_dof_conventions(tmp_path):
    asf = _write(tmp_path, "tiny.asf", TINY_ASF)
    amc = _write(
        tmp_path,
        "tiny_01.amc",
        ":FULLY-SPECIFIED\n:DEGREES\n"
        "1\nroot 1 2 3 0 0 0\na 90\nb 0 0 0\n"
        "2\nroot 0 0 0 0 0 0\na 0\nb 90 90 0\n"
        "3\nroot 0 0 0 0 0 0\n",  # bones a and b missing: identity
    )
    m = load_motion(amc, asf)
    assert m.fps == 120.0 and m.n_frames == 3
    assert m.skeleton.names == ["root", "a", "b", "b_end"]
    assert m.skeleton.metres_per_unit == pytest.approx(ACCLAIM_M)
    p = positions(m, metres_yup=False)
    # Frame 1: C = Rz(90) turns a's x axis into world y, so "rx 90" on a is a 90 degree
    # turn about world Y: a's tip (2,0,0) -> (0,0,-2); b continues along it.
    np.testing.assert_allclose(p[0], [[1, 2, 3], [1, 2, 3], [1, 2, 1], [1, 2, 0]], atol=1e-12)
    # Frame 2: dof rx ry rz composes as Rz @ Ry @ Rx: Rx(90) keeps (1,0,0), Ry(90)
    # sends it to (0,0,-1). (Rx @ Ry @ Rz would give (0,1,0).)
    np.testing.assert_allclose(p[1, 3], [2, 0, -1], atol=1e-12)
    # Frame 3: missing bones keep the rest pose.
    np.testing.assert_allclose(p[2], [[0, 0, 0], [0, 0, 0], [2, 0, 0], [3, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(positions(m)[0, 3], np.array([1, 2, 0]) * ACCLAIM_M, atol=1e-12)


def test_root_rotation_order_from_asf(tmp_path):
    text = TINY_ASF.replace("order TX TY TZ RX RY RZ", "order TX TY TZ RZ RY RX")
    asf = _write(tmp_path, "rootorder.asf", text)
    amc = _write(tmp_path, "rootorder.amc", "1\nroot 0 0 0 90 90 0\n")
    # Values are rz=90, ry=90, rx=0 applied in that order: R = Ry(90) @ Rz(90).
    p = positions(load_motion(amc, asf), metres_yup=False)[0]
    # a's tip (2,0,0): Rz(90) -> (0,2,0); Ry(90) keeps it.
    np.testing.assert_allclose(p[2], [0, 2, 0], atol=1e-12)


def test_amc_with_bones_in_any_order_matches_uniform_file(cmu_dir, tmp_path):
    """Reordering bones inside one frame (legal AMC) takes the line-by-line reader; it
    must agree exactly with the fast reader used for the uniform original."""
    src = cmu_dir / "amc" / "02_01.amc"
    lines = src.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.strip() == "1")
    second = next(i for i, line in enumerate(lines) if line.strip() == "2")
    block = lines[first + 1 : second]
    lines[first + 1 : second] = block[::-1]
    shuffled = _write(tmp_path, "02_01.amc", "\n".join(lines) + "\n")
    asf = cmu_dir / "asf" / "02.asf"
    a, b = load_motion(src, asf), load_motion(shuffled, asf)
    np.testing.assert_array_equal(a.rotations, b.rotations)
    np.testing.assert_array_equal(a.root_translation, b.root_translation)


# ----------------------------------------------------------------------------- the two CMU formats agree


def test_amc_and_bvh_of_the_same_take_agree(cmu_dir):
    """extra/01_01.amc (ASF 01) and extra/01_01.bvh (CMU's own BVH conversion, 120 fps,
    ASF length units, plus a leading T-pose frame) give the same joints.

    Measured (this test's data): hips, spine and legs agree to 0.01 mm; every joint above
    the thorax differs by exactly the thorax bone (11.66 cm): the BVH conversion puts
    ``Neck`` and the clavicles at the thorax's *start* (OFFSET 0 0 0 from ``Spine1``).
    Adding the AMC's thorax bone vector back, those agree to 0.005 mm. Tolerance: 0.1 mm.
    """
    amc = load_motion(cmu_dir / "extra" / "01_01.amc", cmu_dir / "asf" / "01.asf")
    raw = load_motion(cmu_dir / "extra" / "01_01.bvh", drop_tpose=False)
    bvh = load_motion(cmu_dir / "extra" / "01_01.bvh")
    assert detect_tpose(raw) and bvh.n_frames == raw.n_frames - 1
    assert bvh.skeleton.metres_per_unit == pytest.approx(ACCLAIM_M)  # detected, not given
    assert bvh.skeleton.up_axis == "y"
    assert amc.fps == bvh.fps == 120.0
    assert amc.n_frames == bvh.n_frames  # frame k of one is frame k of the other in time
    pa, pb = positions(amc), positions(bvh)
    ca, cb = canonical_joint_map(amc.skeleton), canonical_joint_map(bvh.skeleton)

    sk = amc.skeleton
    thorax = sk.index("thorax")
    g, _ = global_transforms(amc)
    thorax_bone = sk.offsets[sk.index("lowerneck")]  # the thorax's direction * length
    thorax_vec = np.einsum("tab,b->ta", g[:, thorax], thorax_bone) * sk.metres_per_unit
    above_thorax = {"neck", "head", "left_shoulder", "left_elbow", "left_hand",
                    "right_shoulder", "right_elbow", "right_hand"}
    tol = 1e-4  # metres
    for part in ca:
        a, b = pa[:, ca[part]], pb[:, cb[part]]
        if part in above_thorax:
            gap = np.linalg.norm(a - b, axis=1)
            np.testing.assert_allclose(gap, np.linalg.norm(thorax_bone) * ACCLAIM_M, atol=tol, err_msg=part)
            b = b + thorax_vec
        err = np.linalg.norm(a - b, axis=1).max()
        assert err < tol, f"{part}: {err * 1000:.3f} mm"


# ----------------------------------------------------------------------------- every shared file


def _rows(cmu_dir: Path) -> list[dict]:
    with open(cmu_dir / "labels.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_every_labelled_file_loads_upright_and_human_sized(cmu_dir):
    rows = _rows(cmu_dir)
    assert rows
    formats = set()
    problems = []
    for r in rows:
        skel = cmu_dir / r["skeleton"] if r["skeleton"] else None
        m = load_motion(cmu_dir / r["file"], skel)
        formats.add(Path(r["file"]).suffix)
        cmap = canonical_joint_map(m.skeleton)
        p = positions(_every(m, 4))
        head = p[:, cmap["head"], 1]
        ankles = p[:, [cmap["left_ankle"], cmap["right_ankle"]], 1].max(axis=1)
        # Arms can reach above the head (14_07 "jump up to grab"): measure height without them.
        arms = {cmap[k] for k in cmap if k.split("_")[-1] in ("shoulder", "elbow", "hand")}
        arms |= {j for j in range(m.skeleton.n_joints) if _has_ancestor(m.skeleton, j, arms)}
        body = [j for j in range(m.skeleton.n_joints) if j not in arms]
        # The tallest moment of the clip, or the rest pose when that stands upright: a
        # clip may crouch throughout (127_32 "run, duck underneath" peaks at 1.39 m).
        height = (p[:, body, 1].max(axis=1) - p[:, body, 1].min(axis=1)).max()
        rest = rest_positions(m.skeleton)
        if rest[cmap["head"], 1] - rest[cmap["left_ankle"], 1] > 1.0:
            height = max(height, np.ptp(rest[body, 1]))
        if not np.median(head - ankles) > 0.5:  # 127_32 "run, duck underneath" ducks
            problems.append(f"{r['trial']}: head not above ankles")
        if not 1.4 <= height <= 2.0:
            problems.append(f"{r['trial']}: height {height:.2f} m")
        # labels.csv counts the converter's T-pose frame that the loader drops.
        if abs(m.seconds - float(r["seconds"])) > 1 / m.fps + 0.006:
            problems.append(f"{r['trial']}: {m.seconds:.2f} s, labels say {r['seconds']}")
    assert formats == {".amc", ".bvh"}
    assert not problems, problems


def _every(m: Motion, k: int) -> Motion:
    """Every k-th frame (enough to judge posture, k times faster)."""
    jt = None if m.joint_translations is None else m.joint_translations[::k]
    return Motion(m.skeleton, m.rotations[::k], m.root_translation[::k], m.fps / k, m.name, jt)


def _has_ancestor(sk, j: int, group: set[int]) -> bool:
    while j >= 0:
        if j in group:
            return True
        j = sk.joints[j].parent
    return False


def test_character_creator_files_stand_on_the_floor(cmu_dir):
    """CC_Base_Hip-rooted files add their channels to a 105 cm root OFFSET; read that
    way (root_offset='auto' picks it) the feet are on the floor, read the other way they
    would be a metre below it."""
    m = load_motion(cmu_dir / "bvh" / "07_02.bvh")
    assert m.skeleton.names[0] == "CC_Base_Hip" and m.skeleton.metres_per_unit == 0.01
    floor = np.median(positions(m)[..., 1].min(axis=1))
    assert abs(floor) < 0.1
    replaced = load_motion(cmu_dir / "bvh" / "07_02.bvh", root_offset="replace")
    assert np.median(positions(replaced)[..., 1].min(axis=1)) < -0.9


# ----------------------------------------------------------------------------- BVH write -> read


def _random_bvh_text(n_frames: int = 40, seed: int = 1) -> str:
    """A Z-up, centimetre humanoid with mixed layouts: root in YXZ order, a 6-channel
    spine (translation on a non-root joint), ZXY and XZY joints, a 1-channel knee and a
    2-channel elbow, and end sites."""
    rng = np.random.default_rng(seed)
    joints = [  # name, parent index, offset (Z up), channels
        ("Hips", -1, (0, 0, 0), "Xposition Yposition Zposition Yrotation Xrotation Zrotation"),
        ("Spine", 0, (0, 0, 20), "Xposition Yposition Zposition Zrotation Xrotation Yrotation"),
        ("Neck", 1, (0, 0, 40), "Zrotation Yrotation Xrotation"),
        ("Head", 2, (0, 0, 10), "Xrotation Zrotation Yrotation"),
        ("END", 3, (0, 0, 20), ""),
        ("LeftUpLeg", 0, (10, 0, -5), "Zrotation Xrotation Yrotation"),
        ("LeftLeg", 5, (0, 0, -45), "Xrotation"),
        ("LeftFoot", 6, (0, 0, -42), "Zrotation Yrotation Xrotation"),
        ("LeftToeBase", 7, (0, -12, -8), "Xrotation"),
        ("END", 8, (0, -5, 0), ""),
        ("RightUpLeg", 0, (-10, 0, -5), "Zrotation Xrotation Yrotation"),
        ("RightLeg", 10, (0, 0, -45), "Xrotation"),
        ("RightFoot", 11, (0, 0, -42), "Zrotation Yrotation Xrotation"),
        ("RightToeBase", 12, (0, -12, -8), "Xrotation"),
        ("END", 13, (0, -5, 0), ""),
        ("LeftArm", 2, (18, 0, 0), "Zrotation Xrotation Yrotation"),
        ("LeftForeArm", 15, (28, 0, 0), "Yrotation Zrotation"),
        ("LeftHand", 16, (25, 0, 0), "Zrotation Yrotation Xrotation"),
        ("END", 17, (8, 0, 0), ""),
        ("RightArm", 2, (-18, 0, 0), "Zrotation Xrotation Yrotation"),
        ("RightForeArm", 19, (-28, 0, 0), "Yrotation Zrotation"),
        ("RightHand", 20, (-25, 0, 0), "Zrotation Yrotation Xrotation"),
        ("END", 21, (-8, 0, 0), ""),
    ]
    kids: dict[int, list[int]] = {i: [] for i in range(len(joints))}
    for i, j in enumerate(joints):
        if j[1] >= 0:
            kids[j[1]].append(i)
    out = ["HIERARCHY"]

    def emit(i: int, depth: int) -> None:
        name, _, off, chans = joints[i]
        pad = "  " * depth
        out.append(pad + ("End Site" if name == "END" else ("ROOT " if i == 0 else "JOINT ") + name))
        out.append(pad + "{")
        out.append(pad + "  OFFSET %g %g %g" % off)
        if chans:
            out.append(pad + f"  CHANNELS {len(chans.split())} {chans}")
        for k in kids[i]:
            emit(k, depth + 1)
        out.append(pad + "}")

    emit(0, 0)
    rows = []
    for t in range(n_frames):
        vals = []
        for name, _, off, chans in joints:
            for c in chans.split():
                if c.endswith("position"):
                    base = {"X": 0, "Y": 1, "Z": 2}[c[0]]
                    v = (t * 2.0 if c[0] == "Y" else 0.0) + (95.0 if name == "Hips" and c[0] == "Z" else 0.0)
                    v = v if name == "Hips" else off[base] + rng.normal(0, 1.5)
                else:
                    v = rng.uniform(-40, 40)
                vals.append(f"{v:.6f}")
        rows.append(" ".join(vals))
    out += ["MOTION", f"Frames: {n_frames}", "Frame Time: 0.0333333"] + rows
    return "\n".join(out) + "\n"


def test_bvh_mixed_layout_round_trip(tmp_path):
    src = _write(tmp_path, "mixed.bvh", _random_bvh_text())
    m = load_bvh(src, drop_tpose=False)
    assert m.skeleton.up_axis == "z" and m.skeleton.metres_per_unit == 0.01  # detected
    assert m.fps == 30.0
    assert m.joint_translations is not None  # the 6-channel spine
    assert m.skeleton.joints[m.skeleton.index("Hips")].rotation_order == "YXZ"
    out = save_bvh(m, tmp_path / "out.bvh")
    back = load_bvh(out, drop_tpose=False)
    assert back.skeleton.names == m.skeleton.names
    assert [j.channels for j in back.skeleton.joints] == [j.channels for j in m.skeleton.joints]
    np.testing.assert_allclose(back.skeleton.offsets, m.skeleton.offsets)
    p, q = positions(m), positions(back)
    height = np.ptp(p[..., 1], axis=1).max()
    # Tolerance: 1e-6 of body height (values are printed with 6 decimals).
    assert np.abs(p - q).max() < 1e-6 * height
    # Z up in the file means the head is high on world Y.
    cmap = canonical_joint_map(m.skeleton)
    assert (p[:, cmap["head"], 1] > p[:, cmap["left_ankle"], 1] + 0.5).all()


def _breadth_first(m: Motion) -> Motion:
    """The same motion with its joints stored breadth first: every parent still comes
    before its children, but a hip may come before a shoulder's subtree ends."""
    sk = m.skeleton
    order, k = [0], 0
    while k < len(order):
        order += [i for i, j in enumerate(sk.joints) if j.parent == order[k]]
        k += 1
    new_of = {old: new for new, old in enumerate(order)}
    joints = [replace(sk.joints[o], parent=-1 if sk.joints[o].parent < 0 else new_of[sk.joints[o].parent])
              for o in order]
    return Motion(Skeleton(joints, sk.metres_per_unit, sk.up_axis, sk.name), m.rotations[:, order],
                  m.root_translation, m.fps, m.name,
                  None if m.joint_translations is None else m.joint_translations[:, order])


def test_bvh_writes_a_skeleton_stored_out_of_file_order(tmp_path):
    # The file lists joints depth first; a converted rig (DeepMimic's: hips before
    # shoulders) need not be stored so. Each column must still follow its joint.
    m = _breadth_first(load_bvh(_write(tmp_path, "mixed.bvh", _random_bvh_text()), drop_tpose=False))
    assert m.skeleton.names != load_bvh(tmp_path / "mixed.bvh", drop_tpose=False).skeleton.names
    back = load_bvh(save_bvh(m, tmp_path / "out.bvh"), drop_tpose=False)
    p, q = positions(m), positions(back)
    q = q[:, [back.skeleton.index(n) for n in m.skeleton.names]]
    assert np.abs(p - q).max() < 1e-6 * np.ptp(p[..., 1], axis=1).max()


def test_bvh_explicit_units_and_axis_override(tmp_path):
    src = _write(tmp_path, "mixed.bvh", _random_bvh_text())
    m = load_bvh(src, up_axis="y", units="inch", drop_tpose=False)
    assert m.skeleton.up_axis == "y" and m.skeleton.metres_per_unit == 0.0254
    auto = load_bvh(src, drop_tpose=False)
    np.testing.assert_allclose(positions(m, metres_yup=False), positions(auto, metres_yup=False))


def test_acclaim_motion_round_trips_through_bvh(cmu_dir, tmp_path):
    amc = load_motion(cmu_dir / "amc" / "02_01.amc", cmu_dir / "asf" / "02.asf")
    out = save_bvh(amc, tmp_path / "02_01.bvh")
    back = load_motion(out)  # units and axis detected
    assert back.skeleton.metres_per_unit == pytest.approx(ACCLAIM_M)
    assert back.n_frames == amc.n_frames and back.fps == amc.fps
    p = positions(amc)
    assert np.abs(p - positions(back)).max() < 1e-6 * np.ptp(p[..., 1], axis=1).max()


def test_tpose_is_dropped_only_when_it_differs(tmp_path):
    text = _random_bvh_text(n_frames=30, seed=3)
    m = load_bvh(_write(tmp_path, "a.bvh", text), drop_tpose=False)
    assert not detect_tpose(m)  # random frames all differ a lot: no outlier first frame
    smooth = m.copy()
    smooth.rotations[:] = m.rotations[5]  # a still pose ...
    smooth.rotations[0] = np.eye(3)  # ... after a rest-pose first frame
    smooth.joint_translations = None
    assert detect_tpose(smooth)
    path = save_bvh(smooth, tmp_path / "b.bvh")
    assert load_bvh(path).n_frames == smooth.n_frames - 1
    assert load_bvh(path, drop_tpose=False).n_frames == smooth.n_frames


def test_asf_cache_returns_same_object(cmu_dir):
    clear_skeleton_cache()
    a = load_skeleton(cmu_dir / "asf" / "02.asf")
    assert load_skeleton(cmu_dir / "asf" / "02.asf") is a


def test_amc_finds_its_asf_by_cmu_layout(cmu_dir):
    m = load_motion(cmu_dir / "amc" / "02_01.amc")
    assert m.skeleton.name == "02"


# ----------------------------------------------------------------------------- malformed input

GOOD_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 10 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.033333
0 90 0 0 0 0 0 0 0
0 90 0 0 0 0 0 0 1
"""


def _deep_bvh(depth: int) -> str:
    lines = ["HIERARCHY", "ROOT J0", "{", "OFFSET 0 0 0", "CHANNELS 3 Zrotation Yrotation Xrotation"]
    for d in range(1, depth):
        lines += [f"JOINT J{d}", "{", "OFFSET 0 1 0", "CHANNELS 3 Zrotation Yrotation Xrotation"]
    lines += ["}"] * depth
    return "\n".join(lines + ["MOTION", "Frames: 1", "Frame Time: 0.1", " ".join(["0"] * 3 * depth)]) + "\n"


# (file name, content, words expected in the message, line expected in the message)
MALFORMED_BVH = [
    ("truncated_hierarchy.bvh", GOOD_BVH[:120], "truncated", 6),
    ("truncated_frames.bvh", GOOD_BVH.rsplit("0 90", 1)[0], "declared 2 frames but found 1", 19),
    ("short_row.bvh", GOOD_BVH.replace("0 0 0 0 0 1", "0 0 0 0 1"), "expected 9 channel values, found 8", 20),
    ("channel_count.bvh", GOOD_BVH.replace("CHANNELS 3 Zrotation", "CHANNELS 4 Zrotation"), "unknown channel", 10),
    ("bad_channel.bvh", GOOD_BVH.replace("Yrotation Xrotation\n    End", "Yrotation Wrotation\n    End"), "unknown channel", 9),
    ("nan.bvh", GOOD_BVH.replace("0 0 0 0 0 1", "0 0 0 0 nan 1"), "not finite", 20),
    ("inf.bvh", GOOD_BVH.replace("0 90 0 0 0 0 0 0 0", "0 90 0 inf 0 0 0 0 0"), "not finite", 19),
    ("bad_number.bvh", GOOD_BVH.replace("0 0 0 0 0 1", "0 0 0 0 0 1,5"), "bad channel value", 20),
    ("bad_offset.bvh", GOOD_BVH.replace("OFFSET 0 10 0\n    CH", "OFFSET 0 1O 0\n    CH"), "bad OFFSET value", 8),
    ("no_motion.bvh", GOOD_BVH.split("MOTION")[0], "no MOTION section", 15),
    ("empty_motion.bvh", GOOD_BVH.replace("Frames: 2", "Frames: 0"), "no frames", 17),
    ("huge_count.bvh", GOOD_BVH.replace("Frames: 2", "Frames: 20000000"), "exceeds the limit", 17),
    ("zero_time.bvh", GOOD_BVH.replace("0.033333", "0"), "frame time must be positive", 18),
    ("junk.bvh", GOOD_BVH.encode()[:60] + b"\xff\xfe\x00junk" + GOOD_BVH.encode()[60:], "not UTF-8", 5),
    ("deep.bvh", _deep_bvh(300), "deeper than 256", 6 + 4 * 255),
    ("not_bvh.bvh", "hello world\n", "expected 'HIERARCHY'", 1),
    ("empty.bvh", "", "empty file", None),
]


@pytest.mark.parametrize("name,content,words,line", MALFORMED_BVH, ids=[m[0] for m in MALFORMED_BVH])
def test_malformed_bvh_raises_format_error(tmp_path, name, content, words, line):
    path = _write(tmp_path, name, content)
    with pytest.raises(MotionFormatError) as info:
        load_motion(path)
    msg = str(info.value)
    assert name in msg and words in msg
    if line is not None:
        assert info.value.line == line and f"line {line}:" in msg


def test_good_fixture_loads(tmp_path):
    m = load_motion(_write(tmp_path, "good.bvh", GOOD_BVH), drop_tpose=False)
    assert m.n_frames == 2 and m.skeleton.names == ["Hips", "Spine", "Spine_end"]


MALFORMED_AMC = [
    ("unknown_bone.amc", "1\nroot 0 0 0 0 0 0\nwing 3\n", "bone 'wing' is not in skeleton tiny.asf", 3),
    ("wrong_count.amc", "1\nroot 0 0 0 0 0 0\na 1 2\n", "needs 1 values, found 2", 3),
    ("nan.amc", "1\nroot 0 0 0 0 0 0\n2\nroot 0 0 0 0 0 0\na nan\n", "not finite", 5),
    ("bad_number.amc", "1\nroot 0 0 0 0 0 0\nb 1 x 3\n", "bad value 'x'", 3),
    ("empty.amc", ":FULLY-SPECIFIED\n:DEGREES\n", "no frames", None),
    ("before_frame.amc", ":DEGREES\nroot 0 0 0 0 0 0\n", "before the first frame", 2),
    ("twice.amc", "1\na 1\na 2\n", "appears twice", 3),
    ("junk.amc", b"1\nroot 0 0 0 0 0 0\n\x89PNG\r\n", "not UTF-8", 3),
]


@pytest.mark.parametrize("name,content,words,line", MALFORMED_AMC, ids=[m[0] for m in MALFORMED_AMC])
def test_malformed_amc_raises_format_error(tmp_path, name, content, words, line):
    asf = _write(tmp_path, "tiny.asf", TINY_ASF)
    path = _write(tmp_path, name, content)
    with pytest.raises(MotionFormatError) as info:
        load_motion(path, asf)
    msg = str(info.value)
    assert name in msg and words in msg
    if line is not None:
        assert f"line {line}:" in msg


def test_a_latin1_comment_is_read_and_latin1_elsewhere_is_refused(tmp_path):
    """Vicon writes the capture folder into the first comment; HDM05's is Latin-1
    ("#!OML:ASF X:\\für Bonn\\..."). A comment is ignored whatever its bytes; a data line
    that is not UTF-8 is still a bad file, named with its line."""
    asf = _write(tmp_path, "tiny.asf", b"# made in M\xfcnchen\n" + TINY_ASF.encode())
    amc = _write(tmp_path, "take.amc", b"#!OML:ASF X:\\f\xfcr Bonn\\take.ASF\r\n:FULLY-SPECIFIED\r\n:DEGREES\r\n"
                                       b"1\r\nroot 0 0 0 0 0 0\r\n2\r\nroot 0 1 0 0 0 0\r\n")
    m = load_motion(amc, asf)
    assert m.n_frames == 2
    bad = _write(tmp_path, "bad.amc", b"#!OML:ASF X:\\f\xfcr Bonn\n1\nroot 0 0 0 0 0 0\nb 1 \xfc 3\n")
    with pytest.raises(MotionFormatError) as info:
        load_motion(bad, asf)
    assert "not UTF-8" in str(info.value) and info.value.line == 4


MALFORMED_ASF = [
    ("no_end.asf", TINY_ASF.replace("    dof rx\n    limits (-180.0 180.0)\n  end\n", "    dof rx\n"), "missing 'end'", 23),
    ("bad_length.asf", TINY_ASF.replace("length 2\n", "length two\n"), "bad length 'two'", 20),
    ("bad_dof.asf", TINY_ASF.replace("dof rx\n", "dof rq\n"), "unknown dof 'rq'", 22),
    ("unknown_parent.asf", TINY_ASF.replace("    a b\n", "    c b\n"), "unknown bone 'c'", 39),
    ("no_hierarchy.asf", TINY_ASF.split(":hierarchy")[0], "no :hierarchy section", None),
    ("orphan.asf", TINY_ASF.replace("    a b\n", ""), "not connected to the root: b", None),
]


@pytest.mark.parametrize("name,content,words,line", MALFORMED_ASF, ids=[m[0] for m in MALFORMED_ASF])
def test_malformed_asf_raises_format_error(tmp_path, name, content, words, line):
    asf = _write(tmp_path, name, content)
    amc = _write(tmp_path, "ok.amc", "1\nroot 0 0 0 0 0 0\n")
    with pytest.raises(MotionFormatError) as info:
        load_motion(amc, asf)
    msg = str(info.value)
    assert name in msg and words in msg
    if line is not None:
        assert f"line {line}:" in msg


def test_oversized_file_is_refused_before_reading(tmp_path, monkeypatch):
    path = _write(tmp_path, "big.bvh", GOOD_BVH)
    monkeypatch.setattr(textfile, "MAX_FILE_BYTES", 100)
    with pytest.raises(MotionFormatError, match=r"big\.bvh: file is .* limit"):
        load_motion(path)


def test_missing_and_unsupported_files(tmp_path):
    with pytest.raises(MotionFormatError, match="nothere.bvh: cannot read file"):
        load_motion(tmp_path / "nothere.bvh")
    with pytest.raises(MotionFormatError, match="unsupported motion file type '.fbx'"):
        load_motion(_write(tmp_path, "x.fbx", "binary"))
    with pytest.raises(MotionFormatError, match="no ASF skeleton found"):
        load_motion(_write(tmp_path, "lonely_01.amc", "1\n"))
    with pytest.raises(TypeError):
        load_motion(tmp_path / "x.bvh", speed=2)


def test_fuzzed_bvh_only_raises_format_error(tmp_path):
    """Random byte damage to a valid file: either it still loads or it raises
    MotionFormatError — never another exception type."""
    rng = np.random.default_rng(7)
    base = bytearray(_random_bvh_text(n_frames=5).encode())
    for k in range(150):
        data = bytearray(base)
        for _ in range(rng.integers(1, 4)):
            pos = int(rng.integers(0, len(data)))
            action = rng.integers(0, 3)
            if action == 0:
                data[pos] = int(rng.integers(0, 256))
            elif action == 1:
                del data[pos : pos + int(rng.integers(1, 30))]
            else:
                data[pos:pos] = rng.choice(list(b"{}0123456789.-eE \nJOINTEndSite"), size=5).tobytes()
        path = _write(tmp_path, f"fuzz{k}.bvh", bytes(data))
        try:
            load_motion(path)
        except MotionFormatError:
            pass


def test_too_deep_asf_is_refused(tmp_path):
    bones = "".join(
        f"  begin\n    id {i}\n    name b{i}\n    direction 0 1 0\n    length 1\n    axis 0 0 0 XYZ\n    dof rx\n  end\n"
        for i in range(300)
    )
    chain = "    root b0\n" + "".join(f"    b{i} b{i + 1}\n" for i in range(299))
    text = ":units\n  length 1\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n" \
           f":bonedata\n{bones}:hierarchy\n  begin\n{chain}  end\n"
    asf = _write(tmp_path, "deep.asf", text)
    with pytest.raises(MotionFormatError, match=r"deep\.asf: hierarchy deeper than 256"):
        load_skeleton(asf)
