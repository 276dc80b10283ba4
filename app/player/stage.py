"""The story on the table: every character of a scene rendered from the projector's
viewpoint through the tracked rig, for the projector screen and the MP4 export.

Per frame (the rig's one frame loop, :mod:`ar.rig`, as ``storybeam demo`` steps it too):

1. the rig's camera sees the board (and the light the projector showed last frame, as on
   a real rig: one frame of latency) -- a live camera with calibration files
   (:class:`ar.rig.LiveRig`), or with no rig attached the synthetic rig held by a
   synthetic hand (:class:`ar.rig.SyntheticRig`), chosen by :func:`ar.rig.open_rig`;
2. the rig steps its frame loop (:meth:`ar.rig.RigTracker.step`: region detection, pose,
   filter -- tracking / holding / lost -- and the projector pose), told what the projector
   showed (:class:`ar.rig.ProjectedLight`) so the corners its own light fell on are left out;
3. the characters, posed at story time ``t``, are described as seen by the projector from
   the tracked pose (an :class:`ar.scene.SceneDescription`) and drawn: by pyrender
   (:class:`ar.render.PyrenderSceneRenderer`, the MP4 export and headless tests) or, with
   ``draw=None``, by the caller -- the app draws it with Kivy GL on its UI thread
   (:mod:`app.ui.gl`) and hands the light back (:attr:`StageFrame.light_sink`) for the
   rig's next frame; black = no light;
4. the *camera view* is that camera frame: the table with the projected light on it,
   what an audience standing by the rig sees.

The story's table (1.2 x 0.8 m on the tablet) is played as a miniature on the marker
board (:data:`app.player.placement.STAGE_PLACEMENT`): scaled by
:data:`app.player.placement.STAGE_SCALE` and centred on the board, the table's long side
along the board's long side, the child's edge of the table nearest the rig's camera.
Characters stand :data:`STAGE_CHARACTER_HEIGHT_M` tall there (a little larger than the
scale alone would make them, so they read in the projected light; the path timing is kept).

With a scanned table (:class:`ar.height_map.HeightMap`, ``table.npz`` beside the
calibration files, from the wizard's *Scan the table* step) the characters follow its
surface (:func:`retrieval.animation.follow_surface`): their roots are lifted to the
height under their feet, so the projector draws them at that height in the board frame
and their feet land on the top of a box they cross; they jump at edges higher than
:data:`retrieval.animation.STEP_MAX_M`.

A :class:`StageRenderer` owns GL state: create and use it on one thread only (the app's
:class:`app.player.render_thread.RenderThread` through
:class:`app.player.app_renderer.AppRenderer`, or the export's worker process).

Needs no pyrender (it is imported only when ``draw="pyrender"`` draws a first frame):
the stage runs on the tablet with ``draw=None``.
"""
from __future__ import annotations

import functools
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from app.paths import MOTIONS_DIR
from app.player.animator import SceneAnimator
from app.player.placement import STAGE_PLACEMENT
from app.story import Scene
from ar import DEFAULT_BOARD_SPEC, HEIGHT_MAP_FILE, Board, HeightMap, project_points
from ar.errors import RigError
from ar.rig import ProjectedLight, open_rig
from ar.scene import SceneDescription, View, add_character, board_from_scene, scaled_model, scene_ground
from retrieval.errors import StoryBeamError
from retrieval.motion import positions

log = logging.getLogger(__name__)

STAGE_CHARACTER_HEIGHT_M = 0.10
VIEWS = ("projector", "camera")


class StageError(StoryBeamError):
    """The projector stage cannot run (no rig, bad calibration, no renderer)."""


