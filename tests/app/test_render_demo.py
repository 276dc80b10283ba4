"""Rendering the animated character (headless EGL) and the demo command end to end."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from pathlib import Path  # noqa: E402

BVH = Path(__file__).resolve().parents[2] / "assets" / "motions" / "bvh"


@pytest.fixture(scope="module")
def walking_robot():
    from ar.render.characters import build_character
    from retrieval.motion.formats import load_motion
    from retrieval.animation import follow_path, straight_path
    from retrieval.animation import retarget
    ch = build_character("robot")
    m = retarget(load_motion(BVH / "02_01.bvh"), ch.skeleton)
    return ch, follow_path(m, straight_path(0.2, start=(-0.1, 0.0))).motion


def test_projector_render_shows_the_character_where_it_stands(walking_robot):
    from ar.render.character_render import CharacterRig
    from ar.geometry import look_at
    from ar.render.projector_view import ProjectorRenderer

    ch, motion = walking_robot
    K = np.array([[500.0, 0, 159.5], [0, 500.0, 119.5], [0, 0, 1]])
    r = ProjectorRenderer(320, 240, K)
    rig = CharacterRig(r, ch)
    rig.bind(motion)
    r.set_view(look_at(np.array([0.0, 0.5, 0.15]), np.zeros(3), np.array([0.0, 0.0, -1.0])))
    try:
        centroids = []
        for f in (0, motion.n_frames - 1):
            rig.show_frame(f)
            img = r.render()
            lit = img.max(axis=2) > 20
            assert 200 < lit.sum() < 0.5 * lit.size  # a figure, not blank, not a flood
            assert img[lit].max() > 150  # bright colours
            centroids.append(np.argwhere(lit).mean(axis=0)[1])
        assert centroids[1] > centroids[0] + 20  # walked towards +x (image right)
    finally:
        r.close()


def test_demo_command_tiny_run_writes_video_and_report(tmp_path):
    from app.cli import main

    rc = main(["demo", "--out-dir", str(tmp_path), "--seconds", "3", "--max-frames", "6", "--quiet"])
    assert rc == 0
    report = json.loads((tmp_path / "demo.json").read_text())
    for key in ("retrieved", "path_error_cm", "foot_skate_cm_per_m", "render_ms_median", "landing_error_mm", "frames"):
        assert key in report
    assert report["frames"] == 6 and report["tracking_states"]["tracking"] == 6
    assert report["retrieved"]["label"] == "walk" and report["retrieved"]["trial"] != "16_15"
    assert report["path_error_cm"] < 1.2 and report["render_ms_median"] > 0
    import imageio.v2 as imageio

    reader = imageio.get_reader(str(tmp_path / "demo.mp4"))
    frames = [f for f in reader]  # (list(reader) asks len(), which is inf for ffmpeg)
    reader.close()
    # default view: camera | projector | overhead, 640x480 each, side by side
    assert len(frames) == 6 and frames[0].shape == (480, 3 * 640, 3)
    projector = frames[0][:, 640:1280].astype(float)
    assert (projector.max(axis=2) < 24).mean() > 0.8, "projector panel should be mostly black (no light)"
    assert projector.max() > 100, "projector panel should show the character"
    assert frames[-1].std() > 10  # a picture, not a blank frame


def test_render_still_to_png(tmp_path):
    from app.cli import main
    from PIL import Image

    png = tmp_path / "p.png"
    rc = main(["render", "--demo", "--view", "projector", "--still", "3", "--png", str(png), "--size", "320x240",
               "--seconds", "3", "--index-dir", str(tmp_path / "idx")])
    assert rc == 0
    img = np.asarray(Image.open(png))
    assert img.shape == (240, 320, 3) and (img.max(axis=2) > 20).sum() > 100


def test_render_rejects_bad_options(capsys):
    from app.cli import main

    assert main(["render", "--out", "x.mp4"]) == 1  # no --demo
    assert main(["render", "--demo", "--size", "big"]) == 1
    assert "error" in capsys.readouterr().err
