"""Kid-friendly characters built from rounded primitives attached to the canonical body.

A character is a canonical skeleton (:func:`retrieval.animation.retarget.canonical_skeleton`, with
its own proportions: big head, short legs) plus rigid *parts*, each a closed numpy mesh
(:mod:`ar.scene.mesh`: capsule, sphere, ellipsoid) fixed in one joint's frame. Rigid parts per bone need no
skinning, render as a handful of static meshes whose poses change per frame, and stay
readable when projected small and bright onto a table: no thin details, saturated
colours, big eyes.

Units: parts are built in metres in the joint's local frame (the skeleton's native unit
is centimetres; :data:`CM` converts). The character faces +Z with Y up in its rest pose.

Plain numpy (no trimesh, no GL), so the same characters are built on the tablet and on
the desktop; :func:`ar.render.characters.save_character` writes a rest-pose preview file.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.motion import Motion, Skeleton, global_transforms
from retrieval.animation import BodyProportions, canonical_skeleton, sole_level

from ar.scene.mesh import MeshData, capsule, concatenate, ellipsoid, sphere

CM = 0.01
#: Default standing height on the table, metres.
DEFAULT_HEIGHT_M = 0.12

Colour = tuple[int, int, int]


class CharacterError(StoryBeamError):
    """Unknown character or bad character parameters."""


@dataclass
class Part:
    """One rigid piece: ``mesh`` (metres, in the frame of joint ``joint``) and its colour."""

    name: str
    joint: str
    mesh: MeshData
    colour: Colour


@dataclass
class Character:
    """A skeleton and the parts riding on it."""

    name: str
    skeleton: Skeleton
    parts: list[Part] = field(default_factory=list)
    height_m: float = DEFAULT_HEIGHT_M

    def part_poses(self, motion: Motion, frame: int) -> list[np.ndarray]:
        """World 4x4 pose (metres, the motion's Y-up world) of every part at ``frame``."""
        return [p for p in self.all_part_poses(motion, frames=[frame])[0]]

    def all_part_poses(self, motion: Motion, frames: list[int] | None = None) -> np.ndarray:
        """(F, P, 4, 4) part poses for the given frames (all frames by default)."""
        if motion.skeleton.names != self.skeleton.names:
            raise CharacterError(
                f"motion {motion.name!r} is not on {self.name}'s skeleton; retarget it first"
            )
        sub = motion if frames is None else _frames(motion, frames)
        rot, pos = global_transforms(sub)
        idx = [self.skeleton.index(p.joint) for p in self.parts]
        out = np.zeros((sub.n_frames, len(self.parts), 4, 4))
        out[..., :3, :3] = rot[:, idx]
        out[..., :3, 3] = pos[:, idx] * self.skeleton.metres_per_unit
        out[..., 3, 3] = 1.0
        return out

    def posed_mesh(self, motion: Motion | None = None, frame: int = 0) -> MeshData:
        """All parts as one mesh, posed at ``frame`` of ``motion`` (rest pose standing on
        y = 0 when ``motion`` is None). For export, previews and tests; the renderers
        pose the parts separately instead."""
        motion = motion if motion is not None else rest_motion(self)
        poses = self.all_part_poses(motion, [frame])[0]
        return concatenate([part.mesh.transformed(pose) for part, pose in zip(self.parts, poses)])


def _frames(motion: Motion, frames: list[int]) -> Motion:
    jt = None if motion.joint_translations is None else motion.joint_translations[frames]
    return Motion(motion.skeleton, motion.rotations[frames], motion.root_translation[frames],
                  motion.fps, motion.name, jt)


def rest_motion(character: Character, n_frames: int = 1) -> Motion:
    """The character standing in its rest pose with its soles on y = 0."""
    sk = character.skeleton
    root = np.zeros((n_frames, 3))
    root[:, 1] = -sole_level(sk) / sk.metres_per_unit  # soles on y = 0
    rot = np.broadcast_to(np.eye(3), (n_frames, sk.n_joints, 3, 3)).copy()
    return Motion(sk, rot, root, 30.0, f"{character.name}-rest")


@dataclass(frozen=True)
class Palette:
    body: Colour
    limbs: Colour
    head: Colour
    hands: Colour
    feet: Colour
    accent: Colour
    eye: Colour = (255, 255, 255)
    pupil: Colour = (20, 20, 30)


@dataclass(frozen=True)
class Design:
    """What distinguishes one character: proportions, thickness, palette, extras.

    Feet keep a human foot-to-leg ratio (heel to toe tip about 0.28 leg lengths): the
    motion is a human's, and longer cartoon feet would scrape the table in mid-swing.
    Big shoes are drawn with a thicker foot part instead."""

    proportions: BodyProportions
    palette: Palette
    limb_radius: float  # fraction of height
    torso_radii: tuple[float, float, float]  # fractions of height
    head_radius: float  # fraction of height
    extras: str = ""


_DESIGNS: dict[str, Design] = {
    "robot": Design(
        BodyProportions(thigh=0.16, shin=0.15, ankle_height=0.045, foot_length=0.055, toe_length=0.03,
                        hip_half_width=0.07, pelvis_drop=0.03, lower_spine=0.12, upper_spine=0.15,
                        neck=0.08, head_top=0.20, shoulder_half_width=0.12, shoulder_drop=0.03,
                        upper_arm=0.12, forearm=0.11, hand=0.05),
        Palette(body=(30, 110, 255), limbs=(255, 140, 0), head=(255, 215, 0), hands=(255, 40, 40),
                feet=(255, 40, 40), accent=(255, 40, 40)),
        limb_radius=0.045, torso_radii=(0.13, 0.15, 0.10), head_radius=0.13, extras="antenna",
    ),
    "cat": Design(
        BodyProportions(thigh=0.15, shin=0.15, ankle_height=0.04, foot_length=0.055, toe_length=0.03,
                        hip_half_width=0.06, pelvis_drop=0.03, lower_spine=0.12, upper_spine=0.14,
                        neck=0.07, head_top=0.22, shoulder_half_width=0.09, shoulder_drop=0.03,
                        upper_arm=0.11, forearm=0.10, hand=0.05),
        Palette(body=(255, 130, 20), limbs=(255, 130, 20), head=(255, 130, 20), hands=(255, 255, 255),
                feet=(255, 255, 255), accent=(255, 110, 180), eye=(120, 255, 90)),
        limb_radius=0.04, torso_radii=(0.11, 0.15, 0.10), head_radius=0.14, extras="ears,tail,belly",
    ),
    "kid": Design(
        BodyProportions(thigh=0.17, shin=0.16, ankle_height=0.04, foot_length=0.06, toe_length=0.03,
                        hip_half_width=0.06, pelvis_drop=0.03, lower_spine=0.12, upper_spine=0.14,
                        neck=0.07, head_top=0.20, shoulder_half_width=0.10, shoulder_drop=0.03,
                        upper_arm=0.12, forearm=0.11, hand=0.05),
        Palette(body=(235, 30, 70), limbs=(255, 205, 160), head=(255, 205, 160), hands=(255, 205, 160),
                feet=(255, 220, 0), accent=(40, 70, 220)),
        limb_radius=0.035, torso_radii=(0.11, 0.14, 0.08), head_radius=0.13, extras="hair,trousers",
    ),
    # Not a story character: a human-proportioned performer (adult bone lengths, a head
    # one eighth of the height, skin-coloured limbs, shirt and trousers) for rendering
    # synthetic "Act it out" performances that a pose estimator trained on people sees.
    "person": Design(
        BodyProportions(),
        Palette(body=(60, 110, 190), limbs=(224, 172, 140), head=(224, 172, 140), hands=(224, 172, 140),
                feet=(40, 40, 45), accent=(50, 50, 70), eye=(250, 250, 250), pupil=(40, 30, 25)),
        limb_radius=0.026, torso_radii=(0.095, 0.16, 0.06), head_radius=0.062, extras="hair,trousers,nose",
    ),
}

#: The story characters a child picks from (each has its assets under assets/characters/).
CHARACTER_NAMES: tuple[str, ...] = ("robot", "cat", "kid")
#: Performers for synthetic camera tests; :func:`build_character` builds these too.
PERFORMER_NAMES: tuple[str, ...] = ("person",)


def build_character(name: str = "robot", height_m: float = DEFAULT_HEIGHT_M) -> Character:
    """Build character ``name`` (one of :data:`CHARACTER_NAMES`) standing ``height_m`` tall.

    Height runs from the soles to the top of the head (extras such as ears or an antenna
    may stick out a little above it).
    """
    if name not in _DESIGNS:
        raise CharacterError(f"unknown character {name!r}; choose one of {', '.join(CHARACTER_NAMES + PERFORMER_NAMES)}")
    if not 0.01 <= height_m <= 2.0:
        raise CharacterError(f"character height {height_m} m is outside 0.01-2 m")
    d = _DESIGNS[name]
    sk = canonical_skeleton(d.proportions, height_m, name=name)
    off = {j.name: j.offset * CM for j in sk.joints}
    h, pal = height_m, d.palette
    r = d.limb_radius * h
    parts: list[Part] = []

    def add(part: str, joint: str, mesh: MeshData, colour: Colour) -> None:
        parts.append(Part(part, joint, mesh, colour))

    o = np.zeros(3)
    # Torso: one ellipsoid spanning hips..neck, hung on the spine joint so it bends with it.
    spine_len = float(np.linalg.norm(off["neck"]))
    hips_to_spine = float(np.linalg.norm(off["spine"]))
    tx, ty, tz = (np.array(d.torso_radii) * h)
    ty = max(ty, 0.5 * (spine_len + hips_to_spine))  # reach from the belt to the shoulders
    add("torso", "spine", ellipsoid((0, 0.45 * (spine_len - hips_to_spine), 0), (tx, ty, tz)), pal.body)
    trouser = pal.accent if "trousers" in d.extras else pal.body
    add("pelvis", "hips", ellipsoid((0, -0.3 * off["spine"][1], 0), (tx * 0.9, ty * 0.45, tz * 0.9)), trouser)
    # Head: a big sphere centred a bit above the head joint, with eyes on its front (+Z).
    hr = d.head_radius * h
    hc = np.array([0.0, float(np.linalg.norm(off["head_end"])) - hr, 0.0])
    add("neck", "neck", capsule(o, off["head"], r * 1.3), pal.limbs)
    add("head", "head", sphere(hc, hr, 3), pal.head)
    for side in (-1, 1):
        eye_c = hc + np.array([side * 0.38 * hr, 0.12 * hr, 0.82 * hr])
        add(f"eye_{side}", "head", sphere(eye_c, 0.28 * hr), pal.eye)
        add(f"pupil_{side}", "head", sphere(eye_c + np.array([0, -0.02 * hr, 0.2 * hr]), 0.14 * hr), pal.pupil)
    # Limbs: capsules along each bone, hands and feet as round blobs.
    for side in ("left", "right"):
        leg_colour = pal.accent if "trousers" in d.extras else pal.limbs
        add(f"{side}_thigh", f"{side}_hip", capsule(o, off[f"{side}_knee"], r * 1.15), leg_colour)
        add(f"{side}_shin", f"{side}_knee", capsule(o, off[f"{side}_ankle"], r), leg_colour)
        toe = off[f"{side}_toe"]
        ankle_h = -float(toe[1] + off[f"{side}_toe_end"][1])  # toe end site is on the sole
        foot_r = min(r * 1.1, 0.95 * ankle_h)
        sole_axis = np.array([0.0, foot_r - ankle_h, 0.0])  # a flat foot resting on y=0
        add(f"{side}_foot", f"{side}_ankle",
            capsule(sole_axis + [0, 0, -0.15 * toe[2]], sole_axis + [0, 0, toe[2] + off[f"{side}_toe_end"][2] * 0.5], foot_r),
            pal.feet)
        add(f"{side}_upper_arm", f"{side}_shoulder", capsule(o, off[f"{side}_elbow"], r), pal.limbs)
        add(f"{side}_forearm", f"{side}_elbow", capsule(o, off[f"{side}_hand"], r * 0.9), pal.limbs)
        add(f"{side}_hand", f"{side}_hand", sphere(off[f"{side}_hand_end"] * 0.5, r * 1.35), pal.hands)
    if "antenna" in d.extras:
        top = hc + np.array([0, hr, 0])
        add("antenna", "head", capsule(top - [0, 0.2 * hr, 0], top + [0, 0.35 * hr, 0], 0.18 * hr), pal.limbs)
        add("antenna_ball", "head", sphere(top + [0, 0.45 * hr, 0], 0.2 * hr), pal.accent)
        for side in (-1, 1):  # round "ear" bolts
            add(f"bolt_{side}", "head", sphere(hc + [side * hr, 0, 0], 0.22 * hr), pal.accent)
    if "ears" in d.extras:
        for side in (-1, 1):
            c = hc + np.array([side * 0.6 * hr, 0.8 * hr, 0])
            add(f"ear_{side}", "head", ellipsoid(c, (0.3 * hr, 0.42 * hr, 0.18 * hr)), pal.head)
            add(f"ear_inner_{side}", "head", ellipsoid(c + [0, -0.02 * hr, 0.08 * hr], (0.18 * hr, 0.28 * hr, 0.13 * hr)), pal.accent)
        add("nose", "head", sphere(hc + np.array([0, -0.2 * hr, 0.98 * hr]), 0.14 * hr), pal.accent)
    elif "nose" in d.extras:
        add("nose", "head", sphere(hc + np.array([0, -0.15 * hr, 0.95 * hr]), 0.16 * hr), pal.head)
    if "tail" in d.extras:
        add("tail", "hips", capsule(np.array([0, 0, -0.8 * tz]), np.array([0, 0.25 * h, -0.25 * h]), r * 0.9), pal.body)
    if "belly" in d.extras:
        add("belly", "spine", ellipsoid((0, 0, 0.55 * tz), (0.7 * tx, 0.7 * ty, 0.5 * tz)), pal.hands)
    if "hair" in d.extras:
        add("hair", "head", ellipsoid(hc + np.array([0, 0.25 * hr, -0.12 * hr]), (1.06 * hr, 0.85 * hr, 1.0 * hr)), (60, 35, 20) if name == "person" else (240, 120, 30))  # kid: ginger: dark hair would not show in projected light
    return Character(name, sk, parts, height_m)


__all__ = ["CM", "DEFAULT_HEIGHT_M", "Colour", "CharacterError", "Part", "Character", "rest_motion",
           "Palette", "Design", "CHARACTER_NAMES", "PERFORMER_NAMES", "build_character"]
