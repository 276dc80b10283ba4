"""The Kivy GL vs pyrender parity cases, and the Kivy side of the comparison.

:func:`parity_cases` builds, deterministically, one :class:`ar.scene.SceneDescription`
per (bundled character, pose, view) at 640x480: 20 poses per character (4 frames from
each of a walk, run, jump, dance and kick clip of the bundled library, retargeted onto
the character, centred on the board and turned by 18 degrees more each pose) seen from
the projector and the camera of a hand-held rig (:func:`ar.synthetic.handheld_trajectory`,
a different rig pose per case) and from the authoring overhead view.

Run as ``python tests/support/gl_parity.py OUT.npz`` (offscreen SDL) it draws every case
with :class:`app.ui.gl.KivyGLRenderer` -- in its own process: Kivy keeps one window and
one GL context per process -- and saves, per case, the shaded image and the silhouette
image (:func:`silhouette_description`: every item white, ambient 1, no key light), and
the projector-view silhouettes again as the projector screen draws them
(``PROJECTOR_SUPERSAMPLE``, one sample per pixel), and the first :data:`STAGE_FRAMES` projector frames of the demo story's first scene through
:func:`app.ui.gl.stage.kivy_gl_stage_renderer` (the synthetic rig, deterministic).
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.paths import MOTIONS_DIR  # noqa: E402
from ar import Board, DEFAULT_BOARD_SPEC, TrajectoryConfig, default_camera, default_projector, handheld_trajectory  # noqa: E402
from ar.scene import (  # noqa: E402
    CHARACTER_NAMES,
    DrawItem,
    Lighting,
    SceneDescription,
    View,
    add_character,
    board_from_scene,
    build_character,
    overhead_view,
    projector_from_scene,
    scaled_model,
)
from ar.synthetic import default_proj_from_cam  # noqa: E402
from retrieval.animation import retarget  # noqa: E402
from retrieval.motion import load_motion  # noqa: E402

SIZE = (640, 480)
VIEWS = ("projector", "camera", "overhead")
CLASSES = ("walk", "run", "jump", "dance", "kick")
FRAMES_PER_CLIP = 4
STAGE_HEIGHT_M = 0.10  # as app.player.stage.STAGE_CHARACTER_HEIGHT_M
OVERHEAD_HEIGHT_M = 0.12
STAGE_FRAMES = 4  # frames of the demo story's first scene through kivy_gl_stage_renderer


def _clips() -> list[Path]:
    with open(MOTIONS_DIR / "labels.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    first = {}
    for r in rows:
        first.setdefault(r["label"], MOTIONS_DIR / r["file"])
    return [first[c] for c in CLASSES]


def _poses(name: str, height: float) -> list[np.ndarray]:
    """20 (P, 4, 4) part-pose sets of character ``name``, centred and turned."""
    ch = build_character(name, height)
    out = []
    for clip in _clips():
        motion = retarget(load_motion(clip), ch.skeleton)
        frames = np.linspace(0, motion.n_frames - 1, FRAMES_PER_CLIP).round().astype(int)
        poses = ch.all_part_poses(motion, list(frames))
        for p in poses:
            k = len(out)
            yaw = np.radians(18.0 * k)
            R = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
            hips = p[0, :3, 3].copy()
            T = np.eye(4)
            T[:3, :3] = R
            T[:3, 3] = -R @ np.array([hips[0], 0.0, hips[2]])
            out.append(np.einsum("ij,pjk->pik", T, p))
    return out


def parity_cases() -> list[tuple[str, int, str, SceneDescription]]:
    """``(character, pose index, view, description)`` for every case."""
    board = Board(DEFAULT_BOARD_SPEC)
    cam = scaled_model(default_camera(), *SIZE)
    proj = scaled_model(default_projector(), *SIZE)
    T_proj_from_cam = default_proj_from_cam()
    rig = handheld_trajectory(board, 400, TrajectoryConfig(seed=3, distance_m=0.55))
    cases = []
    for ci, name in enumerate(CHARACTER_NAMES):
        stage = build_character(name, STAGE_HEIGHT_M)
        over = build_character(name, OVERHEAD_HEIGHT_M)
        stage_poses, over_poses = _poses(name, STAGE_HEIGHT_M), _poses(name, OVERHEAD_HEIGHT_M)
        for k in range(len(stage_poses)):
            T_cam_from_board = rig[(ci * 131 + k * 17) % len(rig)]
            for view in VIEWS:
                if view == "projector":
                    v = View(*SIZE, proj.K, projector_from_scene(T_cam_from_board, T_proj_from_cam, board))
                    desc, ch, poses = SceneDescription(v), stage, stage_poses[k]
                elif view == "camera":
                    v = View(*SIZE, cam.K, T_cam_from_board @ board_from_scene(board))
                    desc, ch, poses = SceneDescription(v), stage, stage_poses[k]
                else:
                    desc = SceneDescription(overhead_view(*SIZE), lighting=Lighting(0.45, 3.5))
                    ch, poses = over, over_poses[k]
                add_character(desc, ch, poses)
                cases.append((name, k, view, desc))
    return cases


def silhouette_description(desc: SceneDescription) -> SceneDescription:
    """The same geometry drawn flat white (ambient 1, no key light): a pixel's value is
    the fraction of it the geometry covers (255 = fully; pyrender resolves its
    multisampling into partial values, the Kivy ES 2 buffer has none)."""
    items = [DrawItem(i.mesh, (255, 255, 255), i.pose, i.roughness) for i in desc.items]
    return SceneDescription(desc.view, items, Lighting(1.0, 0.0), desc.background)


def _kivy_main(out: Path) -> None:
    from app.ui.env import prepare_kivy_env  # deferred: Kivy reads its environment at import
    prepare_kivy_env(headless=True, width=320, height=240)
    from kivy.core.window import Window  # noqa: F401  (deferred: opens the GL context)

    from app.ui.gl import KivyGLRenderer  # deferred: imports Kivy

    renderer = KivyGLRenderer()  # as the app draws: the default supersampling
    shaded, masks = [], []
    for _name, _k, _view, desc in parity_cases():
        shaded.append(renderer.render(desc))
        masks.append(renderer.render(silhouette_description(desc))[..., 0])
    # the projector screen's own setting (one sample per pixel): its view's silhouettes
    from app.ui.gl import PROJECTOR_SUPERSAMPLE  # deferred: imports Kivy

    light = KivyGLRenderer(PROJECTOR_SUPERSAMPLE)
    projector_masks = [light.render(silhouette_description(desc))[..., 0]
                       for _name, _k, view, desc in parity_cases() if view == "projector"]
    from app.story.demo_story import demo_story  # deferred: only the stage check needs it
    from app.ui.gl.stage import kivy_gl_stage_renderer  # deferred: imports Kivy

    stage = kivy_gl_stage_renderer()
    scene = demo_story().scenes[0]
    stage_frames = np.stack([stage(scene, 0.5 + 0.1 * i, "projector") for i in range(STAGE_FRAMES)])
    np.savez_compressed(out, shaded=np.stack(shaded), masks=np.stack(masks), uploads=renderer.uploads,
                        stage=stage_frames, projector_masks=np.stack(projector_masks))


if __name__ == "__main__":
    _kivy_main(Path(sys.argv[1]))
