"""Characters: closed rounded parts on the canonical body, sized in table units."""
from __future__ import annotations

import numpy as np
import pytest

from ar.render.characters import CHARACTER_NAMES, CharacterError, build_character, rest_motion, save_character
from retrieval.motion import CANONICAL_JOINTS


@pytest.mark.parametrize("name", CHARACTER_NAMES)
def test_character_is_built_of_closed_parts_and_stands_on_the_table(name):
    ch = build_character(name)
    assert len(CHARACTER_NAMES) >= 3
    assert all(p.mesh.is_watertight for p in ch.parts), [p.name for p in ch.parts if not p.mesh.is_watertight]
    mesh = ch.posed_mesh()
    lo, hi = mesh.bounds
    # default 12 cm tall (head top), soles on y = 0; extras (ears, antenna) may add a little
    assert lo[1] == pytest.approx(0.0, abs=0.002)
    assert 0.115 <= hi[1] <= 0.14
    # a kid-sized figure: wider than thin details, narrower than tall
    assert 0.04 < hi[0] - lo[0] < hi[1] - lo[1]
    assert {p.joint for p in ch.parts} >= set(CANONICAL_JOINTS) - {"left_toe", "right_toe"}


@pytest.mark.parametrize("name", CHARACTER_NAMES)
def test_character_has_eyes_and_bright_colours(name):
    ch = build_character(name)
    eyes = [p for p in ch.parts if p.name.startswith("eye_")]
    assert len(eyes) == 2
    body_colours = np.array([p.colour for p in ch.parts if not p.name.startswith(("pupil", "eye"))], float)
    # saturated or bright: max channel high for every visible part (projected light on a table)
    assert (body_colours.max(axis=1) >= 200).all()


@pytest.mark.parametrize("name", CHARACTER_NAMES)
def test_no_thin_details(name):
    ch = build_character(name)
    for p in ch.parts:
        ext = p.mesh.extents
        assert ext.min() >= 0.004 * 0.99, (p.name, ext)  # nothing thinner than 4 mm at 12 cm


def test_height_is_adjustable():
    small, big = build_character("cat", 0.10), build_character("cat", 0.20)
    hs = small.posed_mesh().bounds[1, 1]
    hb = big.posed_mesh().bounds[1, 1]
    assert hb / hs == pytest.approx(2.0, rel=0.01)


def test_bad_names_and_sizes_raise():
    with pytest.raises(CharacterError):
        build_character("dragon")
    with pytest.raises(CharacterError):
        build_character("robot", height_m=-1.0)


def test_posed_parts_follow_the_motion(tmp_path):
    ch = build_character("kid")
    m = rest_motion(ch, 2)
    m.root_translation[1, 0] += 5.0  # 5 cm along x (native unit: cm)
    poses = ch.all_part_poses(m)
    assert poses.shape == (2, len(ch.parts), 4, 4)
    np.testing.assert_allclose(poses[1, :, 0, 3] - poses[0, :, 0, 3], 0.05, atol=1e-9)
    path = save_character(ch, tmp_path)
    assert path.is_file() and (tmp_path / "kid.glb").stat().st_size > 1000
