"""The motion model: a :class:`Skeleton` (joint hierarchy and rest offsets) and a
:class:`Motion` (per-frame root translation and joint rotations at a frame rate).

One model serves every file format (ASF/AMC, BVH) so features, retrieval, retargeting and
rendering never care where a clip came from. Conventions, chosen so FK is one rule for all:

* Joint ``j`` sits at ``p_j = p_parent + G_parent @ offset_j`` where ``G`` is the global
  rotation; ``G_j = G_parent @ R_j`` with ``R_j`` the local rotation of frame ``t``.
  BVH joints map onto this directly. An Acclaim bone becomes a joint at the bone's *start*
  (its children are offset by ``direction * length``), with ``R_j = C M C^T`` for the
  bone's axis matrix ``C``; bones with no children get an end-site joint at their tip.
* Lengths are in the file's native unit; ``Skeleton.metres_per_unit`` converts them.
  ``Skeleton.up_axis`` ("y" or "z") records the file's up axis; ``kinematics`` returns
  positions in metres with Y up unless told otherwise, so motions from different files
  compare directly.
* End sites are joints with no channels. ``Joint.channels`` keeps the file's channel
  layout (e.g. ``["Xposition", ..., "Zrotation", "Yrotation", "Xrotation"]``) and
  ``Joint.rotation_order`` the Euler order, so a writer can reproduce the layout.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


@dataclass
class Joint:
    """One node of the hierarchy.

    ``offset`` is the rest offset from the parent in the parent's frame (native units).
    ``rotation_order`` is the Euler order in which rotation channels are composed,
    outermost first: "ZYX" means ``R = Rz @ Ry @ Rx``. ``channels`` is the file's channel
    list (empty for an end site). ``pre_rotation`` is a fixed rotation ``C`` such that the
    local rotation is ``C @ E @ C.T`` for the Euler rotation ``E`` (Acclaim's bone axis;
    identity for BVH).
    """

    name: str
    parent: int
    offset: np.ndarray
    channels: list[str] = field(default_factory=list)
    rotation_order: str = "ZYX"
    pre_rotation: np.ndarray | None = None

    @property
    def is_end_site(self) -> bool:
        return not self.channels


@dataclass
class Skeleton:
    """A joint hierarchy; joints are stored parents-before-children (index 0 is the root)."""

    joints: list[Joint]
    metres_per_unit: float = 0.01
    up_axis: str = "y"
    name: str = ""

    def __post_init__(self) -> None:
        for i, j in enumerate(self.joints):
            if i == 0 and j.parent != -1:
                raise ValueError("joint 0 must be the root (parent -1)")
            if i > 0 and not 0 <= j.parent < i:
                raise ValueError(f"joint {j.name!r}: parent must come before it")
        self._index = {j.name: i for i, j in enumerate(self.joints)}

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def parents(self) -> np.ndarray:
        return np.array([j.parent for j in self.joints], dtype=np.int64)

    @property
    def offsets(self) -> np.ndarray:
        """(J, 3) rest offsets in native units."""
        return np.array([j.offset for j in self.joints], dtype=np.float64).reshape(-1, 3)

    def index(self, name: str) -> int:
        """Index of the joint called ``name`` (KeyError if absent)."""
        return self._index[name]

    def get(self, name: str) -> int | None:
        return self._index.get(name)

    def children(self, i: int) -> list[int]:
        return [k for k, j in enumerate(self.joints) if j.parent == i]


@dataclass
class Motion:
    """A clip: ``rotations`` (T, J, 3, 3) local rotation matrices (pre-rotation folded in),
    ``root_translation`` (T, 3) in native units, at ``fps`` frames per second.

    ``joint_translations`` (T, J, 3), when not None, replaces the rest offsets per frame
    (BVH files with position channels on non-root joints); the root's row is ignored in
    favour of ``root_translation``.
    """

    skeleton: Skeleton
    rotations: np.ndarray
    root_translation: np.ndarray
    fps: float
    name: str = ""
    joint_translations: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = self.rotations.shape[0]
        if self.rotations.shape != (t, self.skeleton.n_joints, 3, 3):
            raise ValueError(
                f"rotations must be (T, {self.skeleton.n_joints}, 3, 3), got {self.rotations.shape}"
            )
        if self.root_translation.shape != (t, 3):
            raise ValueError(f"root_translation must be ({t}, 3), got {self.root_translation.shape}")
        if self.fps <= 0:
            raise ValueError("fps must be positive")

    @property
    def n_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def seconds(self) -> float:
        return self.n_frames / self.fps

    def copy(self, **changes) -> "Motion":
        """A copy with arrays duplicated and any field replaced."""
        base = replace(
            self,
            rotations=self.rotations.copy(),
            root_translation=self.root_translation.copy(),
            joint_translations=None if self.joint_translations is None else self.joint_translations.copy(),
        )
        return replace(base, **changes) if changes else base

    def slice(self, start: int, stop: int) -> "Motion":
        """Frames ``start:stop`` as a new motion."""
        jt = None if self.joint_translations is None else self.joint_translations[start:stop].copy()
        return Motion(
            self.skeleton,
            self.rotations[start:stop].copy(),
            self.root_translation[start:stop].copy(),
            self.fps,
            self.name,
            jt,
        )
