"""StoryBeam's own feature set (``"storybeam"``): the 17 body-part distances of
:data:`~retrieval.features.relational.MR17`, unchanged and in the same order, plus the
body's turning rate.

Why the extra column: every MR17 value is a distance or a height, invariant to the
body's heading — which is what makes them skeleton- and placement-invariant, but also
why they cannot tell a straight walk from a walk that turns, nor a left turn from a
right one (on bandai2, exact DTW on MR17 gets walk-turn-left right 76 % of the time).
The turning rate (:func:`~retrieval.features.relational.heading_rate`, radians per
second, signed: left turns positive) is also invariant to position, heading, bone
lengths, units and frame rate, and it separates exactly those classes. Its weight
(:data:`HEADING_WEIGHT`, 0.5) puts a brisk turn (about 1 rad/s) at half a leg length,
on the scale of the distances; docs/notebook/results.md has the ablation that chose it.

The first 17 columns are exactly MR17's, so a clip loaded with this set carries the
seed's features too (:func:`mr17_columns`).
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
#: is the file's own.
BODY = "source"

_TURN_JOINTS = ("left_hip", "right_hip", "left_shoulder", "right_shoulder")


def storybeam_feature_set(heading_weight: float = HEADING_WEIGHT, name: str = "storybeam",
                          normalise: str = NORMALISE, centre: bool = CENTRE, body: str = BODY) -> FeatureSet:
    """MR17's pairs plus the turning rate at ``heading_weight``, lengths normalised by
    ``normalise``, on the ``body`` (the registered set uses :data:`HEADING_WEIGHT`,
    :data:`NORMALISE` and :data:`BODY`; other values are for ablations)."""
    return FeatureSet(
        name=name,
        normalise=normalise,
        centre=centre,
        body=body,
        description="MR17 body-part distances plus the body's turning rate (rad/s)",
        specs=MR17.specs + (
            FeatureSpec("heading_rate", "heading_rate", _TURN_JOINTS,
                        "turning: a walk that turns left / right vs a straight walk", heading_weight),
        ),
    )


STORYBEAM = register_feature_set(storybeam_feature_set())


def mr17_columns(features: np.ndarray) -> np.ndarray:
    """The MR17 part (first 17 columns) of features of the StoryBeam set (or MR17 itself)."""
    return np.asarray(features)[:, : MR17.dim]