@dataclass
class StageFrame:
    """One rendered frame and what the tracker said about it.

    ``rgb`` is the requested view; ``projector`` the light image (black = no light);
    ``character_px`` where each character's hips land in the projector image (None
    while no pose is known); ``state`` the tracker's: ``ar.TRACKING`` / ``HOLDING`` / ``LOST``.
    """

    rgb: np.ndarray
    projector: np.ndarray
    state: str
    view: str
    character_px: list = field(default_factory=list)
    problems: list = field(default_factory=list)
    live: bool = False  # a real rig (else the synthetic one)
    scene_id: str = ""
    t: float = 0.0  # story time inside the scene
    #: what the projector shows, for a caller that draws it itself (``draw=None``: then
    #: ``projector`` -- and ``rgb`` for the projector view -- is None until it is drawn)
    description: SceneDescription | None = None
    #: give the drawn light image (RGB) back here: the rig's next frame is tracked knowing
    #: where it fell (and the synthetic rig films it)
    light_sink: object = None


# ---------------------------------------------------------------------------- renderer
class StageRenderer:
    """``render(scene, t, view) -> StageFrame``: one rig frame per call (the hand moves on
    in real time), the scene's characters posed at story time ``t``.

    Prepared scenes are cached by content (preparing = retargeting and laying each
    character's clip on its path, about a second per character)."""

    def __init__(self, rig=None, profile_dir: Path | None = None, fps: float = 30.0,
                 motions_dir: Path | None = None, rig_fps: float | None = None, camera: int | str | None = 0,
                 draw="pyrender", height_map: HeightMap | None = None):
        """``draw``: who draws the light -- ``"pyrender"`` (headless, the MP4 export), a
        callable ``SceneDescription -> RGB``, or None: the caller draws
        :attr:`StageFrame.description` (the app, with Kivy GL on its UI thread).
        ``fps``: the animation's frame rate; ``rig_fps``: how often the rig is sampled
        (one call of :meth:`render` = one rig frame; default ``fps``); ``camera``: the
        camera source :func:`open_rig` tries when no ``rig`` is given; ``height_map``: the
        scanned table (default: ``table.npz`` in ``profile_dir``, followed while the stage
        runs: a new scan is used from the next frame, a deleted one dropped)."""
        self.board = Board(DEFAULT_BOARD_SPEC)
        self.fps = fps
        self.rig_fps = rig_fps or fps
        self.rig = rig if rig is not None else open_rig(profile_dir, self.board, self.rig_fps, camera)
        model = self.rig.projector_model
        if self.rig.live:  # render the light at the projector's own size (up to 1280 wide)
            k = min(1.0, 1280 / model.width)
            model = scaled_model(model, int(model.width * k), int(model.height * k))
        self.light_model = model
        self.draw = draw
        self._pyrender = None  # made on the first frame drawn with draw="pyrender"
        self.problems: list[str] = []
        self.animator = SceneAnimator.from_library(motions_dir or MOTIONS_DIR, fps=fps,
                                                   character_height_m=STAGE_CHARACTER_HEIGHT_M,
                                                   placement=STAGE_PLACEMENT)
        self.height_map: HeightMap | None = None
        #: the profile's scan, followed while the stage runs (a new scan replaces it)
        self._scan_file = None if height_map is not None or profile_dir is None else Path(profile_dir) / HEIGHT_MAP_FILE
        self._scan_stamp: tuple | None = None
        self.set_height_map(height_map)
        self._follow_scan()
        self._cast: list = []  # (design, (F, P, 4, 4) part poses) per character on stage
        self._hips_tracks: list = []
        self._light: ProjectedLight | None = None  # what the projector showed last (None: nothing yet)

    @property
    def live(self) -> bool:
        return bool(self.rig.live)

    def __call__(self, scene: Scene, t: float, view: str = "projector") -> StageFrame:
        return self.render(scene, t, view)

    def set_height_map(self, height_map: HeightMap | None) -> None:
        """Play on ``height_map`` from now on (None: the bare table); the cast is re-laid."""
        self.height_map = height_map
        self.animator.ground = scene_ground(height_map, self.board) if height_map is not None else None
        self._key = None

    def _follow_scan(self) -> None:
        """Load the profile's ``table.npz`` when it appears or changes (the teacher scanned
        again), drop it when it is deleted; an unreadable one is reported and not used."""
        if self._scan_file is None:
            return
        try:
            st = self._scan_file.stat()
            stamp = (st.st_mtime_ns, st.st_size)
        except OSError:
            stamp = None
        if stamp == self._scan_stamp:
            return
        self._scan_stamp = stamp
        height_map = None
        if stamp is not None:
            try:
                height_map = HeightMap.load(self._scan_file)
            except StoryBeamError as exc:  # the stage plays on the bare table; the teacher can scan again
                log.warning("scanned table not used: %s", exc)
        self.set_height_map(height_map)

    def prepare(self, scene: Scene) -> None:
        """Put ``scene``'s characters on stage (no-op if it is already there)."""
        self._follow_scan()
        key = json.dumps(scene.to_dict(), sort_keys=True)
        if key == self._key:
            return
        cast, self.problems = self.animator.animate_scene(scene.characters, "projector stage")
        self._cast = [(design, design.all_part_poses(motion)) for _, design, motion in cast]
        self._hips_tracks = [positions(motion)[:, 0] for _, _, motion in cast]  # for character_px
        self._key = key

    def render(self, scene: Scene, t: float, view: str = "projector") -> StageFrame:
        if view not in VIEWS:
            raise StageError(f"unknown stage view {view!r}; choose one of {', '.join(VIEWS)}")
        self.prepare(scene)
        try:  # the rig's frame loop: a live rig answers its threads' newest, the synthetic one films the next
            track = self.rig.step(self._light)
        except RigError as exc:
            raise StageError(str(exc)) from exc
        frame_bgr = track.image
        m = self.light_model
        light = np.zeros((m.height, m.width, 3), np.uint8)
        character_px: list = []
        desc = None
        if track.T_proj_from_board is not None:
            frame = int(round(max(t, 0.0) * self.fps))
            T_proj_from_scene = track.T_proj_from_board @ board_from_scene(self.board)
            desc = self.describe(T_proj_from_scene, frame)
            if self.draw is not None:
                light = self._draw(desc)
            for hips in self._hips_tracks:
                f = int(np.clip(frame, 0, len(hips) - 1))
                px = project_points(hips[f][None], T_proj_from_scene, m.K, np.zeros(5))[0]
                character_px.append((float(px[0]), float(px[1])))
        light_sink = None
        if self.draw is None and desc is not None:  # the caller draws it, and gives the light back
            light = None
            light_sink = functools.partial(self.take_light, T_proj_from_board=track.T_proj_from_board)
        else:
            self.take_light(light, track.T_proj_from_board)
        if view == "camera":
            rgb = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2RGB)
        else:
            rgb = light
        return StageFrame(rgb, light, track.state, view, character_px, list(self.problems), self.live,
                          scene.id, float(t), desc, light_sink)

    def describe(self, T_proj_from_scene: np.ndarray, frame: int) -> SceneDescription:
        """What the projector shows at animation ``frame`` from ``T_proj_from_scene``: every
        character on stage at its part poses, through the light model's intrinsics."""
        m = self.light_model
        desc = SceneDescription(View(m.width, m.height, m.K, T_proj_from_scene))
        for design, poses in self._cast:
            add_character(desc, design, poses[int(np.clip(frame, 0, len(poses) - 1))])
        return desc

    def _draw(self, desc: SceneDescription) -> np.ndarray:
        if callable(self.draw):
            return self.draw(desc)
        if self._pyrender is None:
            from ar.render import PyrenderSceneRenderer  # optional: pyrender (absent on Android, where draw=None)
            self._pyrender = PyrenderSceneRenderer()
        return self._pyrender.render(desc)

    def take_light(self, light: np.ndarray, T_proj_from_board: np.ndarray | None = None) -> None:
        """The light image just shown (RGB, any size), drawn from ``T_proj_from_board``: the
        rig's next frame is tracked knowing where it fell (the synthetic rig films it on the
        table). Safe to call from another thread."""
        self._light = ProjectedLight(np.asarray(light), self.light_model, T_proj_from_board)

    def close(self) -> None:
        try:
            if self._pyrender is not None:
                self._pyrender.close()
                self._pyrender = None
        finally:
            self.rig.close()


__all__ = ["StageError", "StageFrame", "StageRenderer", "STAGE_CHARACTER_HEIGHT_M", "VIEWS"]
