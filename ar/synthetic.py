"""Synthetic camera test bench: exact renders of the board on a table, with known truth.

Why exact warps instead of a 3-D renderer: the board and the table are one plane, so
every camera pixel maps to one plane point through a ray-plane intersection. We
precompute each (supersampled) pixel's undistorted ray once per camera
(``cv2.undistortPoints`` with a tight iteration criterion), then per frame intersect the rays with the plane, look up
the sheet/table textures with ``cv2.remap`` and area-average down to the output size.
Lens distortion is therefore applied exactly (by remapping), edges are anti-aliased,
and a frame costs tens of milliseconds on a CPU -- no GPU, no rasteriser error.

Projector light is cast the same way: each plane point is projected into the projector
(pinhole ``K_p``, pose ``T_proj_from_board``) and the projector image is sampled there,
so the camera sees ``albedo * (ambient + gain * projector_rgb)``.

Degradations (noise, blur, low light, a lighting gradient, a hand-like occluding blob)
are applied after the geometric render. :func:`handheld_trajectory` produces a smooth
wander plus physiological tremor, like a rig held over a table.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ar.boards import Board
from ar.calibration import CameraCalibration, ProjectorCalibration, place_pattern, rig_pose_for_step
from ar.geometry import invert, look_at, make_transform, project_points, scale_intrinsics


@dataclass
class PinholeModel:
    """Intrinsics of a camera or projector (OpenCV convention, pixel centres at integers)."""

    K: np.ndarray
    dist: np.ndarray
    width: int
    height: int

    @property
    def size(self) -> tuple[int, int]:
        return (self.width, self.height)

    def scaled(self, width: int, height: int) -> "PinholeModel":
        """The same lens at another resolution (intrinsics scaled about pixel corners; distortion unchanged)."""
        K = scale_intrinsics(self.K, width / self.width, height / self.height)
        return PinholeModel(K, self.dist.copy(), int(width), int(height))


def default_camera() -> PinholeModel:
    """The bench camera: 800x600, about 60 degrees horizontal field of view, mild barrel distortion."""
    K = np.array([[700.0, 0.0, 402.3], [0.0, 700.0, 297.8], [0.0, 0.0, 1.0]])
    return PinholeModel(K, np.array([-0.08, 0.02, 0.0005, -0.0003, 0.0]), 800, 600)


def default_projector() -> PinholeModel:
    """The bench projector: 1024x768, throw ratio about 1.3, no distortion."""
    K = np.array([[1300.0, 0.0, 511.5], [0.0, 1300.0, 383.5], [0.0, 0.0, 1.0]])
    return PinholeModel(K, np.zeros(5), 1024, 768)


def default_proj_from_cam() -> np.ndarray:
    """The bench rig: projector 6 cm right of and 1 cm below the camera, toed in to meet at 0.6 m."""
    return look_at(np.array([0.06, 0.01, 0.0]), np.array([0.0, 0.0, 0.6]), np.array([0.0, -1.0, 0.0]))


@dataclass
class Degradation:
    """Image degradations applied after the geometric render."""

    noise_sigma: float = 1.0  # Gaussian read noise, grey levels
    blur_sigma: float = 0.0  # Gaussian blur, pixels (defocus / motion)
    exposure: float = 1.0  # overall light level (low light: 0.15-0.25)
    gradient: float = 0.0  # fraction of left-to-right lighting fall-off
    occlusion: float = 0.0  # fraction of the board's image area covered by a hand-like blob
    shot_noise: float = 0.0  # Poisson-like noise scale (grows in low light)


def _smooth_noise(shape: tuple[int, int], scale: int, rng: np.random.Generator) -> np.ndarray:
    small = rng.random((max(2, shape[0] // scale), max(2, shape[1] // scale))).astype(np.float32)
    return cv2.resize(small, (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)


def make_table_texture(size_m: float = 2.4, px_per_m: float = 800.0, seed: int = 7) -> tuple[np.ndarray, float]:
    """A wood-like table top (BGR float32 albedo in 0..1), centred on the board frame origin region."""
    rng = np.random.default_rng(seed)
    n = int(size_m * px_per_m)
    ys, xs = np.mgrid[0:n, 0:n].astype(np.float32)
    warp = _smooth_noise((n, n), 200, rng) * 40.0
    grain = 0.5 + 0.5 * np.sin((ys + warp) / 9.0 + 3.0 * _smooth_noise((n, n), 60, rng))
    fine = _smooth_noise((n, n), 4, rng)
    base = 0.35 + 0.12 * grain + 0.05 * fine
    tex = np.stack([base * 0.55, base * 0.8, base * 1.1], -1)  # BGR, warm brown
    return np.clip(tex, 0, 1).astype(np.float32), px_per_m


class SyntheticCamera:
    """Renders what the rig's camera sees for a given board pose (and projector image)."""

    def __init__(self, board: Board, camera: PinholeModel | None = None, supersample: int = 2,
                 projector: PinholeModel | None = None, proj_from_cam: np.ndarray | None = None,
                 board_px_per_m: float = 4000.0, ambient: float = 0.6, projector_gain: float = 0.45):
        self.board = board
        self.camera = camera or default_camera()
        self.projector = projector or default_projector()
        self.proj_from_cam = default_proj_from_cam() if proj_from_cam is None else proj_from_cam
        self.ss = int(supersample)
        self.ambient = ambient
        self.projector_gain = projector_gain
        sheet, self.sheet_ppm = board.texture(board_px_per_m)
        self.sheet_margin_m = board.texture_origin_m(self.sheet_ppm)
        self.sheet = (0.04 + 0.88 * sheet.astype(np.float32) / 255.0)  # ink and paper albedo
        self.table, self.table_ppm = make_table_texture()
        # table texture centred on the board centre
        self.table_origin = board.centre[:2] - self.table.shape[0] / self.table_ppm / 2
        w, h = self.camera.width * self.ss, self.camera.height * self.ss
        us, vs = np.meshgrid((np.arange(w) + 0.5) / self.ss - 0.5, (np.arange(h) + 0.5) / self.ss - 0.5)
        pix = np.stack([us, vs], -1).reshape(-1, 1, 2).astype(np.float64)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-10)
        norm = cv2.undistortPoints(pix, self.camera.K, self.camera.dist, None, None, None, crit).reshape(h, w, 2)
        self._rays = norm.astype(np.float32)

    # ------------------------------------------------------------------ geometry
    def plane_points(self, T_cam_from_board: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Board-plane (x, y) of every supersampled pixel's ray, and a mask of valid hits."""
        T = invert(T_cam_from_board)
        R = T[:3, :3].astype(np.float32)
        o = T[:3, 3].astype(np.float32)
        xn, yn = self._rays[..., 0], self._rays[..., 1]
        dx = R[0, 0] * xn + R[0, 1] * yn + R[0, 2]
        dy = R[1, 0] * xn + R[1, 1] * yn + R[1, 2]
        dz = R[2, 0] * xn + R[2, 1] * yn + R[2, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -o[2] / dz
        valid = s > 0
        px = o[0] + s * dx
        py = o[1] + s * dy
        return px, py, valid

    @property
    def rays(self) -> np.ndarray:
        """Undistorted normalised ray ``(x, y)`` of every supersampled pixel, (H*ss, W*ss, 2) float32."""
        return self._rays

    def albedo(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Albedo (BGR float32 in 0..1) of the table plane at board-frame ``(px, py)``: the
        printed sheet where it lies, the wood texture elsewhere."""
        m = self.sheet_margin_m
        su = ((px + m) * self.sheet_ppm - 0.5).astype(np.float32)
        sv = ((py + m) * self.sheet_ppm - 0.5).astype(np.float32)
        sheet = cv2.remap(self.sheet, su, sv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
        tu = ((px - self.table_origin[0]) * self.table_ppm - 0.5).astype(np.float32)
        tv = ((py - self.table_origin[1]) * self.table_ppm - 0.5).astype(np.float32)
        table = cv2.remap(self.table, tu, tv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        on_sheet = sheet >= 0
        return np.where(on_sheet[..., None], np.repeat(sheet[..., None], 3, -1), table)

    def ambient_light(self, shape: tuple[int, ...], deg: Degradation) -> np.ndarray:
        """Room light on each supersampled pixel, (H, W, 1), with the degradation's fall-off."""
        light = np.full(shape[:2], self.ambient, np.float32)
        if deg.gradient:
            light *= np.linspace(1.0, 1.0 - deg.gradient, shape[1], dtype=np.float32)[None, :]
        return light[..., None]

    def render(self, T_cam_from_board: np.ndarray, projector_image: np.ndarray | None = None,
               degradation: Degradation | None = None, rng: np.random.Generator | None = None) -> np.ndarray:
        """BGR uint8 camera frame of the table, board and (optional) projector light.

        ``projector_image``: what the projector shows, RGB uint8 (H, W, 3) or grey (H, W).
        """
        deg = degradation or Degradation()
        px, py, valid = self.plane_points(T_cam_from_board)
        albedo = self.albedo(px, py)
        light = self.ambient_light(px.shape, deg)
        if projector_image is not None:
            light = light + self.projector_gain * self.projector_light(T_cam_from_board, px, py, projector_image)
        img = albedo * light * deg.exposure
        img[~valid] = 0
        return self.finish(img, T_cam_from_board, deg, rng)

    def finish(self, img: np.ndarray, T_cam_from_board: np.ndarray, deg: Degradation,
               rng: np.random.Generator | None = None) -> np.ndarray:
        """Supersampled linear radiance (0..1) -> the camera's uint8 frame: area-average to
        the output size, then the degradation's hand, blur and noise."""
        rng = rng or np.random.default_rng(0)
        img = cv2.resize(img, self.camera.size, interpolation=cv2.INTER_AREA) if self.ss > 1 else img
        img = img * 255.0
        if deg.occlusion > 0:
            img = self._occlude(img, T_cam_from_board, deg.occlusion, rng, deg.exposure)
        if deg.blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), deg.blur_sigma)
        if deg.shot_noise > 0:
            img = img + rng.normal(0, 1, img.shape).astype(np.float32) * np.sqrt(np.maximum(img, 0) * deg.shot_noise)
        if deg.noise_sigma > 0:
            img = img + rng.normal(0, deg.noise_sigma, img.shape).astype(np.float32)
        return np.clip(img + 0.5, 0, 255).astype(np.uint8)

    def projector_light(self, T_cam_from_board: np.ndarray, px: np.ndarray, py: np.ndarray,
                        projector_image: np.ndarray, pz: np.ndarray | None = None) -> np.ndarray:
        """Projector radiance arriving at board-frame points ``(px, py, pz)`` (``pz`` = 0, the
        table, when not given): (H, W, 3) in 0..1 for an RGB image, (H, W, 1) for a grey one."""
        T = self.proj_from_cam @ T_cam_from_board  # T_proj_from_board
        R, t = T[:3, :3].astype(np.float32), T[:3, 3].astype(np.float32)
        X = R[0, 0] * px + R[0, 1] * py + t[0]
        Y = R[1, 0] * px + R[1, 1] * py + t[1]
        Z = R[2, 0] * px + R[2, 1] * py + t[2]
        if pz is not None:
            X, Y, Z = X + R[0, 2] * pz, Y + R[1, 2] * pz, Z + R[2, 2] * pz
        K = self.projector.K
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (K[0, 0] * X / Z + K[0, 2]).astype(np.float32)
            v = (K[1, 1] * Y / Z + K[1, 2]).astype(np.float32)
        u[~(Z > 0)] = -10
        pimg = projector_image.astype(np.float32) / 255.0
        if pimg.ndim == 3:
            pimg = np.ascontiguousarray(pimg[..., ::-1])  # projector images are RGB (as rendered); frames are BGR
        out = cv2.remap(pimg, u, v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return out if out.ndim == 3 else out[..., None]

    def _occlude(self, img: np.ndarray, T_cam_from_board: np.ndarray, fraction: float,
                 rng: np.random.Generator, exposure: float) -> np.ndarray:
        """Cover about ``fraction`` of the board's image area with a hand-like blob (palm + fingers)."""
        w, h = self.board.pattern_size_m
        quad = project_points(np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]]), T_cam_from_board,
                              self.camera.K, self.camera.dist).astype(np.float32)
        board_mask = np.zeros(img.shape[:2], np.uint8)
        cv2.fillConvexPoly(board_mask, np.round(quad).astype(np.int32), 1)
        board_area = max(1, int(board_mask.sum()))
        # enter from a random side of the board, palm centred near that edge
        edge = int(rng.integers(4))
        a, b = quad[edge], quad[(edge + 1) % 4]
        centre_q = quad.mean(0)
        along = rng.uniform(0.3, 0.7)
        anchor = a + along * (b - a)
        inward = centre_q - anchor
        inward /= np.linalg.norm(inward) + 1e-9
        angle = np.degrees(np.arctan2(inward[1], inward[0]))
        scale = np.sqrt(fraction * board_area / 2.2)
        for _ in range(3):  # adjust the scale until the covered fraction is close
            mask = np.zeros_like(board_mask)
            palm = anchor + inward * scale * 0.6
            cv2.ellipse(mask, (int(palm[0]), int(palm[1])), (int(scale * 0.75), int(scale * 0.6)), angle, 0, 360, 1, -1)
            for k, off in enumerate((-0.45, -0.15, 0.15, 0.45)):
                side = np.array([-inward[1], inward[0]])
                base = palm + inward * scale * 0.5 + side * scale * off
                tip = base + inward * scale * (0.7 + 0.15 * (k in (1, 2)))
                cv2.line(mask, (int(base[0]), int(base[1])), (int(tip[0]), int(tip[1])), 1, max(2, int(scale * 0.22)))
            wrist = anchor - inward * scale * 2.0
            cv2.line(mask, (int(palm[0]), int(palm[1])), (int(wrist[0]), int(wrist[1])), 1, int(scale * 1.1))
            covered = (mask & board_mask).sum() / board_area
            if covered <= 0:
                break
            scale *= float(np.sqrt(fraction / covered))
        mask_f = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), 1.0)[..., None]
        skin = np.array([120.0, 150.0, 200.0], np.float32) * exposure * (0.9 + 0.2 * _smooth_noise(img.shape[:2], 40, rng))[..., None]
        return img * (1 - mask_f) + skin * mask_f


