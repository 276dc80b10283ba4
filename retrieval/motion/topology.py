"""Map a skeleton onto the canonical body by its shape when its joint names say nothing.

Used by :func:`retrieval.motion.body.canonical_joint_map` when name patterns leave a
canonical joint unmatched (joints called ``j0 .. j30``, or names in another language).
It reads only the hierarchy and the rest pose (offsets), so it is invariant to bone
lengths, units (every threshold is a fraction of the skeleton's own size), up axis and
root offset (only differences of rest positions are used). The method:

1. **Rest pose.** Joint positions with every local rotation identity, in native units.
   ``size`` is the longest leaf-to-leaf path through the tree (bone lengths summed).
   Bones on the root's single-child trunk (a floor joint above the pelvis, offset by the
   take's start position) count zero, so the root offset does not matter.
2. **Limbs.** While more than five leaves remain, prune the shortest leaf *twig* (the
   path from a leaf up to the nearest joint with another remaining child) if it is
   shorter than :data:`TWIG_FRACTION` x ``size``: fingers, thumbs and short helper bones
   go, shortest first, until one chain per hand is left (fingers are shorter than the
   head and neck, so the head stays). Exactly five leaves must remain, else the skeleton
   is refused (too many or too few limbs).
3. **Upper body vs legs.** Of the five limb leaves, the upper body is the unique triple
   whose lowest common ancestor (the *chest*) lies strictly below the common ancestor of
   all five (the *hips*); the other two are the feet. Of the triple, the leaf with the
   shortest path from the chest is the head; the others are the hands.
4. **Up, forward, left.** Up ``u`` is hips -> head leaf. Forward ``f`` is the mean
   direction ankle -> toe of both feet, with its ``u`` component removed; the skeleton is
   refused when the toes give no forward direction (``|f|`` < 10 % of the foot length),
   because left and right could not then be told apart. Left is ``u x f`` (right-handed
   axes: facing +Z with +Y up, the left hand is at +X).
   The feet must lie below the hips and the head above (along ``u``).
5. **Chains.** Along each limb path, joints that coincide with their parent (Acclaim's
   ``lhipjoint`` starts at the root) or carry no channels are skipped. Leg: hip = first,
   toe = last (or the foot's end site when the foot has no toe joint), ankle = the one
   before, knee = the middle joint nearest to the hip-ankle midpoint. Arm: shoulder = the
   first joint at least as far from the body's midline as the hip joints (so a clavicle is
   skipped), elbow and hand = the next two. Head path: neck = the first joint above the
   chest, head = the last; spine = the chest (when the head path has one joint only, the
   chest is the neck and its parent the spine).

Limits: rigs with long helper chains (twist bones, facial bones) beside the limbs, and
rest poses that are not roughly upright with the toes forward (the BVH rest poses of the
shared Bandai and Character Creator files are not), are refused by shape; their names
resolve. Twist bones inside a limb chain are not recognised as such.

Every refusal raises :class:`TopologyError` with the reason; the caller adds the names
it could not match.
"""
from __future__ import annotations

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.motion.model import Skeleton

#: While more than five leaves remain, the shortest leaf twig is pruned if it is shorter
#: than this fraction of the skeleton's size (fingers, thumbs, helper bones).
TWIG_FRACTION = 0.12
#: Joints closer than this fraction of the size to their parent count as coincident.
COINCIDENT_FRACTION = 1e-3


class TopologyError(StoryBeamError):
    """A skeleton's hierarchy and rest pose do not determine the canonical body."""


def _rest(skeleton: Skeleton) -> np.ndarray:
    pos = np.zeros((skeleton.n_joints, 3))
    offs = skeleton.offsets
    for j, joint in enumerate(skeleton.joints):
        if joint.parent >= 0:
            pos[j] = pos[joint.parent] + offs[j]
    return pos


def _path_up(parents: np.ndarray, j: int) -> list[int]:
    """Joints from ``j`` up to the root, ``j`` first."""
    out = [j]
    while parents[out[-1]] >= 0:
        out.append(int(parents[out[-1]]))
    return out


