"""Where the hands are in the body's own frame (issue 31, styles and gestures): the
"across" / "forward" feature kinds, :func:`body_axes`, and the ``storybeam`` set's hand columns,
which its codes do not see."""
from __future__ import annotations

import numpy as np
import pytest

from retrieval.features import (
    STORYBEAM,
    STORYBEAM_NO_HANDS,
    FeatureError,
    FeatureSet,
    FeatureSpec,
    body_axes,
    get_feature_set,
    hand_specs,
    heading_weight_of,
    leg_length,
    motion_features,
    storybeam_feature_set,
)
from tests.support.synthetic_motion import make_motion, make_skeleton

_TURN = ("left_hip", "right_hip", "left_shoulder", "right_shoulder")


def test_storybeam_is_the_set_before_plus_four_uncoded_hand_columns():
    assert get_feature_set("storybeam-no-hands") is STORYBEAM_NO_HANDS
    assert STORYBEAM.names[: STORYBEAM_NO_HANDS.dim] == STORYBEAM_NO_HANDS.names
    assert STORYBEAM.names[STORYBEAM_NO_HANDS.dim:] == ["lhand_across", "lhand_forward", "rhand_across", "rhand_forward"]
    assert (STORYBEAM_NO_HANDS.dim, STORYBEAM.dim) == (18, 22)
    # the codes see the 18 columns of the set before; the set without hands codes them all
    assert (STORYBEAM.coded, STORYBEAM.code_columns) == (18, 18)
    assert STORYBEAM_NO_HANDS.code_columns is None
    assert heading_weight_of(STORYBEAM_NO_HANDS) == heading_weight_of(STORYBEAM) == 0.5
    m = make_motion(make_skeleton())
    assert np.array_equal(motion_features(m, "storybeam")[:, : STORYBEAM_NO_HANDS.dim],
                          motion_features(m, "storybeam-no-hands"))
    assert storybeam_feature_set(hands_weight=0.0).dim == STORYBEAM_NO_HANDS.dim


def _axes(heading_deg: float, frames: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Axes of a still body facing +Z turned by ``heading_deg`` about Y (left joints at +X)."""
    t = np.radians(heading_deg)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    body = np.array([[0.1, 1.0, 0.0], [-0.1, 1.0, 0.0], [0.2, 1.5, 0.0], [-0.2, 1.5, 0.0]]) @ rot.T
    return body_axes(np.repeat(body[None], frames, axis=0), [0, 1, 2, 3], 30.0)


def test_body_axes_turn_with_the_body_and_forward_is_where_the_chest_faces():
    across, forward = _axes(0.0)
    assert across[0] == pytest.approx([-1.0, 0.0])  # left (+X) to right (-X)
    assert forward[0] == pytest.approx([0.0, 1.0])  # facing +Z
    across, forward = _axes(90.0)
    assert across[0] == pytest.approx([0.0, 1.0], abs=1e-12)
    assert forward[0] == pytest.approx([1.0, 0.0], abs=1e-12)  # +Z turned by 90 degrees about Y is +X
    assert np.allclose(np.linalg.norm(across, axis=1), 1.0) and np.allclose((across * forward).sum(axis=1), 0.0)


def test_body_axes_with_no_across_direction_fall_back_instead_of_nan():
    pos = np.zeros((4, 4, 3))
    across, forward = body_axes(pos, [0, 1, 2, 3], 30.0)
    assert np.isfinite(across).all() and np.isfinite(forward).all()


def test_hand_columns_on_the_synthetic_body():
    sk = make_skeleton()
    # on the file's own body, where the synthetic skeleton's 18 cm are 18 cm (the registered
    # set re-poses onto the canonical body, whose shoulders sit elsewhere)
    own_body = storybeam_feature_set(name="storybeam-hands-source", hands_weight=1.0, body="source")
    f = motion_features(make_motion(sk, frames=2, arm_swing=0, knee_bend=0), own_body)
    names, legs = STORYBEAM.names, leg_length(sk)
    # the hands hang 18 cm to either side of the spine: left one on the left, right one on the right
    assert f[0, names.index("lhand_across")] == pytest.approx(-0.18 / legs)
    assert f[0, names.index("rhand_across")] == pytest.approx(0.18 / legs)
    assert abs(f[0, names.index("lhand_forward")]) < 1e-9 and abs(f[0, names.index("rhand_forward")]) < 1e-9
    # swinging arms move the hands in front of and behind the chest, in opposition
    g = motion_features(make_motion(sk, arm_swing=40), "storybeam")
    lf, rf = g[:, names.index("lhand_forward")], g[:, names.index("rhand_forward")]
    assert lf.max() > 0.1 and lf.min() < -0.1 and np.corrcoef(lf, rf)[0, 1] < -0.9


def test_hand_columns_are_invariant_to_heading_body_size_and_up_axis():
    cols = slice(STORYBEAM.dim, None)
    base = motion_features(make_motion(make_skeleton(1.0)), "storybeam")[:, cols]
    for other in (make_motion(make_skeleton(0.6)), make_motion(make_skeleton(1.0), heading_deg=70),
                  make_motion(make_skeleton(1.0, up_axis="z"))):
        assert np.allclose(motion_features(other, "storybeam")[:, cols], base, atol=1e-6)


def test_hand_columns_need_the_frame_rate():
    fs = FeatureSet("hands-only", hand_specs())
    assert fs.needs_fps
    sk = make_skeleton()
    m = make_motion(sk)
    from retrieval.motion import canonical_joint_map, positions  # deferred: test-local helpers
    with pytest.raises(FeatureError, match="frame rate"):
        fs.from_positions(positions(m), canonical_joint_map(sk), leg_length(sk), fps=None)


def test_a_hand_spec_with_the_wrong_joints_is_refused():
    from retrieval.features import register_feature_set  # deferred: test-local helper
    with pytest.raises(FeatureError):
        register_feature_set(FeatureSet("bad-hands", (FeatureSpec("x", "across", ("left_hand", "neck")),)))
    assert len(hand_specs()[0].joints) == 2 + len(_TURN)