# ---------------------------------------------------------------------- trajectories
@dataclass
class TrajectoryConfig:
    """A handheld path: where the rig hovers and how much it wanders and trembles."""

    distance_m: float = 0.5
    tilt_deg: float = 25.0  # angle between the view direction and the table normal
    fps: float = 30.0
    wander_deg: float = 3.0  # slow angular wander amplitude
    wander_m: float = 0.015  # slow positional wander amplitude
    tremor_deg: float = 0.06  # 8-12 Hz physiological tremor, rotation
    tremor_m: float = 0.0004  # tremor, translation
    seed: int = 0


def _wander(t: np.ndarray, rng: np.random.Generator, freqs: tuple[float, float]) -> np.ndarray:
    """Sum of three sinusoids with random frequencies and phases, unit amplitude."""
    out = np.zeros_like(t)
    for _ in range(3):
        f = rng.uniform(*freqs)
        out += np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    return out / 3.0


def handheld_trajectory(board: Board, n_frames: int, cfg: TrajectoryConfig | None = None) -> list[np.ndarray]:
    """``T_cam_from_board`` for ``n_frames`` of a rig held over the board.

    The camera sits on the board's +x side at ``tilt_deg`` from vertical, looking at the
    board centre with the board's -x direction up in the image (so the long side of a
    portrait board runs along the image's long side). Slow wander (0.05-0.4 Hz) moves
    the view point and aim; tremor (8-12 Hz) adds small fast shakes.
    """
    cfg = cfg or TrajectoryConfig()
    rng = np.random.default_rng(cfg.seed)
    t = np.arange(n_frames) / cfg.fps
    c = board.centre
    slow = {k: _wander(t, rng, (0.05, 0.4)) for k in ("tilt", "az", "dist", "ax", "ay", "roll")}
    fast = {k: _wander(t, rng, (8.0, 12.0)) for k in ("rx", "ry", "rz", "tx", "ty", "tz")}
    poses = []
    for i in range(n_frames):
        tilt = np.radians(cfg.tilt_deg + cfg.wander_deg * slow["tilt"][i])
        az = np.radians(3 * cfg.wander_deg * slow["az"][i])
        d = cfg.distance_m * (1 + 0.03 * slow["dist"][i])
        eye = c + d * np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), -np.cos(tilt)])
        target = c + np.array([cfg.wander_m * slow["ax"][i], cfg.wander_m * slow["ay"][i], 0.0])
        T = look_at(eye, target, np.array([-1.0, 0.0, 0.0]))
        roll = np.radians(cfg.wander_deg * slow["roll"][i])
        shake = np.radians(cfg.tremor_deg) * np.array([fast["rx"][i], fast["ry"][i], fast["rz"][i]])
        R_extra, _ = cv2.Rodrigues(shake + np.array([0, 0, roll]))
        dt = cfg.tremor_m * np.array([fast["tx"][i], fast["ty"][i], fast["tz"][i]])
        poses.append(make_transform(R_extra, dt) @ T)
    return poses


