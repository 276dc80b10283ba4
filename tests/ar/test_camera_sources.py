"""Camera sources: a folder of images, a video file, frames in memory, an OpenCV device
(a stand-in ``cv2.VideoCapture``: no camera is attached here), and the ``--camera`` text."""
from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

import ar.camera_sources as cs
from ar.camera_sources import (CameraSourceError, FrameListSource, ImageFolderSource, OpenCVDeviceSource,
                               VideoFileSource, open_camera_source)
from retrieval.errors import StoryBeamError


def _frames(n: int, size=(64, 48)) -> list[np.ndarray]:
    """Distinct frames: frame i has a bright square at column 4 i (readable after lossy coding)."""
    out = []
    for i in range(n):
        img = np.full((size[1], size[0], 3), 40, np.uint8)
        img[10:26, 4 * i:4 * i + 16] = (200, 160, 120)
        out.append(img)
    return out


def _square_column(img: np.ndarray) -> int:
    cols = np.where(img[18, :, 0] > 120)[0]
    return int(cols[0]) if len(cols) else -1


def test_folder_source_reads_images_in_name_order_at_its_rate(tmp_path):
    frames = _frames(5)
    for i, f in reversed(list(enumerate(frames))):  # written out of order
        cv2.imwrite(str(tmp_path / f"frame_{i:05d}.png"), f)
    (tmp_path / "notes.txt").write_text("not an image")
    with ImageFolderSource(tmp_path, fps=25.0) as src:
        got = [src.read() for _ in range(5)]
        assert src.read() is None
    for i, (g, f) in enumerate(zip(got, frames)):
        assert g.index == i and g.timestamp_s == pytest.approx(i / 25.0)
        np.testing.assert_array_equal(g.image, f)


def test_folder_source_loops_and_keeps_counting(tmp_path):
    for i, f in enumerate(_frames(3)):
        cv2.imwrite(str(tmp_path / f"{i}.png"), f)
    src = ImageFolderSource(tmp_path, fps=10.0, loop=True)
    got = [src.read() for _ in range(7)]
    assert [g.index for g in got] == list(range(7))
    assert [_square_column(g.image) for g in got] == [0, 4, 8, 0, 4, 8, 0]
    assert got[6].timestamp_s == pytest.approx(0.6)


def test_video_source_plays_a_recording(tmp_path):
    path = tmp_path / "session.mp4"
    frames = _frames(10)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (64, 48))
    for f in frames:
        writer.write(f)
    writer.release()
    src = open_camera_source(str(path), paced=False)
    assert isinstance(src, VideoFileSource) and src.fps == pytest.approx(30.0)
    got = []
    while (frame := src.read()) is not None:
        got.append(frame)
    src.close()
    assert len(got) == 10
    assert [_square_column(g.image) for g in got] == [4 * i for i in range(10)]
    assert max(float(np.abs(g.image.astype(int) - f).mean()) for g, f in zip(got, frames)) < 8  # lossy, close


def test_paced_recording_arrives_at_camera_speed():
    """Paced, frame i is not handed out before i / fps after the first (a lower bound: a
    busy machine may only be later); unpaced, the same frames come at once."""
    frames = _frames(6)
    t0 = time.monotonic()
    src = FrameListSource(frames, fps=20.0, paced=True)
    while src.read() is not None:
        pass
    assert time.monotonic() - t0 >= 5 / 20.0 - 0.01
    unpaced = FrameListSource(frames, fps=0.5)
    t0 = time.monotonic()
    while unpaced.read() is not None:
        pass
    assert time.monotonic() - t0 < 5 / 0.5  # would take 10 s if it were paced


class _FakeCapture:
    """Stands in for cv2.VideoCapture(index): sends ``n`` grey frames, then fails."""

    opened = True
    n = 3

    def __init__(self, index):
        self.index = index
        self.sent = 0
        self.props = {}

    def isOpened(self):
        return type(self).opened

    def set(self, prop, value):
        self.props[prop] = value
        return True

    def read(self):
        if self.sent >= self.n:
            return False, None
        self.sent += 1
        return True, np.full((48, 64), self.sent * 10, np.uint8)

    def release(self):
        pass