def _lca(parents: np.ndarray, joints: list[int]) -> int:
    common = set(_path_up(parents, joints[0]))
    for j in joints[1:]:
        common &= set(_path_up(parents, j))
    # the deepest common ancestor: the first on any joint's upward path
    return next(a for a in _path_up(parents, joints[0]) if a in common)


def _between(parents: np.ndarray, top: int, leaf: int) -> list[int]:
    """Joints strictly below ``top`` down to ``leaf`` (inclusive), top-down."""
    up = _path_up(parents, leaf)
    return list(reversed(up[: up.index(top)]))


def _size(parents: np.ndarray, bone: np.ndarray) -> float:
    """Longest leaf-to-leaf path (tree diameter weighted by bone length)."""
    n = len(parents)
    down = np.zeros(n)  # longest path from j down to a leaf
    best = 0.0
    children: list[list[int]] = [[] for _ in range(n)]
    for k in range(1, n):
        children[parents[k]].append(k)
    for j in range(n - 1, -1, -1):
        reach = sorted((down[k] + bone[k] for k in children[j]), reverse=True)
        down[j] = reach[0] if reach else 0.0
        best = max(best, sum(reach[:2]))
    return float(best)


def _limb_leaves(parents: np.ndarray, bone: np.ndarray, size: float) -> list[int]:
    n = len(parents)
    alive = np.ones(n, dtype=bool)
    while True:
        live = np.flatnonzero(alive[1:]) + 1
        kids = np.bincount(parents[live], minlength=n)
        leaves = [j for j in range(n) if alive[j] and kids[j] == 0 and j > 0]
        twigs = []
        for leaf in leaves:
            path, length, j = [], 0.0, leaf
            while parents[j] >= 0 and kids[parents[j]] == 1:
                path.append(j)
                length += bone[j]
                j = int(parents[j])
            path.append(j)
            length += bone[j]
            if parents[j] >= 0 and kids[parents[j]] >= 2:
                twigs.append((length, path))
        if not twigs or len(leaves) <= 5:
            return leaves
        length, path = min(twigs, key=lambda t: t[0])
        if length >= TWIG_FRACTION * size:
            return leaves
        alive[path] = False