# ---------------------------------------------------------------------- calibration captures
def calibration_poses(board: Board, n_views: int = 12, seed: int = 1, distance_m: float = 0.45) -> list[np.ndarray]:
    """Varied board views for camera calibration (tilts 15-45 degrees all around, board off-centre).

    Varied tilt directions and image positions are what make focal length, principal
    point and distortion separable; a fronto-parallel-only set would not.
    """
    rng = np.random.default_rng(seed)
    c = board.centre
    poses = []
    for i in range(n_views):
        az = 2 * np.pi * i / n_views + rng.uniform(-0.3, 0.3)
        tilt = np.radians(rng.uniform(15, 45))
        d = distance_m * rng.uniform(0.85, 1.15)
        eye = c + d * np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), -np.cos(tilt)])
        target = c + np.array([rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), 0.0])
        up = np.array([-1.0, 0.0, 0.0]) if i % 2 == 0 else np.array([0.0, -1.0, 0.0])
        poses.append(look_at(eye, target, up))
    return poses


def capture_projector_sequence(cam: SyntheticCamera, sequence, degradation: Degradation | None = None,
                               seed: int = 0, inner: tuple[int, int] = (9, 6)):
    """Drive a :class:`ar.calibration.ProjectorCalibrationSequence` on the synthetic rig.

    Returns ``(step, T_cam_from_board_true, pattern, {"dark", "white", "pattern": frame})``
    per step. The pattern is placed with the true projector model (placement only; the
    calibration never sees it).
    """
    rng = np.random.default_rng(seed)
    out = []
    for step in sequence:
        T = rig_pose_for_step(step)
        pattern = place_pattern(step, T, cam.proj_from_cam, cam.projector.K, cam.projector.size, inner)
        frames = {name: cam.render(T, getattr(pattern, name), degradation, rng) for name in step.shows}
        out.append((step, T, pattern, frames))
    return out


