"""The research's experiment: the method and its baselines behind one matcher interface
(the seed's quantised DTW, exact DTW on features, Forbes–Fiume) and the k-fold 1-NN
evaluation; the cross-skeleton identity checks."""
from __future__ import annotations

from lab.experiment.baselines import (
    ExactDTWMatcher,
    ForbesFiumeMatcher,
    kmeans_pp_seeds,
)
from lab.experiment.cross_skeleton import (
    POSE_FRACTIONS,
    OtherTrial,
    other_skeleton_trials,
    pose_identity,
    skeleton_identity,
)
from lab.experiment.evaluation import (
    METHODS,
    SEED_METHODS,
    SPLITS,
    EvaluationError,
    MethodResult,
    evaluate,
    make_matcher,
    plot_confusion,
    plot_sweep,
    stratified_folds,
    stratified_subset,
    subject_folds,
    sweep_dims,
    warm_up,
)
from lab.experiment.matchers import (
    FastMatcher,
    Matcher,
    MatcherError,
    QuantizedMatcher,
    StoryBeamMatcher,
    stack_frames,
)

__all__ = [
    "Matcher",
    "MatcherError",
    "stack_frames",
    "QuantizedMatcher",
    "FastMatcher",
    "StoryBeamMatcher",
    "kmeans_pp_seeds",
    "ExactDTWMatcher",
    "ForbesFiumeMatcher",
    "METHODS",
    "SEED_METHODS",
    "SPLITS",
    "subject_folds",
    "EvaluationError",
    "MethodResult",
    "stratified_folds",
    "stratified_subset",
    "make_matcher",
    "evaluate",
    "sweep_dims",
    "plot_sweep",
    "plot_confusion",
    "warm_up",
    "POSE_FRACTIONS",
    "OtherTrial",
    "other_skeleton_trials",
    "pose_identity",
    "skeleton_identity",
]
