"""The app's integration with the 3-D characters and the AR rig: the story MP4 export,
the projector screen through the (synthetic) tracked rig, the animated "more like this"
thumbnails and the tap-to-import package picker.

Kivy runs in a subprocess per scenario (tests/support/ui_driver.py), as in tests/app/test_ui.py.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from app.story import Character, MotionChoice, Scene, Story, wavy_path

REPO = Path(__file__).resolve().parents[2]
DRIVER = REPO / "tests" / "support" / "ui_driver.py"
LIBRARY = REPO / "assets" / "motions"

needs_library = pytest.mark.skipif(not (LIBRARY / "labels.csv").is_file(), reason="bundled motion library absent")


def _drive(tmp_path: Path, scenario: str) -> tuple[dict, Path]:
    """Run one driver scenario with the real bundled motion library."""
    out = tmp_path / f"out_{scenario}"
    env = {k: v for k, v in os.environ.items() if k != "STORYBEAM_TEST_MOTIONS"}
    env.update(SDL_VIDEODRIVER="offscreen", KIVY_NO_ARGS="1", KIVY_HOME=str(tmp_path / "kivy"),
               STORYBEAM_TEST_LANG="en", PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, str(DRIVER), scenario, str(tmp_path / "p.db"), str(out)],
                          env=env, capture_output=True, text=True, timeout=240)
    result_file = out / "result.json"
    assert result_file.is_file(), f"driver produced no result (rc {proc.returncode}):\n{proc.stderr[-3000:]}"
    result = json.loads(result_file.read_text())
    assert "error" not in result, result["error"]
    return result, out


def _rgb(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float32)


def _two_scene_story() -> Story:
    return Story(title="two scenes", arc="free", scenes=[
        Scene(id="s1", background="grass", part="beginning", characters=[
            Character(id="c1", kind="robot", path=wavy_path(0.2, 0.3, 1.0, 0.5, 0.05, 1.6), motion=MotionChoice("walk"))]),
        Scene(id="s2", background="night", part="end", characters=[
            Character(id="c2", kind="animal", path=wavy_path(1.0, 0.5, 0.2, 0.4, 0.05, 1.2), motion=MotionChoice("run"))]),
    ])


def _light_centroid(frame: np.ndarray) -> np.ndarray | None:
    """Centre of the projected light in a camera-view frame: unlit paper is about 140
    grey and the table darker, so only projector light takes a pixel above 215."""
    ys, xs = np.nonzero(frame.max(axis=2) > 215)
    return None if len(xs) < 15 else np.array([xs.mean(), ys.mean()])


@needs_library
@pytest.mark.slow  # a 3-D video export in a child process
def test_story_mp4_shows_3d_characters_walking_scene_after_scene(tmp_path):
    pytest.importorskip("pyrender")
    import imageio.v2 as imageio

    from app.player.video_export import available, export_in_subprocess, frame_count
    if available():
        pytest.skip(available())
    story, fps = _two_scene_story(), 8.0
    seen = []
    result = export_in_subprocess(story, tmp_path / "story.mp4", fps=fps, view="camera",
                                  progress=lambda d, n: seen.append((d, n)))
    total = frame_count(story, fps)
    assert result.mode == "camera" and not result.note  # the 3-D camera view, not the 2-D fallback
    assert seen[-1] == (total, total) and len(seen) == total  # progress for every frame
    frames = [f for f in imageio.get_reader(result.path)]
    assert len(frames) == total and frames[0].shape == (480, 640, 3)
    assert all(f.std() > 15 for f in frames)  # table and board, not a blank frame
    n1 = int(round(story.scenes[0].duration * fps))
    # the robot's light walks across the board in scene 1, the cat's in scene 2
    for first, last in ((2, n1 - 1), (n1 + 1, total - 1)):
        a, b = _light_centroid(frames[first]), _light_centroid(frames[last])
        assert a is not None and b is not None, "no projected character light in the camera view"
        assert np.linalg.norm(a - b) > 25, (a, b)


@needs_library
def test_stick_figures_differ_between_clips_and_show_a_jump(tmp_path):
    from app.services.thumbnails import HEAD, ThumbnailCache, library_files

    cache = ThumbnailCache(LIBRARY, n_frames=8)
    files = library_files(LIBRARY)
    walk, jump = "02_01", "02_04"  # labels.csv: a walk and a jump
    assert walk in files and jump in files
    cache.request([walk, jump, "no-such-clip"])
    assert cache.wait([walk, jump, "no-such-clip"], timeout=60)
    a, b = cache.get(walk).points, cache.get(jump).points
    assert a.shape == b.shape == (8, 18, 2)
    assert np.abs(a - b).max() > 0.05
    # a jump lifts the whole figure: its head's height varies much more than a walker's
    assert np.ptp(b[:, HEAD, 1]) > 2 * np.ptp(a[:, HEAD, 1])
    assert cache.failed("no-such-clip") and cache.get("no-such-clip") is None
    # a list reopened while its figures were being made: every asker hears back
    again = ThumbnailCache(LIBRARY, n_frames=4)
    heard = []
    again.request([walk, walk], lambda trial, frames: heard.append(trial))
    assert again.wait([walk])
    again.request([walk], lambda trial, frames: heard.append(trial))  # asked after it was made
    assert _eventually(lambda: len(heard) == 3)


def _eventually(check, seconds: float = 10.0) -> bool:
    import time
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if check():
            return True
        time.sleep(0.01)
    return check()


@needs_library
@pytest.mark.slow  # starts the app in a child process
def test_projector_screen_preview_lights_only_the_characters(tmp_path):
    pytest.importorskip("pyrender")
    r, out = _drive(tmp_path, "projector3d")
    assert r["stage_available"]
    p = r["projector3d"]
    assert p["render_error"] is None and p["problems"] == []
    # a pose is known (the characters' light can hide markers for a frame: then "holding")
    assert p["state"] in ("tracking", "holding") and not p["live"]
    assert p["label"] == f"preview rig · {p['state']}"  # the corner label says the frame's state
    frame = np.load(out / "projector3d.npy").astype(np.float32)
    h, w = frame.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    near = np.zeros((h, w), bool)
    assert len(p["character_px"]) == 2  # robot and cat of the demo's first scene
    for cx, cy in p["character_px"]:
        d = np.hypot(xs - cx, ys - cy)
        assert frame[d < 30].max() > 100, f"no light where the character stands ({cx:.0f}, {cy:.0f})"
        near |= d < 80
    assert (frame[~near].max(axis=1) < 10).mean() > 0.999  # black (no light) everywhere else
    # the screen shows that frame full screen (letter-boxed): bright at the characters, black around
    shot = _rgb(out / "projector3d.png")
    scale = p["norm_size"][1] / h
    x0 = (shot.shape[1] - p["norm_size"][0]) / 2
    for cx, cy in p["character_px"]:
        sx, sy = int(x0 + cx * scale), int(cy * scale)
        assert shot[max(0, sy - 50):sy + 50, max(0, sx - 50):sx + 50].max() > 100
    assert np.median(shot) < 10
    # Preview: the camera view of the synthetic rig -- the table and board with the light on it
    cam = r["projector_camera"]
    assert cam["view"] == "camera" and cam["state"] in ("tracking", "holding")
    camera = np.load(out / "projector_camera.npy").astype(np.float32)
    assert camera.mean() > 30 and camera.std() > 20


@needs_library
@pytest.mark.slow  # starts the app in a child process
def test_more_like_this_tiles_show_animated_stick_figures(tmp_path):
    r, out = _drive(tmp_path, "thumbs")
    tiles = r["tiles"]
    assert len(tiles) >= 2 and all(t["figure"] for t in tiles)
    figures = [np.array(t["points"]) for t in tiles]
    for f in figures:
        assert f.shape[0] >= 4 and f.min() >= -1e-3 and f.max() <= 1 + 1e-3
        assert np.abs(np.diff(f, axis=0)).max() > 0.02  # the poses change along the clip
    for i in range(len(figures)):
        for j in range(i + 1, len(figures)):
            assert np.abs(figures[i] - figures[j]).max() > 0.02, (tiles[i]["trial"], tiles[j]["trial"])
    assert any(a != b for a, b in zip([t["pose"] for t in tiles], r["poses_later"]))  # animated
    shot = _rgb(out / "more_like_this_thumbs.png")
    for t in tiles:
        x, y, w, h = (int(v) for v in t["box"])
        box = shot[800 - (y + h):800 - y, x:x + w]
        assert (box.mean(axis=2) < 120).sum() > 150, f"no stick figure drawn in the {t['trial']} tile"


@pytest.mark.slow  # starts the app in a child process
def test_import_picker_imports_by_tap_and_refuses_a_bad_package(tmp_path):
    r, _out = _drive(tmp_path, "import")
    assert r["tiles"] == ["broken.zip", "good.zip"]
    assert r["before"]["stories"] == []
    assert r["bad_ok"] is False and "broken.zip" in r["bad_message"] and "manifest.json" in r["bad_message"]
    assert r["after_bad"] == r["before"]  # same stories, same database bytes
    assert r["good_ok"] is True and r["imported_titles"] == ["Imported by tap"]
    assert len(r["after_good"]["stories"]) == 1 and r["after_good"]["digest"] != r["before"]["digest"]


@needs_library
def test_stage_keeps_the_show_going_when_a_live_rig_fails():
    """A live rig's frames are tracked in real time; when its camera stops, the app's
    renderer carries on with the synthetic rig instead of killing the render thread."""
    pytest.importorskip("pyrender")
    from app.story.demo_story import demo_story
    from app.player import AppRenderer, StageJob
    from ar.errors import RigError
    from ar.rig import SyntheticRig
    from ar.boards import DEFAULT_BOARD_SPEC, Board

    class UnpluggedRig(SyntheticRig):
        """A live rig (its newest tracked frame at each :meth:`step`) whose camera stops after two frames."""
        live = True

        def step(self, light=None):
            if self._i >= 2:
                raise RigError("the rig's camera stopped sending frames")
            return super().step(None)

    renderer = AppRenderer(rig=UnpluggedRig(Board(DEFAULT_BOARD_SPEC)))
    scene = demo_story().scenes[0]
    frames = [renderer(StageJob(scene, "projector"), k / 10) for k in range(4)]
    assert [f.live for f in frames] == [True, True, False, False]
    assert all(f.state == "tracking" for f in frames[:2]) and frames[-1].character_px
    assert frames[-1].rgb.max() > 100  # the characters are still lit


def test_export_falls_back_to_2d_and_says_why_when_3d_cannot_render(tmp_path, monkeypatch):
    import imageio.v2 as imageio

    from app.player import video_export
    if video_export.available():
        pytest.skip(video_export.available())

    def no_gl(story, fps, view, size=None):
        raise RuntimeError("eglInitialize failed")
        yield  # a generator, like the real one

    monkeypatch.setattr(video_export, "story_frames_3d", no_gl)
    story = _two_scene_story()
    result = video_export.export_story_mp4(story, tmp_path / "s.mp4", fps=5, view="camera")
    assert result.mode == "2d" and "eglInitialize failed" in result.note and "2-D" in result.note
    frames = [f for f in imageio.get_reader(result.path)]
    assert len(frames) == video_export.frame_count(story, 5) == result.frames
    # the story film (the default view) falls back too, and keeps its title and ending cards
    film = video_export.export_story_mp4(story, tmp_path / "f.mp4", fps=5, size=(320, 180))
    assert film.mode == "2d" and "eglInitialize failed" in film.note
    assert film.frames == video_export.frame_count(story, 5, "story") == video_export.frame_count(story, 5) + sum(
        video_export.card_frames(5))


@pytest.mark.slow  # a video export in a child process
def test_export_child_process_failure_is_one_plain_error(tmp_path):
    from app.player.video_export import VideoExportError, available, export_in_subprocess
    if available():
        pytest.skip(available())
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(VideoExportError) as err:
        export_in_subprocess(_two_scene_story(), tmp_path / "a_file" / "inside.mp4", fps=5)
    message = str(err.value)
    assert "inside.mp4" in message and "video export failed" in message and "Traceback" not in message