def test_device_source_reads_frames_and_names_a_dead_camera(monkeypatch):
    monkeypatch.setattr(cs.cv2, "VideoCapture", _FakeCapture)
    src = open_camera_source("0")
    assert isinstance(src, OpenCVDeviceSource) and src.live
    frames = [src.read() for _ in range(3)]
    assert [f.image.shape for f in frames] == [(48, 64, 3)] * 3  # grey frames come back as BGR
    assert frames[2].image[0, 0, 0] == 30 and frames[1].timestamp_s >= frames[0].timestamp_s
    with pytest.raises(CameraSourceError, match="camera 0: the camera stopped sending frames"):
        src.read()
    monkeypatch.setattr(_FakeCapture, "opened", False)
    with pytest.raises(CameraSourceError, match="camera 2: no camera with this number"):
        open_camera_source("2")


@pytest.mark.parametrize("make, fragment", [
    (lambda p: p / "missing.mp4", "no such file or folder"),
    (lambda p: (p / "notes.txt").write_text("x") and p / "notes.txt", "not a video file"),
    (lambda p: (p / "empty").mkdir() or p / "empty", "no images"),
    (lambda p: (p / "broken.mp4").write_bytes(b"not a video") and p / "broken.mp4", "not a video OpenCV can read"),
])
def test_bad_sources_raise_one_clear_error(tmp_path, make, fragment):
    path = make(tmp_path)
    with pytest.raises(CameraSourceError, match=fragment) as info:
        open_camera_source(str(path))
    assert isinstance(info.value, StoryBeamError) and str(path) in str(info.value)


def test_unreadable_image_in_folder_is_named(tmp_path):
    cv2.imwrite(str(tmp_path / "a.png"), _frames(1)[0])
    (tmp_path / "b.png").write_bytes(b"\x89PNG broken")
    src = open_camera_source(str(tmp_path), paced=False)
    assert src.read() is not None
    with pytest.raises(CameraSourceError, match="b.png is not an image"):
        src.read()
    with pytest.raises(CameraSourceError, match="empty camera source"):
        open_camera_source("  ")


class _FakeKivyCamera:
    """Stands in for kivy.core.camera.Camera: a texture of RGBA bytes, bottom-up rows."""

    def __init__(self, w=8, h=6):
        self.size = (w, h)
        self.texture = None
        self.callbacks = []
        self.started = False

    def bind(self, on_texture):
        self.callbacks.append(on_texture)

    def unbind(self, on_texture):
        self.callbacks.remove(on_texture)

    def start(self):
        self.started = True

    def stop(self):
        self.started = False

    def show(self, rgba_top_down: np.ndarray):
        class _Tex:
            pass

        tex = _Tex()
        tex.size = self.size
        tex.pixels = np.ascontiguousarray(rgba_top_down[::-1]).tobytes()  # GL textures are bottom-up
        self.texture = tex
        for cb in list(self.callbacks):
            cb(self)


def test_kivy_camera_source_turns_textures_into_bgr_frames_newest_first():
    from app.ui.kivy_camera import KivyCameraSource

    cam = _FakeKivyCamera()
    src = KivyCameraSource(camera=cam, timeout_s=0.2)
    assert cam.started and src.live
    rng = np.random.default_rng(0)
    shown = [rng.integers(0, 256, (6, 8, 4), dtype=np.uint8) for _ in range(3)]
    cam.show(shown[0])
    first = src.read()
    np.testing.assert_array_equal(first.image, shown[0][..., 2::-1])  # RGBA top-down -> BGR top-down
    cam.show(shown[1])
    cam.show(shown[2])  # the grabber was late: frame 1 is replaced by frame 2
    second = src.read()
    np.testing.assert_array_equal(second.image, shown[2][..., 2::-1])
    assert src.replaced == 1 and second.index == 1
    with pytest.raises(CameraSourceError, match="no frame from the camera in 0.2 s"):
        src.read()
    src.close()
    assert not cam.started and cam.callbacks == []


def test_app_command_names_a_bad_camera_before_opening_a_window(tmp_path, capsys):
    from app.cli import main

    missing = tmp_path / "session.mp4"
    assert main(["app", "--camera", str(missing), "--db", str(tmp_path / "p.db")]) == 1
    err = capsys.readouterr().err
    assert f"camera {missing}: no such file or folder" in err and "Traceback" not in err