# ---------------------------------------------------------------------- recorded rig sessions
@dataclass
class SessionConfig:
    """A recorded handheld rig session: how the hand moves and what the camera suffers.

    ``shutter`` is the exposure time as a fraction of the frame time (motion blur length);
    the exposure (``exposure_level`` times 1) follows a slow drift of ``exposure_drift`` plus an auto-exposure dip to
    ``exposure_dip`` a third of the way in (recovering over ``dip_frames``); a hand enters
    over the board at ``hand_at`` (fraction of the session), covers up to ``hand_cover`` of
    it, and leaves after ``hand_frames``.
    """

    fps: float = 30.0
    distance_m: float = 0.5
    wander_deg: float = 6.0  # twice the bench's: a child's hand, not a steady one
    wander_m: float = 0.03
    tremor_deg: float = 0.1
    tremor_m: float = 0.0006
    shutter: float = 0.5
    noise_sigma: float = 2.5
    shot_noise: float = 0.3
    exposure_level: float = 1.0  # the room's light (0.15-0.3: a dim classroom corner)
    exposure_drift: float = 0.15
    exposure_dip: float = 0.45
    dip_frames: int = 15
    hand_at: float = 0.6
    hand_frames: int = 30
    hand_cover: float = 0.3
    swing_at: float = 0.15  # a quick look aside and back (fraction of the session) ...
    swing_deg: float = 5.0  # ... this far ...
    swing_frames: int = 20  # ... over this many frames (the blur of a fast move)
    supersample: int = 2
    seed: int = 0


