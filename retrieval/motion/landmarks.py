"""BlazePose's 33 landmarks → StoryBeam's canonical joints, for a camera take.

A pose estimator (:mod:`ar.body`, MediaPipe's BlazePose models) gives per frame 33
*image* landmarks (pixels) and 33 *world* landmarks (metres, MediaPipe's convention:
origin between the hips, x image-right, y down, z away from the camera). The search
speaks of the canonical body (:data:`~retrieval.motion.CANONICAL_JOINTS`) in metres with
Y up, the way the library's clips are. :func:`landmarks_to_positions` converts:

**Coordinates.** X and Y come from the *image* landmarks, scaled to metres: X =
(u − u₀)·s(t), Y = −(v − v₀)·s(t), with u₀ the clip's median hip column, v₀ the image's
middle row (the principal point's; the median hip row when the image size is not given)
and s(t) the metres per pixel *at frame t* (:func:`scale_track`): the ratio of the world
torso length (shoulder midpoint to hip midpoint, metres) to its image length (pixels),
followed by a straight line in time (Theil–Sen) — a body walking towards or away from
the camera at a steady speed has a depth, hence a metres-per-pixel, linear in time, and
a torso leaning towards the lens for a moment (a crouch) is an outlier the fit ignores.
Measuring Y from the principal point's row at each frame's scale keeps the floor at one
height as the body comes nearer (for a level camera exactly: a floor point's Y is minus
the lens height); a camera pitched up or down still sees the floor under a travelling
body drift linearly, so heights are finally taken from the take's *floor line*
(:func:`floor_line`: the Theil–Sen line of the lowest foot joint over time, at its 2nd
percentile — a jump's flight frames are outliers to it). Until issue 27 one
metres-per-pixel (the median ratio) served the whole take and Y was measured from the
hips' median row: a body walking from 7 m to 3 m then doubled in size and its floor
slid down the image, and walks, runs and kicks towards the camera read as other classes
(lab/bench/act_cameras.py: 0.667 → 0.900 on 60 held-out trials filmed travelling
towards a camera; docs/notebook/act-it-out.md). So the root's height comes from the
image — world landmarks are hip-centred and cannot show a jump's flight — and so does
every other vertical and lateral coordinate, which a monocular estimator gets right far
more often than depth. Z is the world landmarks' depth turned towards the camera (Z =
−z): kept so that a clip can be turned to its mean heading, then dropped by the frontal
features (:mod:`retrieval.features.frontal`). The axes are StoryBeam's: Y up from the
floor, the camera on +Z, image-right = +X, so a performer facing the camera faces +Z
with their left on +X, like a canonical body in its rest pose.

**Joints** (BlazePose index in brackets): shoulders [11/12], elbows [13/14], wrists
[15/16] as the hands, hips [23/24], knees [25/26], ankles [27/28], foot index [31/32]
as the toes; the root (``hips``) from the hip midpoint, ``spine`` halfway between the
hip and shoulder midpoints, ``neck`` from the shoulder midpoint, ``head`` along the
trunk above the neck (:data:`HEAD_ABOVE_NECK`, below).

**Offsets it corrects.** CMU's skeletons (the library) put some joints where no
landmark is, and BlazePose marks some points elsewhere than CMU's joints. Each joint is
moved along the trunk direction ``up`` (hip midpoint → shoulder midpoint, per frame) by
:data:`UP_OFFSETS` leg lengths ``L`` (hip→knee→ankle, the clip's median, measured on the
landmarks before the correction). Measured on the rest poses of the 15 CMU skeletons of
the shared data: the root sits 0.107–0.122 L above the hip-joint midpoint (14 Acclaim
skeletons); Acclaim's head joint is the *start* of the head bone, at the top of the
neck, 0.11–0.19 L above the shoulder midpoint — below the ears, not above them; the neck
joint 0.04–0.10 L below the shoulder midpoint. Measured against BlazePose (the median
over 30 tuning renders of the human-proportioned figure of CMU joint − landmark joint,
relative to the hip midpoint, in leg lengths): BlazePose's hips sit 0.08 L above the hip
joints, its shoulders 0.06 L above CMU's, its foot index 0.14 L below CMU's toe joint
(the ball of the foot); the table of :data:`UP_OFFSETS` is the result (docs/notebook/act-it-out.md).

**The head from the trunk, not the ears.** Acclaim's head joint is the top of the neck,
which moves with the shoulders; where the *ears* sit above it depends on the size of the
head, and heads differ: a child's is larger for its body than an adult's, and StoryBeam's
cartoon kid larger still. The head joint used to be the ear midpoint moved down
0.225 L, which put the kid's head joint at its shoulders (0.04 L above them against
0.17 L on CMU's skeletons): hand–head distances came out 0.7–0.8 library standard
deviations short on its walks and jumps (hands read as near the head), and walks were
found as jumps and dances. The head joint is now :data:`HEAD_ABOVE_NECK` trunk lengths
(corrected hips → corrected neck) above the corrected neck, on the trunk's line: 0.52,
the median over the human-proportioned figure's takes of where the ear-based head sat
(0.524 over the 237 earlier renders of seeds 1–3, 0.522 over 93 re-rendered takes), so a
human-proportioned performer's head joint stays where it was, and a big head no longer
pulls it down. Over 93 takes per figure
(against the take's true joints, in library standard deviations): the kid's mean
|error| of the hand–head distances 0.95 → 0.69 and of hand-above-head 0.56 → 0.34, the
person's 0.41 → 0.40 and 0.20 → 0.18; class accuracy (1-NN, trial left out) person
0.871 → 0.892 against a ceiling of 0.903, kid 0.710 → 0.710 (docs/notebook/act-it-out.md).

**Sides kept consistent.** On a body it reads badly (StoryBeam's cartoon kid: a quarter
of the frames of the tuning takes) BlazePose swaps the whole body's left and right from
frame to frame — it takes the performer for one seen from behind — and the frames of a
swap collapse both sides onto the middle. Left and right landmarks are therefore swapped
back (:func:`consistent_sides`) in every frame whose image *across* direction (the
left→right shoulder plus left→right hip offsets along the image's x) points the other
way from the take's majority, and a frame whose across width is under
:data:`COLLAPSE_FRACTION` of the take's median is treated as missed. A performer who
really turns round is then seen mirrored while their back is to the camera; the
features (:mod:`retrieval.features.frontal`) are left/right pairs, so a mirror mostly
swaps features within a pair.

After the correction ``L`` is measured again and returned with the positions: the
features divide by it. Frames the estimator missed (``valid`` false) are filled by
linear interpolation of the frames around them (the first and last seen frames are held
at the ends); a take with no valid frame raises :class:`LandmarkError`.

Pure numpy: the retrieval layer never imports the camera side (:mod:`ar`).
"""
from __future__ import annotations

