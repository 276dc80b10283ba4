"""Retargeting any skeleton onto a character's canonical body, and the BVH round trip."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from ar.render.characters import build_character
from retrieval.motion import canonical_joint_map
from retrieval.motion.formats import load_bvh, save_bvh
from retrieval.motion import positions, resample
from retrieval.motion import Joint, Motion, Skeleton
from retrieval.motion.formats import load_motion
from retrieval.animation.retarget import (
    RetargetError,
    contacts,
    retarget,
    skeleton_leg_length,
    sole_points,
)

ASSETS = Path(__file__).resolve().parents[2] / "assets" / "motions"
LIMBS = [("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("right_hip", "right_knee"),
         ("right_knee", "right_ankle"), ("left_shoulder", "left_elbow"), ("left_elbow", "left_hand"),
         ("right_shoulder", "right_elbow"), ("right_elbow", "right_hand"), ("spine", "neck")]


def _check_retarget(src: Motion, character: str = "robot") -> Motion:
    ch = build_character(character)
    out = retarget(src, ch.skeleton)
    assert out.skeleton.names == ch.skeleton.names and out.n_frames == src.n_frames
    p_src, p_out = positions(src), positions(out)
    cmap = canonical_joint_map(src.skeleton)
    idx = {n: i for i, n in enumerate(out.skeleton.names)}
    for a, b in LIMBS:  # every limb points where the source's limb points
        ds = p_src[:, cmap[b]] - p_src[:, cmap[a]]
        dt = p_out[:, idx[b]] - p_out[:, idx[a]]
        cos = np.sum(ds * dt, 1) / np.linalg.norm(ds, axis=1) / np.linalg.norm(dt, axis=1)
        assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.5, (a, b)
    # root travel scaled by the leg-length ratio
    ratio = skeleton_leg_length(out.skeleton) / skeleton_leg_length(src.skeleton)
    mid = lambda p, lh, rh: 0.5 * (p[:, lh] + p[:, rh])
    travel_src = mid(p_src, cmap["left_hip"], cmap["right_hip"])[[0, -1]][:, [0, 2]]
    travel_out = mid(p_out, idx["left_hip"], idx["right_hip"])[[0, -1]][:, [0, 2]]
    d_src = np.linalg.norm(np.diff(travel_src, axis=0))
    d_out = np.linalg.norm(np.diff(travel_out, axis=0))
    assert d_out == pytest.approx(d_src * ratio, rel=1e-6, abs=1e-6)
    # on the table: in every frame with a foot down, the lowest standing sole point is at y=0
    soles = sole_points(out)
    c = contacts(retarget(src, ch.skeleton, ground=False))  # the contacts grounding works from
    down = c.any(axis=1)
    assert down.mean() > 0.2
    low = np.where(c, soles[:, :, 1], np.inf).min(axis=1)[down]
    scale = ch.height_m / 0.12
    assert np.quantile(np.abs(low), 0.9) < 0.0002 * scale  # 0.2 mm at 12 cm (smoothed edges)
    assert np.abs(low).max() < 0.003 * scale
    # standing feet never sink into the table (a swinging toe may brush below it)
    assert np.where(c, soles[:, :, 1], 0.0).min() > -0.002 * scale
    return out


def _roundtrip(motion: Motion, tmp_path: Path) -> None:
    path = save_bvh(motion, tmp_path / "retargeted.bvh")
    back = load_bvh(path, units=motion.skeleton.metres_per_unit, up_axis="y", drop_tpose=False)
    assert back.skeleton.names == motion.skeleton.names
    assert back.n_frames == motion.n_frames and back.fps == pytest.approx(motion.fps)
    np.testing.assert_allclose(positions(back), positions(motion), atol=1e-6)  # 1 micrometre
    assert canonical_joint_map(back.skeleton)  # still a canonical body


def test_retarget_bundled_walk_and_bvh_round_trip(tmp_path):
    walk = load_motion(ASSETS / "bvh" / "02_01.bvh")
    out = _check_retarget(walk, "kid")
    _roundtrip(out, tmp_path)


def test_retarget_every_shared_acclaim_skeleton(cmu_dir):
    rows = list(csv.DictReader(open(cmu_dir / "labels.csv")))
    first_per_skeleton = {}
    for r in rows:
        if r["skeleton"] and r["skeleton"] not in first_per_skeleton and float(r["seconds"]) < 12:
            first_per_skeleton[r["skeleton"]] = r
    assert len(first_per_skeleton) >= 10
    for asf, r in sorted(first_per_skeleton.items()):
        m = resample(load_motion(cmu_dir / r["file"], cmu_dir / asf), 30)
        _check_retarget(m, "robot")


def test_retarget_character_creator_bvh_and_round_trip(cmu_dir, tmp_path):
    names = sorted(p.name for p in (cmu_dir / "bvh").glob("*.bvh"))
    assert names
    for name in names[:3]:
        m = load_motion(cmu_dir / "bvh" / name)
        assert "CC_Base" in " ".join(m.skeleton.names)
        out = _check_retarget(resample(m, 30), "cat")
    _roundtrip(out, tmp_path)


def test_retarget_same_motion_from_amc_and_bvh_agrees(cmu_dir):
    """01_01 exists as AMC and as a BVH conversion: both must give the same character motion."""
    a = retarget(load_motion(cmu_dir / "extra" / "01_01.amc", cmu_dir / "asf" / "01.asf"), build_character().skeleton)
    b = retarget(load_motion(cmu_dir / "extra" / "01_01.bvh"), build_character().skeleton)
    n = min(a.n_frames, b.n_frames)
    pa, pb = positions(a)[:n], positions(b)[:n]
    assert np.median(np.linalg.norm(pa - pb, axis=-1)) < 0.002  # 2 mm at 12 cm


def test_skeleton_without_legs_is_refused():
    sk = Skeleton([Joint("Hips", -1, np.zeros(3), ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]),
                   Joint("Spine", 0, np.array([0, 10.0, 0]), ["Zrotation", "Yrotation", "Xrotation"])], name="stub")
    m = Motion(sk, np.broadcast_to(np.eye(3), (3, 2, 3, 3)).copy(), np.zeros((3, 3)), 30.0, "stub")
    with pytest.raises(RetargetError, match="stub"):
        retarget(m, build_character().skeleton)
