"""App parts without a window: gestures, strings and font coverage, motion catalog,
render thread, calibration wizard."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from PIL import Image, ImageDraw, ImageFont

from app.story.gestures import find_spins, hop_time, thin
from app.player.render_thread import RenderThread
from app.services.catalog import MotionCatalog
from app.ui.strings import LANGUAGES, STRINGS, tr

FONT = "assets/fonts/Mplus1-Medium.otf"


def _timed(points):
    return [(x, y, 0.1 * i) for i, (x, y) in enumerate(points)]


def test_thin_drops_resting_finger_samples():
    pts = _timed([(0.1, 0.1), (0.1001, 0.1), (0.1002, 0.1), (0.2, 0.1)])
    assert [p[:2] for p in thin(pts)] == [(0.1, 0.1), (0.2, 0.1)]


def test_small_loop_is_a_spin_and_is_cut_out():
    pts = [(0.2 + 0.02 * i, 0.5) for i in range(11)]
    pts += [(0.4, 0.53), (0.4, 0.56), (0.37, 0.56), (0.35, 0.56), (0.35, 0.53), (0.35, 0.47)]
    pts += [(0.35 + 0.03 * i, 0.45) for i in range(1, 12)]
    path, spins = find_spins(_timed(pts))
    assert len(spins) == 1 and spins[0] == pytest.approx(0.7)
    assert len(path) < len(pts)
    assert all(b[2] > a[2] for a, b in zip(path, path[1:]))


def test_big_self_crossing_is_not_a_spin():
    pts = [(0.1, 0.1), (0.9, 0.1), (0.9, 0.7), (0.5, 0.7), (0.5, 0.0)]  # crosses after ~1.6 m
    path, spins = find_spins(_timed(pts))
    assert spins == [] and len(path) == len(pts)


def test_hop_arc_onto_the_path():
    path = _timed([(0.1 + 0.05 * i, 0.3) for i in range(15)])
    arc = _timed([(0.3 + 0.02 * i, 0.3 + 0.1 * (1 - abs(i - 5) / 5)) for i in range(11)])
    assert hop_time(arc, path) == pytest.approx(0.4)
    straight = _timed([(0.3 + 0.02 * i, 0.3) for i in range(11)])
    assert hop_time(straight, path) is None  # no bulge: a new path, not a hop
    far = _timed([(0.3 + 0.02 * i, 0.6 + 0.1 * (1 - abs(i - 5) / 5)) for i in range(11)])
    assert hop_time(far, path) is None


def test_every_string_exists_in_both_languages():
    for key, entry in STRINGS.items():
        for lang in LANGUAGES:
            assert entry.get(lang), f"{key} missing in {lang}"
    assert tr("story_n", "ja", n=3) == "おはなし 3"
    assert tr("no_such_key", "en") == "no_such_key"


def test_bundled_font_has_every_japanese_glyph_we_use():
    font = ImageFont.truetype(FONT, 32)

    def mask(ch):
        img = Image.new("L", (48, 48))
        ImageDraw.Draw(img).text((4, 4), ch, font=font, fill=255)
        return np.asarray(img)

    notdef = mask("\U000F0000")  # private-use plane: not in the font -> the .notdef box
    chars = {ch for entry in STRINGS.values() for ch in entry["ja"] if not ch.isspace() and ord(ch) > 0x7F}
    assert len(chars) > 50
    missing = [ch for ch in chars if np.array_equal(mask(ch), notdef)]
    assert missing == []


def test_catalog_lists_classes_and_falls_back_to_same_class(tmp_path):
    (tmp_path / "labels.csv").write_text("trial,label,file,skeleton\na,walk,a.bvh,\nb,walk,b.bvh,\nc,kick,c.bvh,\n")
    cat = MotionCatalog(tmp_path, build_index=False)
    assert cat.classes == ["kick", "walk"]
    assert [c.trial for c in cat.similar("a")] == ["a", "b"]
    assert [c.trial for c in cat.similar("kick")] == ["c"]
    assert cat.similar("dance") == []
    assert MotionCatalog(tmp_path / "missing").clips == []


def test_catalog_rebuilds_an_index_saved_on_another_body(tmp_path):
    """A saved index whose features were taken on the file's own body (before issue 31)
    is not used: the catalogue builds the index from the clips instead."""
    import json

    from retrieval.library import MotionIndex
    from retrieval.motion import save_bvh
    from tests.support.synthetic_motion import make_motion, make_skeleton

    rows = ["trial,label,file,skeleton"]
    for k in range(4):
        save_bvh(make_motion(make_skeleton(), frames=40, arm_swing=20.0 + 10 * k), tmp_path / f"t{k}.bvh")
        rows.append(f"t{k},{'walk' if k % 2 else 'kick'},t{k}.bvh,")
    (tmp_path / "labels.csv").write_text("\n".join(rows) + "\n")
    saved = MotionIndex.build(tmp_path, dims=3).save(tmp_path / "index")
    meta = json.loads((saved / "index.json").read_text())
    meta["body"] = "source"
    meta["trials"] = ["stale"] + meta["trials"][1:]  # so the test can tell which index was used
    (saved / "index.json").write_text(json.dumps(meta))
    cat = MotionCatalog(tmp_path)
    cat.start_index()
    assert cat.wait_index(60) and cat.index_ready, cat._index_error
    assert cat._index.trials == ["t0", "t1", "t2", "t3"]


def test_render_thread_renders_on_its_own_thread_and_keeps_the_newest_request():
    threads, delivered = [], []
    gate = threading.Event()

    def make():
        threads.append(threading.current_thread().name)

        def render(scene, t):
            gate.wait(5)
            threads.append(threading.current_thread().name)
            return np.full((4, 4, 3), int(t), np.uint8)
        return render

    rt = RenderThread(make, lambda cb, frame: cb(frame))
    rt.request("s", 1, delivered.append)
    time.sleep(0.1)  # the first request is being rendered (blocked on the gate)
    for t in (2, 3, 4):
        rt.request("s", t, delivered.append)
    gate.set()
    deadline = time.time() + 5
    while len(delivered) < 2 and time.time() < deadline:
        time.sleep(0.01)
    rt.stop()
    assert [int(f[0, 0, 0]) for f in delivered] == [1, 4]  # 2 and 3 were superseded
    assert set(threads) == {"storybeam-render"}


def test_render_thread_survives_a_broken_renderer():
    def make():
        raise RuntimeError("no GL here")
    rt = RenderThread(make, lambda cb, frame: cb(frame))
    rt._thread.join(2)
    assert not rt.alive and "no GL here" in rt.error
    rt.request("s", 0.0, lambda f: None)  # ignored, no exception


def test_calibration_wizard_runs_the_ar_chain_on_synthetic_views(tmp_path):
    pytest.importorskip("cv2")
    from app.services.calibration_wizard import CalibrationWizard
    wizard = CalibrationWizard(tmp_path, n_views=5)
    while not wizard.done:
        step = wizard.run_next()
        assert step.error is None, f"{step.key}: {step.error}"
    assert (tmp_path / "camera.json").is_file()
    assert "RMS" in wizard.steps[2].result
    broken = CalibrationWizard(tmp_path, board_spec="charuco:bad")
    step = broken.run_next()
    assert step.error and not broken.done and broken.current == 0


def test_story_video_export_writes_every_frame(tmp_path):
    from app.story.demo_story import demo_story
    from app.player.video_export import VideoExportError, available, export_story_mp4
    if available():
        pytest.skip(available())
    import imageio.v2 as imageio
    story = demo_story()
    result = export_story_mp4(story, tmp_path / "demo.mp4", fps=10, view="2d")  # the no-GL fallback
    assert result.mode == "2d" and result.frames == sum(int(round(s.duration * 10)) for s in story.scenes)
    reader = imageio.get_reader(result.path)
    assert reader.count_frames() == sum(int(round(s.duration * 10)) for s in story.scenes)
    first = reader.get_data(0)
    assert first.shape[:2] == (426, 640) and first.std() > 5
    with pytest.raises(VideoExportError):
        (tmp_path / "a_file").write_text("x")
        export_story_mp4(story, tmp_path / "a_file" / "inside.mp4", view="2d")  # parent is a file