import numpy as np

from retrieval.errors import StoryBeamError
from retrieval.motion.body import CANONICAL_JOINTS

#: BlazePose's 33 landmarks, in the models' order: StoryBeam's one table of them (the
#: tracker in :mod:`ar.body`, the "Act it out" verdict and skeleton in :mod:`app.services`
#: and the joints below all read it).
LANDMARK_NAMES: tuple[str, ...] = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye", "right_eye_outer",
    "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder", "right_shoulder", "left_elbow",
    "right_elbow", "left_wrist", "right_wrist", "left_pinky", "right_pinky", "left_index", "right_index",
    "left_thumb", "right_thumb", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
    "left_heel", "right_heel", "left_foot_index", "right_foot_index",
)
#: Landmark name -> its index in :data:`LANDMARK_NAMES`.
LANDMARK_INDEX: dict[str, int] = {name: i for i, name in enumerate(LANDMARK_NAMES)}
#: Number of BlazePose landmarks.
N_LANDMARKS = len(LANDMARK_NAMES)
#: BlazePose landmark indices used here.
NOSE, L_EAR, R_EAR = (LANDMARK_INDEX[n] for n in ("nose", "left_ear", "right_ear"))
L_SHOULDER, R_SHOULDER, L_ELBOW, R_ELBOW, L_WRIST, R_WRIST = (LANDMARK_INDEX[n] for n in (
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist"))
L_HIP, R_HIP, L_KNEE, R_KNEE, L_ANKLE, R_ANKLE = (LANDMARK_INDEX[n] for n in (
    "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle"))
L_FOOT_INDEX, R_FOOT_INDEX = LANDMARK_INDEX["left_foot_index"], LANDMARK_INDEX["right_foot_index"]

#: Canonical joint -> the one BlazePose landmark it is (the joints built from several
#: landmarks — hips, spine, neck, head — are in :func:`landmarks_to_positions`).
DIRECT: dict[str, int] = {
    "left_shoulder": L_SHOULDER, "right_shoulder": R_SHOULDER,
    "left_elbow": L_ELBOW, "right_elbow": R_ELBOW,
    "left_hand": L_WRIST, "right_hand": R_WRIST,
    "left_hip": L_HIP, "right_hip": R_HIP,
    "left_knee": L_KNEE, "right_knee": R_KNEE,
    "left_ankle": L_ANKLE, "right_ankle": R_ANKLE,
    "left_toe": L_FOOT_INDEX, "right_toe": R_FOOT_INDEX,
}
#: Offsets along the trunk direction ``up``, in leg lengths, added to each canonical
#: joint after it is read from the landmarks: where CMU's joint sits relative to what
#: BlazePose marks (measured, see the module docstring; positive = towards the head).
UP_OFFSETS: dict[str, float] = {
    "hips": 0.126 - 0.08,  # root above the hip-joint midpoint, itself below the landmark hips
    "left_hip": -0.08, "right_hip": -0.08,  # BlazePose's hips sit above the hip joints
    "left_shoulder": -0.06, "right_shoulder": -0.06,
    "neck": -0.14,
    "left_toe": 0.14, "right_toe": 0.14,  # the ball of the foot, above the toe tip
}

#: The head joint's height above the (corrected) neck along the trunk, in trunk lengths
#: (corrected hips → corrected neck): Acclaim's head joint is the top of the neck and
#: moves with the trunk; the ears' height above it depends on the head's size (see the
#: module docstring).
HEAD_ABOVE_NECK = 0.52

#: Left/right BlazePose landmark pairs (eyes, ears, mouth, and every limb landmark), in
#: the order of the left one.
LR_PAIRS: tuple[tuple[int, int], ...] = tuple(
    (i, LANDMARK_INDEX[name.replace("left", "right")]) for i, name in enumerate(LANDMARK_NAMES) if "left" in name)
#: A frame whose image across width (|shoulder dx| + |hip dx|, pixels) is under this
#: fraction of the take's median is a side swap caught half-way: treated as missed.
COLLAPSE_FRACTION = 0.3
#: The canonical foot joints whose lowest, per frame, stands on the floor.
FOOT_JOINTS: tuple[str, ...] = ("left_ankle", "left_toe", "right_ankle", "right_toe")


class LandmarkError(StoryBeamError):
    """Landmarks cannot be turned into joint positions (bad shapes, nothing seen)."""


def _check(world: np.ndarray, image_xy: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    world = np.asarray(world, dtype=np.float64)
    image_xy = np.asarray(image_xy, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    t = valid.shape[0] if valid.ndim == 1 else -1
    if valid.ndim != 1 or world.shape != (t, N_LANDMARKS, 3) or image_xy.shape != (t, N_LANDMARKS, 2):
        raise LandmarkError(f"landmarks must be world (T, 33, 3), image (T, 33, 2) and valid (T,); got "
                            f"{world.shape}, {image_xy.shape} and {valid.shape}")
    ok = valid & np.all(np.isfinite(world), axis=(1, 2)) & np.all(np.isfinite(image_xy), axis=(1, 2))
    if not ok.any():
        raise LandmarkError(f"no frame of the take ({t} frames) has a body: nothing to search with")
    return world, image_xy, ok


def fill_gaps(values: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """(T, ...) values with the rows where ``ok`` is false replaced by linear
    interpolation between the nearest good rows (held constant before the first and
    after the last)."""
    values = np.asarray(values, dtype=np.float64)
    if ok.all():
        return values.copy()
    t = np.arange(len(values))
    flat = values.reshape(len(values), -1)
    out = np.empty_like(flat)
    for c in range(flat.shape[1]):
        out[:, c] = np.interp(t, t[ok], flat[ok, c])
    return out.reshape(values.shape)


def consistent_sides(world: np.ndarray, image_xy: np.ndarray, valid: np.ndarray,
                     collapse: float = COLLAPSE_FRACTION) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The take's landmarks with left and right the same way round in every frame, and
    the frames caught half-way through a swap marked missed (see the module docstring).

    Per valid frame the across offset is a = (u[R_SHOULDER] − u[L_SHOULDER]) + (u[R_HIP] −
    u[L_HIP]) (image x, pixels); the take's majority sign of a is kept (a tie keeps the
    sign of a body facing the camera, a < 0) and every :data:`LR_PAIRS` pair of the
    frames of the other sign is exchanged in both ``world`` and ``image_xy``. Frames
    with |shoulder dx| + |hip dx| under ``collapse`` × its median over the valid frames
    are dropped from ``valid`` (unless that would drop every frame). Returns new arrays."""
    world, image_xy, ok = _check(world, image_xy, valid)
    u = image_xy[..., 0]
    sh, hp = u[:, R_SHOULDER] - u[:, L_SHOULDER], u[:, R_HIP] - u[:, L_HIP]
    sign = np.sign(sh + hp)
    major = np.sign(np.sum(sign[ok])) or -1.0
    flip = ok & (sign == -major)
    world, image_xy = world.copy(), image_xy.copy()
    if flip.any():
        left, right = [a for a, _ in LR_PAIRS], [b for _, b in LR_PAIRS]
        for arr in (world, image_xy):
            arr[np.ix_(flip, left + right)] = arr[np.ix_(flip, right + left)]
    width = np.abs(sh) + np.abs(hp)
    if collapse > 0:
        narrow = ok & (width < collapse * np.median(width[ok]))
        if (ok & ~narrow).any():
            ok = ok & ~narrow
    return world, image_xy, ok


def metres_per_pixel(world: np.ndarray, image_xy: np.ndarray, valid: np.ndarray) -> float:
    """The clip's image scale: median over valid frames of the world torso length
    (shoulder midpoint to hip midpoint, metres) over its image length (pixels)."""
    world, image_xy, ok = _check(world, image_xy, valid)

    def torso(a: np.ndarray) -> np.ndarray:
        return np.linalg.norm((a[:, L_SHOULDER] + a[:, R_SHOULDER]) / 2 - (a[:, L_HIP] + a[:, R_HIP]) / 2, axis=1)

    tw, ti = torso(world[ok]), torso(image_xy[ok])
    good = ti > 1.0
    if not good.any():
        raise LandmarkError("the torso is under a pixel long in every frame: no image scale")
    return float(np.median(tw[good] / ti[good]))


def _leg(joints: dict[str, np.ndarray]) -> float:
    """Median over frames of both legs' mean hip→knee→ankle length."""
    legs = [np.linalg.norm(joints[f"{s}_knee"] - joints[f"{s}_hip"], axis=1)
            + np.linalg.norm(joints[f"{s}_ankle"] - joints[f"{s}_knee"], axis=1) for s in ("left", "right")]
    size = float(np.median((legs[0] + legs[1]) / 2))
    if not size > 1e-3:
        raise LandmarkError(f"the take's leg length is {size:.4f} m: the landmarks are degenerate")
    return size


def _robust_line(t: np.ndarray, y: np.ndarray, max_points: int = 120) -> tuple[float, float]:
    """Theil–Sen slope and median intercept of y over t (at most ``max_points`` evenly
    spaced samples enter the slope): robust to under 29 % of outlying frames."""
    if len(t) < 3 or np.ptp(t) <= 0:
        return 0.0, float(np.median(y)) if len(y) else 0.0
    pick = np.unique(np.linspace(0, len(t) - 1, min(len(t), max_points)).round().astype(int))
    tt, yy = t[pick], y[pick]
    i, j = np.triu_indices(len(tt), 1)
    dt = tt[j] - tt[i]
    keep = dt > 0
    slope = float(np.median((yy[j] - yy[i])[keep] / dt[keep])) if keep.any() else 0.0
    return slope, float(np.median(y - slope * t))


def scale_track(world: np.ndarray, image_xy: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(T,) metres per pixel at the body, per frame: the ratio of the world torso length
    (shoulder midpoint → hip midpoint) to its image length, followed by a straight line
    in time (:func:`_robust_line`). A body walking or running towards or away from the
    camera at a steady speed has a depth, hence a metres-per-pixel, linear in time; a
    body in place has a constant one. Frames where the torso leans towards the camera
    (a crouch, a bow) foreshorten it and read high for a moment: the robust fit ignores
    them. Never under a fifth of the median ratio."""
    world, image_xy, ok = _check(world, image_xy, valid)

    def torso(a: np.ndarray) -> np.ndarray:
        return np.linalg.norm((a[:, L_SHOULDER] + a[:, R_SHOULDER]) / 2 - (a[:, L_HIP] + a[:, R_HIP]) / 2, axis=1)

    tw, ti = torso(world), torso(image_xy)
    good = ok & (ti > 1.0)
    if not good.any():
        raise LandmarkError("the torso is under a pixel long in every frame: no image scale")
    t = np.arange(len(ok), dtype=np.float64)
    ratio = tw[good] / ti[good]
    slope, icpt = _robust_line(t[good], ratio)
    return np.maximum(icpt + slope * t, 0.2 * float(np.median(ratio)))


def floor_line(foot_y: np.ndarray, percentile: float = 2.0) -> np.ndarray:
    """(T,) floor height per frame under (T,) lowest-foot heights: a straight line in
    time whose slope is the Theil–Sen slope of the lowest foot (robust to a jump's flight
    frames) and whose level is ``percentile`` of the residuals (the features' own floor
    rule, :data:`retrieval.features.relational.FLOOR_PERCENTILE`). A camera pitched up or
    down sees the floor under a body that travels in depth move up or down the image in
    proportion to the depth, which is linear in time for a steady walk; a body in place
    gets a level floor."""
    foot_y = np.asarray(foot_y, dtype=np.float64)
    t = np.arange(len(foot_y), dtype=np.float64)
    slope, _ = _robust_line(t, foot_y)
    return slope * t + float(np.percentile(foot_y - slope * t, percentile))


def landmarks_to_positions(world: np.ndarray, image_xy: np.ndarray, valid: np.ndarray,
                           image_size: tuple[int, int] | None = None,
                           fps: float | None = None) -> tuple[np.ndarray, dict[str, int], float]:
    """(T, 18, 3) canonical joint positions (metres, Y up from the floor, the camera on
    +Z), the joint map (canonical name -> column) and the leg length (metres) of a take,
    from BlazePose world landmarks (T, 33, 3), image landmarks (T, 33, 2, pixels) and
    the per-frame ``valid`` flags (see the module docstring for the method; left and
    right are made consistent first, :func:`consistent_sides`). Pixels become metres at
    each frame's own scale (:func:`scale_track`), heights are measured from the image's
    middle row when ``image_size`` (w, h) is given (else from the hips' median row) and
    then from the take's floor line (:func:`floor_line`). ``fps`` is checked when given."""
    world, image_xy, ok = _check(world, image_xy, valid)
    if image_size is not None and not (len(image_size) == 2 and min(image_size) > 0):
        raise LandmarkError(f"image size must be (width, height) in pixels, got {image_size}")
    if fps is not None and not fps > 0:
        raise LandmarkError(f"fps must be positive, got {fps}")
    world, image_xy, ok = consistent_sides(world, image_xy, ok)
    s = scale_track(world, image_xy, ok)[:, None]
    mid_px = (image_xy[ok, L_HIP] + image_xy[ok, R_HIP]) / 2
    u0, v0 = np.median(mid_px, axis=0)
    if image_size is not None:  # the principal point's row: a level camera's floor stays put as depth changes
        v0 = (image_size[1] - 1) / 2
    lm = np.empty(world.shape)
    lm[..., 0] = (image_xy[..., 0] - u0) * s
    lm[..., 1] = -(image_xy[..., 1] - v0) * s
    lm[..., 2] = -world[..., 2]
    lm = fill_gaps(lm, ok)

    def mid(a: int, b: int) -> np.ndarray:
        return (lm[:, a] + lm[:, b]) / 2

    hips, shoulders = mid(L_HIP, R_HIP), mid(L_SHOULDER, R_SHOULDER)
    up = shoulders - hips
    up /= np.maximum(np.linalg.norm(up, axis=1, keepdims=True), 1e-9)
    joints = {name: lm[:, i] for name, i in DIRECT.items()}
    joints["hips"] = hips
    joints["spine"] = (hips + shoulders) / 2
    joints["neck"] = shoulders
    raw_leg = _leg(joints)
    joints = {n: p + UP_OFFSETS.get(n, 0.0) * raw_leg * up for n, p in joints.items()}
    joints["head"] = joints["neck"] + HEAD_ABOVE_NECK * (joints["neck"] - joints["hips"])
    floor = floor_line(np.min([joints[n][:, 1] for n in FOOT_JOINTS], axis=0))
    joints = {n: p - np.stack([np.zeros_like(floor), floor, np.zeros_like(floor)], axis=1) for n, p in joints.items()}
    leg = _leg(joints)
    names = list(CANONICAL_JOINTS)
    pos = np.stack([joints[n] for n in names], axis=1)
    return pos, {n: i for i, n in enumerate(names)}, leg


__all__ = ["LANDMARK_NAMES", "LANDMARK_INDEX", "N_LANDMARKS", "DIRECT", "UP_OFFSETS", "HEAD_ABOVE_NECK", "LR_PAIRS", "COLLAPSE_FRACTION", "LandmarkError",
           "FOOT_JOINTS",
           "consistent_sides", "fill_gaps", "floor_line", "metres_per_pixel", "scale_track", "landmarks_to_positions"]
