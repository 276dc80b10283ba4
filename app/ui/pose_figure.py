"""A posable figure for search by pose: the child drags the hands, feet, head and hips of
a stick figure, and the pose becomes the library's own features.

:class:`PoseModel` (no Kivy) is the body: the canonical body's 18 joints with fixed bone
lengths of an adult-proportioned figure (metres, Y up, the figure faces +X, left side at
+Z). Its joints move only within plausible limits:

* **hands and feet** are two-bone limbs solved analytically in the body's side plane
  (law of cosines); a target out of reach is pulled onto the reachable ring (at most the
  straightened limb, at least a third of it: no limb folds through itself); knees bend
  forwards, elbows backwards, as a body's do;
* **feet** never go below the floor (the ankle stays at least its standing height above
  it) and stay where they are in the room when the hips move, unless out of reach;
* **head** tilts about the neck by at most ±40° (nod forwards or back);
* **hips** move up and down only, between a deep crouch and a jump's apex.

The pose's features are :func:`retrieval.library.pose_features` of its joints (the
figure's own proportions; the pose search's canonical body re-poses them like any other
skeleton's), with the floor at the standing height of the joints the feature set takes
its floor from (:func:`floor_height`: the library's floor is its clips' lowest such joint).

:class:`PoseFigure` draws the model side-on (the far, left limbs darker and a little
behind) with a large round handle on each draggable joint (``HANDLE_DP`` across, above the
48 dp guideline), and calls ``on_pose(model)`` when a drag ends.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from kivy.graphics import Color, Ellipse, Line
from kivy.metrics import dp
from kivy.uix.widget import Widget

from retrieval.motion import CANONICAL_JOINTS

# bone lengths and offsets (metres)
THIGH, SHIN, ANKLE_H, TOE_FWD, TOE_DROP = 0.42, 0.42, 0.08, 0.13, 0.05
HIP_DROP, HIP_HALF, SPINE, NECK, HEAD = 0.06, 0.09, 0.25, 0.25, 0.18
SHOULDER_DROP, SHOULDER_HALF, UPPER_ARM, FOREARM = 0.03, 0.18, 0.28, 0.27
LEG = THIGH + SHIN  # the body size the features divide by (hip -> knee -> ankle)
STAND_HIPS = HIP_DROP + LEG + ANKLE_H  # hips' height standing straight
FLOOR = ANKLE_H - TOE_DROP  # the toes' standing height (the drawing's ground is FLOOR - TOE_DROP)
HIPS_RANGE = (0.5, 1.45)  # deep crouch .. jump apex
HEAD_LIMIT_DEG = 40.0
MIN_REACH = 1 / 3  # of the straightened limb
HANDLES = ("head", "left_hand", "right_hand", "left_foot", "right_foot", "hips")
SIDE = {"left": 1.0, "right": -1.0}
HANDLE_DP = 60
DEPTH_SHEAR = 0.35  # screen x = x - DEPTH_SHEAR * z: the far (left) side drawn a little behind


def floor_height(feature_set: str | None = None) -> float:
    """The figure's floor for a feature set's heights (the pose search's set unless named):
    the standing height of the lowest of the set's floor joints (``FeatureSet.floor_joints``)
    -- the toes' (:data:`FLOOR`) on the file's body, the ankles' (:data:`ANKLE_H`) on the
    canonical body -- as the library's floor is its clips' lowest such joint."""
    from retrieval.library import POSE_FEATURE_SET, pose_floor_joints  # deferred: the search stack stays off the UI's start-up
    standing = {"ankle": ANKLE_H, "toe": FLOOR}
    return min(standing[j.split("_")[1]] for j in pose_floor_joints(feature_set or POSE_FEATURE_SET))


def two_bone(root: np.ndarray, target: np.ndarray, a: float, b: float, bend: float) -> tuple[np.ndarray, np.ndarray]:
    """(middle joint, reached end) of a two-bone limb from ``root`` towards ``target``
    (2-D points): the end is pulled onto the ring ``[MIN_REACH·(a+b), a+b]`` around the
    root; the middle joint is on the ``bend`` side (+1: counter-clockwise of the root→end
    line, -1: clockwise), by the law of cosines."""
    v = np.asarray(target, dtype=float) - root
    d = float(np.hypot(*v))
    direction = v / d if d > 1e-9 else np.array([0.0, -1.0])
    d = min(max(d, MIN_REACH * (a + b)), (a + b) * (1 - 1e-9))
    end = root + direction * d
    cos_a = np.clip((a * a + d * d - b * b) / (2 * a * d), -1.0, 1.0)
    ang = bend * math.acos(cos_a)
    c, s = math.cos(ang), math.sin(ang)
    mid = root + a * np.array([c * direction[0] - s * direction[1], s * direction[0] + c * direction[1]])
    return mid, end


class PoseModel:
    """The posable body (module docstring). Start: standing, arms a little apart, one foot
    a step ahead (so every handle can be touched on its own)."""

    def __init__(self) -> None:
        self.hips_y = STAND_HIPS
        self.head_deg = 0.0
        # hands relative to their shoulder; ankles in the room (x, y)
        self.hands = {"left": np.array([-0.12, -0.50]), "right": np.array([0.12, -0.50])}
        self.ankles = {"left": np.array([-0.12, ANKLE_H]), "right": np.array([0.14, ANKLE_H])}
        self._settle()

    # -- joints ---------------------------------------------------------------------
    def _hip(self, side: str) -> np.ndarray:
        return np.array([0.0, self.hips_y - HIP_DROP])

    def _shoulder(self) -> np.ndarray:
        return np.array([0.0, self.hips_y + SPINE + NECK - SHOULDER_DROP])

    def _settle(self) -> None:
        """Pull every limb back within its limits (after a drag or a hips move)."""
        for side in SIDE:
            a = self.ankles[side].copy()
            a[1] = max(a[1], ANKLE_H)
            _, end = two_bone(self._hip(side), a, THIGH, SHIN, +1)
            self.ankles[side] = end
            sh = self._shoulder()
            _, hand = two_bone(sh, sh + self.hands[side], UPPER_ARM, FOREARM, -1)
            self.hands[side] = hand - sh

    def positions(self) -> np.ndarray:
        """(18, 3) joint positions in :data:`retrieval.motion.CANONICAL_JOINTS` order."""
        p: dict[str, tuple[float, float, float]] = {}
        hy = self.hips_y
        p["hips"] = (0.0, hy, 0.0)
        p["spine"] = (0.0, hy + SPINE, 0.0)
        neck = np.array([0.0, hy + SPINE + NECK])
        p["neck"] = (neck[0], neck[1], 0.0)
        h = math.radians(self.head_deg)
        p["head"] = (neck[0] + HEAD * math.sin(h), neck[1] + HEAD * math.cos(h), 0.0)
        for side, sz in SIDE.items():
            sh = self._shoulder()
            elbow, hand = two_bone(sh, sh + self.hands[side], UPPER_ARM, FOREARM, -1)
            p[f"{side}_shoulder"] = (sh[0], sh[1], sz * SHOULDER_HALF)
            p[f"{side}_elbow"] = (elbow[0], elbow[1], sz * SHOULDER_HALF)
            p[f"{side}_hand"] = (hand[0], hand[1], sz * SHOULDER_HALF)
            hip = self._hip(side)
            knee, ankle = two_bone(hip, self.ankles[side], THIGH, SHIN, +1)
            p[f"{side}_hip"] = (hip[0], hip[1], sz * HIP_HALF)
            p[f"{side}_knee"] = (knee[0], knee[1], sz * HIP_HALF)
            p[f"{side}_ankle"] = (ankle[0], ankle[1], sz * HIP_HALF)
            p[f"{side}_toe"] = (ankle[0] + TOE_FWD, ankle[1] - TOE_DROP, sz * HIP_HALF)
        return np.array([p[name] for name in CANONICAL_JOINTS], dtype=float)

    def handle_point(self, handle: str) -> np.ndarray:
        """A handle's joint (x, y, z)."""
        joint = {"left_foot": "left_ankle", "right_foot": "right_ankle"}.get(handle, handle)
        return self.positions()[CANONICAL_JOINTS.index(joint)]

    def drag(self, handle: str, x: float, y: float) -> None:
        """Move ``handle`` towards the room point (x, y) (its depth is the body's), within
        the limits."""
        if handle == "hips":
            self.hips_y = float(np.clip(y, *HIPS_RANGE))
        elif handle == "head":
            neck = (0.0, self.hips_y + SPINE + NECK)
            ang = math.degrees(math.atan2(x - neck[0], max(y - neck[1], 1e-9)))
            self.head_deg = float(np.clip(ang, -HEAD_LIMIT_DEG, HEAD_LIMIT_DEG))
        elif handle in ("left_hand", "right_hand"):
            self.hands[handle.split("_")[0]] = np.array([x, y]) - self._shoulder()
        elif handle in ("left_foot", "right_foot"):
            self.ankles[handle.split("_")[0]] = np.array([x, y], dtype=float)
        else:
            raise ValueError(f"no handle {handle!r} (handles: {', '.join(HANDLES)})")
        self._settle()

    def features(self, feature_set: str | None = None) -> np.ndarray:
        """The pose as the library's per-frame features (the pose search's set unless named)."""
        from retrieval.library import POSE_FEATURE_SET, pose_features  # deferred: the search stack stays off the UI's start-up
        name = feature_set or POSE_FEATURE_SET
        return pose_features(self.positions(), {n: i for i, n in enumerate(CANONICAL_JOINTS)}, LEG,
                             floor_height(name), name)


_BONES = tuple((CANONICAL_JOINTS.index(a), CANONICAL_JOINTS.index(b)) for a, b in (
    ("hips", "spine"), ("spine", "neck"), ("neck", "head"),
    ("neck", "left_shoulder"), ("left_shoulder", "left_elbow"), ("left_elbow", "left_hand"),
    ("neck", "right_shoulder"), ("right_shoulder", "right_elbow"), ("right_elbow", "right_hand"),
    ("hips", "left_hip"), ("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("left_ankle", "left_toe"),
    ("hips", "right_hip"), ("right_hip", "right_knee"), ("right_knee", "right_ankle"),
    ("right_ankle", "right_toe")))
_HANDLE_COLOURS = {"head": (0.95, 0.75, 0.2), "left_hand": (0.3, 0.5, 0.95), "right_hand": (0.45, 0.75, 1.0),
                   "left_foot": (0.85, 0.35, 0.35), "right_foot": (1.0, 0.55, 0.5), "hips": (0.5, 0.8, 0.45)}
_VIEW_TOP = 2.05  # metres of the room shown above the floor


class PoseFigure(Widget):
    """The posable figure (module docstring): drag a handle, ``on_pose(model)`` on release."""

    def __init__(self, on_pose: Callable[[PoseModel], object] | None = None, **kwargs):
        super().__init__(**kwargs)
        self.model = PoseModel()
        self.on_pose = on_pose
        self.grabbed: str | None = None
        self.bind(pos=self.redraw, size=self.redraw)

    # -- room <-> widget pixels ---------------------------------------------------------
    @property
    def scale(self) -> float:
        return min(self.height / (_VIEW_TOP + 0.1), self.width / 2.0)

    def to_px(self, x: float, y: float, z: float = 0.0) -> tuple[float, float]:
        s = self.scale
        return self.center_x + (x - DEPTH_SHEAR * z) * s, self.y + 0.05 * s + (y - FLOOR + TOE_DROP) * s

    def to_room(self, px: float, py: float, z: float = 0.0) -> tuple[float, float]:
        s = self.scale
        return (px - self.center_x) / s + DEPTH_SHEAR * z, (py - self.y - 0.05 * s) / s + FLOOR - TOE_DROP

    def handle_px(self, handle: str) -> tuple[float, float]:
        """Where a handle is drawn, in widget coordinates."""
        return self.to_px(*self.model.handle_point(handle))

    # -- touch ------------------------------------------------------------------------
    def on_touch_down(self, touch):
        if not self.collide_point(*touch.pos):
            return super().on_touch_down(touch)
        best, best_d = None, dp(HANDLE_DP) * 0.75
        for h in HANDLES:
            hx, hy = self.handle_px(h)
            d = math.hypot(touch.x - hx, touch.y - hy)
            if d < best_d:
                best, best_d = h, d
        if best is None:
            return super().on_touch_down(touch)
        self.grabbed = best
        touch.grab(self)
        return True

    def on_touch_move(self, touch):
        if touch.grab_current is not self or self.grabbed is None:
            return super().on_touch_move(touch)
        z = self.model.handle_point(self.grabbed)[2]
        self.model.drag(self.grabbed, *self.to_room(touch.x, touch.y, z))
        self.redraw()
        return True

    def on_touch_up(self, touch):
        if touch.grab_current is not self:
            return super().on_touch_up(touch)
        touch.ungrab(self)
        if self.grabbed is not None:
            z = self.model.handle_point(self.grabbed)[2]
            self.model.drag(self.grabbed, *self.to_room(touch.x, touch.y, z))
            self.grabbed = None
            self.redraw()
            if self.on_pose is not None:
                self.on_pose(self.model)
        return True

    # -- drawing ------------------------------------------------------------------------
    def redraw(self, *_: object) -> None:
        self.canvas.clear()
        pos = self.model.positions()
        px = [self.to_px(*p) for p in pos]
        s = self.scale
        with self.canvas:
            Color(0.55, 0.45, 0.35, 1)
            fx0, fy = self.to_px(-0.75, FLOOR - TOE_DROP)
            Line(points=[fx0, fy, fx0 + 1.5 * s, fy], width=dp(2))
            for far in (True, False):  # the far (left) limbs first, darker
                for a, b in _BONES:
                    if (pos[b, 2] > 1e-9) != far:
                        continue
                    Color(*((0.35, 0.35, 0.45) if far else (0.12, 0.12, 0.18)), 1)
                    Line(points=[*px[a], *px[b]], width=max(dp(2.5), s * 0.03), cap="round")
            r = 0.11 * s
            hx, hy = px[CANONICAL_JOINTS.index("head")]
            Color(0.12, 0.12, 0.18, 1)
            Ellipse(pos=(hx - r, hy - r), size=(2 * r, 2 * r))
            hr = dp(HANDLE_DP) / 2
            for h in HANDLES:
                x, y = self.handle_px(h)
                Color(*_HANDLE_COLOURS[h], 0.85 if h == self.grabbed else 0.55)
                Ellipse(pos=(x - hr, y - hr), size=(2 * hr, 2 * hr))