@dataclass
class RigSession:
    """Frames (BGR uint8) of a handheld session and, for each, the true ``T_cam_from_board``
    and what was done to it (``exposure``, ``blur_px`` = motion-blur length, ``hand`` = covered fraction)."""

    frames: list
    poses: list
    fps: float
    camera: PinholeModel
    exposure: np.ndarray
    blur_px: np.ndarray
    hand: np.ndarray

    def write(self, folder, video: str | None = None) -> dict:
        """Write ``frame_00000.png`` ... and ``truth.npz`` (poses, fps, K, dist, exposure, blur_px,
        hand) into ``folder``; with ``video`` (a file name, beside the folder) also that video
        (mp4v codec, lossy). ``camera.json`` and ``projector.json`` (the true rig of
        :func:`default_projector` and :func:`default_proj_from_cam` at the camera's size, the
        files calibration writes) go into the folder and beside the video, so the recording
        is a complete rig for ``storybeam app --camera``. Returns the paths written
        (``{"folder", "truth", "video"}``)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        for i, frame in enumerate(self.frames):
            cv2.imwrite(str(folder / f"frame_{i:05d}.png"), frame)
        proj = default_projector().scaled(*self.camera.size)
        R, t = default_proj_from_cam()[:3, :3], default_proj_from_cam()[:3, 3]
        calibration = (CameraCalibration(self.camera.K, self.camera.dist, self.camera.size, 0.0, board="synthetic"),
                       ProjectorCalibration(proj.K, proj.dist, proj.size, R, t, 0.0))
        truth = folder / "truth.npz"
        np.savez(truth, poses=np.asarray(self.poses), fps=self.fps, K=self.camera.K, dist=self.camera.dist,
                 size=np.asarray(self.camera.size), exposure=self.exposure, blur_px=self.blur_px, hand=self.hand)
        out = {"folder": folder, "truth": truth, "video": None}
        calibration[0].save(folder / "camera.json")
        calibration[1].save(folder / "projector.json")
        if video:
            path = folder.parent / video if not Path(video).is_absolute() else Path(video)
            calibration[0].save(path.parent / "camera.json")
            calibration[1].save(path.parent / "projector.json")
            writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), self.fps, self.camera.size)
            try:
                for frame in self.frames:
                    writer.write(frame)
            finally:
                writer.release()
            out["video"] = path
        return out


def load_session_truth(path) -> dict:
    """The ``truth.npz`` a :meth:`RigSession.write` left (a folder or the file itself)."""
    path = Path(path)
    with np.load(path / "truth.npz" if path.is_dir() else path) as data:
        return {k: data[k] for k in data.files}


def _motion_blur(img: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """Average of the image shifted along the segment (-d/2 .. d/2): a straight-line motion blur."""
    length = float(np.hypot(dx, dy))
    if length < 0.5:
        return img
    n = int(np.ceil(length)) | 1
    size = n + 2
    kernel = np.zeros((size, size), np.float32)
    c = size // 2
    for s in np.linspace(-0.5, 0.5, 4 * n):
        x, y = c + s * dx / length * n, c + s * dy / length * n
        x0, y0 = int(np.floor(x)), int(np.floor(y))
        fx, fy = x - x0, y - y0
        for xx, yy, wgt in ((x0, y0, (1 - fx) * (1 - fy)), (x0 + 1, y0, fx * (1 - fy)),
                            (x0, y0 + 1, (1 - fx) * fy), (x0 + 1, y0 + 1, fx * fy)):
            if 0 <= xx < size and 0 <= yy < size:
                kernel[yy, xx] += wgt
    kernel /= kernel.sum()
    return cv2.filter2D(img, -1, kernel, borderType=cv2.BORDER_REPLICATE)


def record_rig_session(board: Board, n_frames: int = 150, camera: PinholeModel | None = None,
                       cfg: SessionConfig | None = None) -> RigSession:
    """Film a handheld rig session with the synthetic camera, keeping the true poses.

    Method: a :func:`handheld_trajectory` with twice the bench's wander and one quick
    turn aside and back (``swing_deg``, up to about 4 px of blur); each frame is
    rendered exactly (no degradation), then, in the order a camera applies them:
    the hand (a skin-coloured blob entering from one side of the board, its covered
    fraction ramping 0 -> ``hand_cover`` -> 0), the exposure (drift and dip), a
    straight-line motion blur whose length and direction are the image motion of the
    board centre during the shutter time, and shot + read noise.
    """
    cfg = cfg or SessionConfig()
    camera = camera or default_camera().scaled(640, 480)
    cam = SyntheticCamera(board, camera=camera, supersample=cfg.supersample)
    traj = TrajectoryConfig(distance_m=cfg.distance_m, fps=cfg.fps, wander_deg=cfg.wander_deg, wander_m=cfg.wander_m,
                            tremor_deg=cfg.tremor_deg, tremor_m=cfg.tremor_m, seed=cfg.seed)
    poses = handheld_trajectory(board, n_frames + 1, traj)  # one extra: the motion into frame 0
    s0 = int(cfg.swing_at * n_frames)
    for i in range(s0, min(n_frames + 1, s0 + cfg.swing_frames)):  # turn about the camera's own y axis
        angle = np.radians(cfg.swing_deg) * np.sin(np.pi * (i - s0) / cfg.swing_frames) ** 2
        poses[i] = make_transform(cv2.Rodrigues(np.array([0.0, angle, 0.0]))[0], np.zeros(3)) @ poses[i]
    rng = np.random.default_rng(cfg.seed + 1)
    t = np.arange(n_frames) / cfg.fps
    exposure = cfg.exposure_level * (1.0 + cfg.exposure_drift * np.sin(2 * np.pi * 0.15 * t + rng.uniform(0, 2 * np.pi)))
    dip_at = n_frames // 3
    k = np.arange(n_frames) - dip_at
    exposure = exposure * np.where(k >= 0, 1.0 - (1.0 - cfg.exposure_dip) * np.exp(-np.maximum(k, 0) / max(1, cfg.dip_frames / 3)), 1.0)
    hand = np.zeros(n_frames)
    h0 = int(cfg.hand_at * n_frames)
    for i in range(h0, min(n_frames, h0 + cfg.hand_frames)):
        phase = (i - h0 + 0.5) / cfg.hand_frames
        hand[i] = cfg.hand_cover * np.sin(np.pi * phase)
    hand_seed = int(rng.integers(1 << 30))
    centre = board.centre[None]
    blur_px = np.zeros(n_frames)
    frames = []
    for i in range(n_frames):
        T_prev, T = poses[i], poses[i + 1]
        img = cam.render(T, degradation=Degradation(noise_sigma=0.0), rng=rng).astype(np.float32)
        if hand[i] > 0.01:
            img = cam._occlude(img, T, float(hand[i]), np.random.default_rng(hand_seed), 1.0)
        img = img * exposure[i]
        p0 = project_points(centre, T_prev, camera.K, camera.dist)[0]
        p1 = project_points(centre, T, camera.K, camera.dist)[0]
        d = (p1 - p0) * cfg.shutter
        blur_px[i] = float(np.hypot(*d))
        img = _motion_blur(img, float(d[0]), float(d[1]))
        img = img + rng.normal(0, 1, img.shape).astype(np.float32) * np.sqrt(np.maximum(img, 0) * cfg.shot_noise)
        img = img + rng.normal(0, cfg.noise_sigma, img.shape).astype(np.float32)
        frames.append(np.clip(img + 0.5, 0, 255).astype(np.uint8))
    return RigSession(frames, poses[1:], cfg.fps, camera, exposure, blur_px, hand)
