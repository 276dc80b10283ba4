"""Search by pose: which library clips pass through one posture, and at which frame.

A pose (one posture of the canonical body, from a posable figure or one frame of a motion
file) is turned into the library's own per-frame features (:func:`pose_features`, the
same feature set as the index) and searched in two stages:

1. **Subsequence search over codes** — the pose's features are encoded with the index's
   quantiser into a one-frame code query and :meth:`MotionIndex.subsequence_codes` (the
   product's one search path, the exact :class:`~retrieval.search.SubsequenceSearcher`)
   returns the ``shortlist`` clips that pass closest through that code. For a one-frame
   query the subsequence distance of a clip is ``min_j D[q, b_j] / 2``: the code-table
   distance to the clip's nearest frame code.
2. **Refinement on the features** — 2-bit codes are coarse (one code covers a whole cell
   of poses, so many clips tie at the same code distance and the tie would otherwise be
   broken by library order); each shortlisted clip's frames are compared with the pose by
   Euclidean distance of the real-valued features, and the clips are ranked by their
   nearest frame. That frame is the moment a tile starts at.

The answer is therefore exact for the refined distance *within the shortlist*; a clip
outside it is missed when its code distance is above the shortlist's last while its
feature distance is below. The shortlist is a speed/recall trade: on CMU
(``storybeam bench pose-search``, docs/notebook/results.md) a shortlist of 32 gives the same top
clip as refining every clip for most queries, not all, at the same or better class
accuracy.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.features import get_feature_set
from retrieval.library.clip import Clip, Match
from retrieval.library.dataset import clip_from_motion, load_dataset
from retrieval.library.index import MotionIndex
from retrieval.motion import Motion

#: Clips the code search hands to the refinement by default.
SHORTLIST = 32

#: The feature set a pose search indexes by default (:meth:`PoseSearch.build`): MR17 on
#: the canonical body (issue 31), so a pose from another skeleton -- the app's posable
#: figure, a teacher's file -- lands where the same posture is in the library (same class
#: 0.35 -> 0.96 on a cartoon body), with the floor taken within a second of each frame,
#: which keeps CMU's own jump poses (``storybeam bench pose-search``: jump 96.2 %, the
#: file's own body ``"mr17"`` 92.5 %): docs/notebook/results.md, "Why the canonical body
#: lost CMU's jumps"; ``--body source`` measures the file's own body.
POSE_FEATURE_SET = "mr17-canonical"


def pose_feature_set(body: str | None = None) -> str:
    """The name of the pose search's feature set (:data:`POSE_FEATURE_SET`), or of MR17
    on the other ``body`` ("source": ``"mr17"``; "canonical": ``"mr17-canonical"``)."""
    if body is None:
        return POSE_FEATURE_SET
    if body not in ("source", "canonical"):
        raise StoryBeamError(f"pose search: unknown body {body!r} (source or canonical)")
    return "mr17" if body == "source" else "mr17-canonical"


def pose_floor_joints(feature_set: str = POSE_FEATURE_SET) -> tuple[str, ...]:
    """The canonical joints whose lowest is the floor of ``feature_set``'s heights
    (:attr:`FeatureSet.floor_joints`): a posed body's ``floor`` for :func:`pose_features`
    is their standing height."""
    return get_feature_set(feature_set).floor_joints


def pose_features(positions: np.ndarray, joint_map: Mapping[str, int], body_size: float, floor: float = 0.0,
                  feature_set: str = POSE_FEATURE_SET) -> np.ndarray:
    """The (dim,) features of one posture: ``positions`` (J, 3) in metres, Y up, the
    floor at height ``floor``.

    Method: the feature set's own :meth:`FeatureSet.from_positions` on a one-frame clip,
    whose floor (a percentile of the lowest foot over the clip) is then that frame's
    lowest foot; each "height" column is shifted by ``(lowest foot − floor) / body_size``
    so heights are measured above the given floor instead — a posture with both feet in
    the air (a jump's apex) keeps its height. Every other column does not depend on the
    floor, so the result equals the row of the same frame inside a clip whose floor is
    ``floor`` (exactly for a set on the file's body; on the canonical body the shift is
    the source's ankle height over its leg length, the canonical body's own when the
    source's thigh and shin are equally long and its pelvis level, close otherwise)."""
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise StoryBeamError(f"a pose must be (joints, 3) positions, got shape {pos.shape}")
    if not np.all(np.isfinite(pos)):
        raise StoryBeamError("a pose's positions must be finite")
    fs = get_feature_set(feature_set)
    # a still posture: a rate feature (the heading's) is 0, whatever the frame rate
    out = fs.from_positions(pos[None], dict(joint_map), body_size, 1.0)[0]
    lowest = min(pos[joint_map[j], 1] for j in fs.floor_joints)
    for k, spec in enumerate(fs.specs):
        if spec.kind == "height":
            out[k] += (lowest - floor) / body_size * getattr(spec, "weight", 1.0)
    return out


class PoseSearch:
    """Pose queries over a :class:`MotionIndex` and its clips' features (see the module
    docstring). ``features[i]`` are the (frames, dim) features of the index's clip ``i``,
    the ones its codes were encoded from."""

    def __init__(self, index: MotionIndex, features: Sequence[np.ndarray]):
        if len(features) != len(index):
            raise StoryBeamError(f"pose search: {len(features)} feature arrays for {len(index)} clips")
        width = index.quantizer.pca.mean.shape[0]
        self.features = []
        for i, f in enumerate(features):
            f = np.asarray(f, dtype=np.float64)
            if f.ndim != 2 or f.shape[1] != width or len(f) != len(index.codes[i]):
                raise StoryBeamError(f"pose search: clip {index.trials[i]!r} has features {f.shape}, "
                                     f"codes for {len(index.codes[i])} frames of width {width}")
            self.features.append(f)
        self.index = index

    @classmethod
    def from_clips(cls, clips: Sequence[Clip], dims: int = 6, backend: str = "auto",
                   feature_set: str = POSE_FEATURE_SET) -> "PoseSearch":
        """Index ``clips`` (:meth:`MotionIndex.from_clips`, DTW ``backend``) and keep their
        features; ``feature_set`` names the set they were computed with (the one
        :meth:`motion_pose` computes a query's features with)."""
        return cls(MotionIndex.from_clips(clips, dims, feature_set=feature_set, backend=backend),
                   [c.features for c in clips])

    @classmethod
    def build(cls, folder: str | Path, dims: int = 6, fps: float = 30.0, backend: str = "auto") -> "PoseSearch":
        """A pose search over every clip of a labelled folder at ``fps``."""
        return cls.from_clips(load_dataset(folder, fps=fps, feature_set=POSE_FEATURE_SET), dims, backend)

    def __len__(self) -> int:
        return len(self.index)

    def motion_pose(self, motion: Motion, frame: int) -> np.ndarray:
        """The (dim,) pose query of frame ``frame`` of ``motion`` (numbered in the file's
        own frames): the motion's features at the index's rate and feature set (its own
        floor, :func:`~retrieval.library.clip_from_motion`), the row nearest that frame's
        time — what ``storybeam search --pose FILE:FRAME`` asks."""
        if not 0 <= frame < motion.n_frames:
            raise StoryBeamError(f"pose: frame {frame} is outside the motion's frames 0..{motion.n_frames - 1}")
        feats = clip_from_motion(motion, "", "", self.index.fps, self.index.feature_set).features
        return feats[min(int(round(frame * self.index.fps / motion.fps)), len(feats) - 1)]

    def search(self, pose: np.ndarray, k: int = 5, shortlist: int = SHORTLIST,
               exclude: str | None = None) -> list[Match]:
        """The ``k`` clips passing closest through ``pose`` ((dim,) features, see
        :func:`pose_features`), nearest first, ties by library order; the clip called
        ``exclude`` (a held-back query's own) is left out of the answer."""
        q = np.asarray(pose, dtype=np.float64).reshape(-1)
        width = self.features[0].shape[1]
        if q.shape != (width,) or not np.all(np.isfinite(q)):
            raise StoryBeamError(f"a pose query must be {width} finite features, got shape {np.shape(pose)}")
        if k < 1:
            raise StoryBeamError(f"k must be at least 1, got {k}")
        want = min(len(self), max(shortlist, k) + (exclude is not None))
        codes = self.index.encode(q[None])
        hits = []
        for m in self.index.subsequence_codes(codes, k=want):
            if m.trial == exclude:
                continue
            i = self.index.position(m.trial)
            d = np.sqrt(((self.features[i] - q) ** 2).sum(axis=1))
            j = int(np.argmin(d))
            hits.append((float(d[j]), i, Match(m.trial, m.label, float(d[j]), frame=j, code_distance=m.distance)))
        hits.sort(key=lambda h: (h[0], h[1]))
        return [h[2] for h in hits[:k]]


#: How the evaluation picks a class's most characteristic frame, by feature name:
#: jump — the apex (highest hips above the floor); kick — the highest ankle (either
#: foot); run — the flight phase (both feet highest: the larger of the two ankles'
#: lower height, which a walk never has).
CHARACTERISTIC = {
    "jump": "the frame where the hips are highest above the floor (the apex)",
    "kick": "the frame where either ankle is highest above the floor",
    "run": "the frame where the lower of the two ankles is highest (flight: both feet off the floor)",
}


def characteristic_frame(features: np.ndarray, label: str, feature_set: str = "mr17") -> int | None:
    """The frame of a clip of class ``label`` that shows the class best (see
    :data:`CHARACTERISTIC`), or ``None`` for a class without a rule."""
    names = get_feature_set(feature_set).names
    f = np.asarray(features)

    def col(name: str) -> np.ndarray:
        return f[:, names.index(name)]

    if label == "jump":
        return int(np.argmax(col("hips_height")))
    if label == "kick":
        return int(np.argmax(np.maximum(col("lankle_height"), col("rankle_height"))))
    if label == "run":
        return int(np.argmax(np.minimum(col("lankle_height"), col("rankle_height"))))
    return None