def topology_joint_map(skeleton: Skeleton) -> dict[str, int]:
    """Canonical joint name -> joint index, from hierarchy and rest pose only (module
    docstring). Raises :class:`TopologyError` when the shape is not a human body or is
    ambiguous."""
    parents = skeleton.parents
    n = len(parents)
    if n < 14:
        raise TopologyError(f"only {n} joints; a body needs at least 14 besides names")
    pos = _rest(skeleton)
    bone = np.zeros(n)
    bone[1:] = np.linalg.norm(pos[1:] - pos[parents[1:]], axis=1)
    # A floor/root joint above the pelvis (Bandai's joint_Root, offset by the take's start
    # position) is not part of the body: bones on the root's single-child trunk count 0.
    j = 0
    while True:
        kids = np.flatnonzero(parents == j)
        if len(kids) != 1:
            break
        j = int(kids[0])
        bone[j] = 0.0
    size = _size(parents, bone)
    if not np.isfinite(size) or size <= 0:
        raise TopologyError("the rest pose is degenerate (all joints at one point)")
    leaves = _limb_leaves(parents, bone, size)
    if len(leaves) != 5:
        raise TopologyError(
            f"found {len(leaves)} limbs in the hierarchy, expected 5 (head, two arms, two legs)"
        )
    hips = _lca(parents, leaves)
    triples = []
    for a in range(5):
        for b in range(a + 1, 5):
            pair = [leaves[a], leaves[b]]
            trio = [x for x in leaves if x not in pair]
            chest = _lca(parents, trio)
            if chest != hips:
                triples.append((pair, trio, chest))
    if len(triples) != 1:
        raise TopologyError("cannot tell the upper body from the legs (limbs do not group 3 + 2)")
    feet, trio, chest = triples[0]

    def path_len(top: int, leaf: int) -> float:
        return float(sum(bone[k] for k in _between(parents, top, leaf)))

    lengths = sorted((path_len(chest, x), x) for x in trio)
    if lengths[0][0] >= 0.8 * lengths[1][0]:
        raise TopologyError("cannot tell the head from the arms (their chains are as long)")
    head_leaf, hands = lengths[0][1], [lengths[1][1], lengths[2][1]]

    eps = COINCIDENT_FRACTION * size

    def chain(top: int, leaf: int) -> list[int]:
        out = []
        for k in _between(parents, top, leaf):
            if bone[k] <= eps or not skeleton.joints[k].channels:
                continue
            out.append(k)
        return out

    up = pos[head_leaf] - pos[hips]
    if np.linalg.norm(up) <= eps:
        raise TopologyError("the head leaf coincides with the hips in the rest pose")
    u = up / np.linalg.norm(up)

    legs = {}
    fwd = np.zeros(3)
    foot_len = 0.0
    for leaf in feet:
        c = chain(hips, leaf)
        if len(c) < 4 and leaf not in c and bone[leaf] > eps:
            c = c + [leaf]  # foot without a toe joint: its end site is the toe
        if len(c) < 4:
            raise TopologyError("a leg has fewer than 4 joints (hip, knee, ankle, toe)")
        if np.dot(pos[c[-2]] - pos[hips], u) >= 0:
            raise TopologyError("a foot is not below the hips in the rest pose")
        hip, ankle, toe = c[0], c[-2], c[-1]
        mid = (pos[hip] + pos[ankle]) / 2
        knee = min(c[1:-2], key=lambda k: float(np.linalg.norm(pos[k] - mid)))
        legs[leaf] = (hip, knee, ankle, toe)
        d = pos[toe] - pos[ankle]
        fwd += d - np.dot(d, u) * u
        foot_len += float(np.linalg.norm(d))
    if np.linalg.norm(fwd) < 0.1 * foot_len or foot_len <= 0:
        raise TopologyError(
            "cannot tell left from right: the toes give no forward direction in the rest pose"
        )
    f = fwd / np.linalg.norm(fwd)
    left = np.cross(u, f)
    legs_by_side = sorted(legs.values(), key=lambda j: float(np.dot(pos[j[0]] - pos[hips], left)))
    (r_leg, l_leg) = legs_by_side
    if np.dot(pos[l_leg[0]] - pos[hips], left) <= 0 or np.dot(pos[r_leg[0]] - pos[hips], left) >= 0:
        raise TopologyError("the hip joints are not on either side of the body")
    hip_lateral = min(abs(float(np.dot(pos[j[0]] - pos[hips], left))) for j in legs_by_side)

    arms = []
    for leaf in hands:
        c = chain(chest, leaf)
        lat = [abs(float(np.dot(pos[k] - pos[hips], left))) for k in c]
        start = next((i for i, v in enumerate(lat) if v >= hip_lateral), None)
        if start is None or start + 2 >= len(c):
            raise TopologyError("an arm has no shoulder, elbow and wrist away from the body")
        arms.append((c[start], c[start + 1], c[start + 2]))
    arms.sort(key=lambda a: float(np.dot(pos[a[2]] - pos[hips], left)))
    r_arm, l_arm = arms
    if np.dot(pos[l_arm[0]] - pos[hips], left) <= 0 or np.dot(pos[r_arm[0]] - pos[hips], left) >= 0:
        raise TopologyError("the arms are not on either side of the body")

    head_chain = chain(chest, head_leaf)
    if not head_chain:
        raise TopologyError("no head joint above the chest")
    if np.dot(pos[head_chain[-1]] - pos[hips], u) <= 0:
        raise TopologyError("the head is not above the hips")
    if len(head_chain) >= 2:
        spine, neck, head = chest, head_chain[0], head_chain[-1]
    else:
        spine, neck, head = int(parents[chest]), chest, head_chain[0]
        if spine < 0 or spine == hips:
            raise TopologyError("no spine joint between the hips and the neck")
    out = {"hips": hips, "spine": spine, "neck": neck, "head": head}
    for side, arm, leg in (("left", l_arm, l_leg), ("right", r_arm, r_leg)):
        out.update({f"{side}_shoulder": arm[0], f"{side}_elbow": arm[1], f"{side}_hand": arm[2]})
        out.update({f"{side}_hip": leg[0], f"{side}_knee": leg[1], f"{side}_ankle": leg[2], f"{side}_toe": leg[3]})
    if len(set(out.values())) != len(out):
        raise TopologyError("two canonical joints fell on one joint (ambiguous shape)")
    return out
