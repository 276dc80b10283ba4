"""StoryBeam's own feature set (``"storybeam"``): the 17 body-part distances of
:data:`~retrieval.features.relational.MR17`, unchanged and in the same order, plus the
body's turning rate, plus where each hand is in the body's own frame (:func:`hand_specs`).

Why the extra column: every MR17 value is a distance or a height, invariant to the
body's heading — which is what makes them skeleton- and placement-invariant, but also
why they cannot tell a straight walk from a walk that turns, nor a left turn from a
right one (on bandai2, exact DTW on MR17 gets walk-turn-left right 76 % of the time).
The turning rate (:func:`~retrieval.features.relational.heading_rate`, radians per
second, signed: left turns positive) is also invariant to position, heading, bone
lengths, units and frame rate, and it separates exactly those classes. Its weight
(:data:`HEADING_WEIGHT`, 0.5) puts a brisk turn (about 1 rad/s) at half a leg length,
on the scale of the distances; docs/notebook/results.md has the ablation that chose it.

The distances are taken on the canonical body (:data:`BODY`): every skeleton re-posed
with the same bone lengths (:func:`~retrieval.motion.canonical_pose`), so a trial on
another character gives the same features as on its own. The first 17 columns are
MR17's pairs in MR17's order (:func:`mr17_columns`), on that body.

Why the hand columns (issue 31): a wave, a knock on a door and a guiding arm put the hand
at much the same distances from the head and shoulders, but one swings it across in front
of the face, one forward and back, one holds it out to the side. The last four columns
say which. The 2-bit codes see only the first 18 columns (:attr:`FeatureSet.coded`):
the hand columns vary with each performer's arm swing in a walk, and coded they cost the
two-actor gait studio 7.6 points leaving one actor out; in the summaries and the exact
re-ranking they cost it 2.2 and gain the gesture studio 4.8 (with the shortlist of 4;
docs/notebook/results.md, "Gestures from another studio").
"""
from __future__ import annotations

import numpy as np

from retrieval.features.relational import MR17, FeatureSet, FeatureSpec, register_feature_set

#: Multiplier of the turning rate (rad/s) beside distances in leg lengths (ablation in
#: docs/notebook/results.md).
HEADING_WEIGHT = 0.5

#: How lengths are normalised ("legs" as MR17; "arms" and "chain" were tried for
#: identity, see docs/notebook/results.md).
NORMALISE = "legs"

#: Whether each feature's mean over the clip is subtracted (ablation in docs/notebook/results.md).
CENTRE = False

#: Which body the distances are taken on: "canonical" re-poses every skeleton onto the
#: canonical body first (:func:`~retrieval.motion.canonical_pose`; issue 31), "source"
#: is the file's own. Canonical since issue 31: on the file's body a clip's features
#: carry its skeleton's proportions — a long-armed body's hand-to-head distances sit
#: higher *and* swing wider (twice as wide on the cartoon development conversion), so
#: neither the class ranking nor "find this clip" (which removes only each column's
#: offset) recognises a trial converted to another character (the class ranking found
#: 166 / 205 of the rig's trials, 86 / 205 of the cartoon's; on the canonical body
#: 205 / 205 each), while CMU and bandai2 hold (docs/notebook/results.md, "The clip
#: features on the canonical body").
BODY = "canonical"

_TURN_JOINTS = ("left_hip", "right_hip", "left_shoulder", "right_shoulder")

#: Weight of the four hand-placement columns (:func:`hand_specs`; leg lengths, as the
#: distances); 0 leaves them out. At 1 since issue 31's gesture studio (UTD-MHAD, leave one
#: performer out: 81.9 -> 86.6 % with the shortlist of 4 then; docs/notebook/results.md). They enter the exact
#: re-ranking and the clip summaries but not the 2-bit codes (:attr:`FeatureSet.coded`):
#: coded too, they cost the two-actor gait studio 7.6 points leaving one actor out.
HANDS_WEIGHT = 1.0


def hand_specs(weight: float = 1.0) -> tuple[FeatureSpec, ...]:
    """Where each hand is in the body's own horizontal frame: its offset from the neck
    along the body's left-to-right axis ("across": out to the side vs across the chest)
    and along its forward axis (in front of the chest vs beside or behind it), in leg
    lengths (:func:`~retrieval.features.relational.body_axes`). A distance cannot say
    this — a hand out to the side and a hand in front are equally far from the
    shoulder — but a wave (the hand swinging across in front of the face), a guiding
    gesture (the arm held out forward and to the side) and a raised hand differ exactly
    there. Invariant to position and heading (the frame turns with the body), to bone
    lengths and units (leg lengths); the neck, not the head, because rigs disagree
    about where the head joint sits."""
    out = []
    for side in ("left", "right"):
        for kind in ("across", "forward"):
            out.append(FeatureSpec(f"{side[0]}hand_{kind}", kind, (f"{side}_hand", "neck") + _TURN_JOINTS,
                                   f"where the {side} hand is: {'to the side / across the body' if kind == 'across' else 'in front of / behind the chest'}",
                                   weight))
    return tuple(out)


def storybeam_feature_set(heading_weight: float = HEADING_WEIGHT, name: str = "storybeam",
                          normalise: str = NORMALISE, centre: bool = CENTRE, body: str = BODY,
                          hands_weight: float = HANDS_WEIGHT) -> FeatureSet:
    """MR17's pairs plus the turning rate at ``heading_weight``, lengths normalised by
    ``normalise``, on the ``body``, then — when ``hands_weight`` > 0 — the four
    hand-placement columns of :func:`hand_specs` at that weight, which the codes do not
    see (``coded``: the first 18 columns). The registered set uses :data:`HEADING_WEIGHT`,
    :data:`NORMALISE`, :data:`BODY` and :data:`HANDS_WEIGHT`; other values are for
    ablations (``"storybeam-no-hands"``: the set before the hand columns)."""
    base = MR17.dim + 1
    return FeatureSet(
        name=name,
        normalise=normalise,
        centre=centre,
        body=body,
        description="MR17 body-part distances plus the body's turning rate (rad/s)"
                    + (" and where the hands are in the body's frame" if hands_weight > 0 else ""),
        specs=MR17.specs + (
            FeatureSpec("heading_rate", "heading_rate", _TURN_JOINTS,
                        "turning: a walk that turns left / right vs a straight walk", heading_weight),
        ) + (hand_specs(hands_weight) if hands_weight > 0 else ()),
        coded=base if hands_weight > 0 else 0,
    )


STORYBEAM = register_feature_set(storybeam_feature_set())
#: The StoryBeam set without the hand-placement columns (the set before issue 31's gesture
#: studio; an ablation).
STORYBEAM_NO_HANDS = register_feature_set(storybeam_feature_set(name="storybeam-no-hands", hands_weight=0.0))


def heading_weight_of(feature_set: FeatureSet) -> float:
    """The weight of a StoryBeam set's turning-rate column."""
    return next(s.weight for s in feature_set.specs if s.kind == "heading_rate")


def mr17_columns(features: np.ndarray) -> np.ndarray:
    """The MR17 part (first 17 columns) of features of the StoryBeam set (or MR17 itself)."""
    return np.asarray(features)[:, : MR17.dim]
