""""Act it out" (issue 18): the flow shared by the app and ``storybeam search --video``
(:mod:`app.services.act_it_out`), on a stand-in tracker and search: the take's length and
frame rate, the verdict and its reasons, the results, privacy (no frame outlives its
processing; nothing written, nothing of a frame logged), the teacher's switch (kept in
the profile), and the command line's refusals. The real pose estimator and search on a
rendered performance are in test_act_it_out_flow.py."""
from __future__ import annotations

import gc
import json
import logging
import sys
import threading
import weakref
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.services import act_it_out as act
from app.services.act_it_out import (
    LIFT_HEAD,
    NO_BODY,
    STEP_BACK,
    ActItOut,
    ActItOutError,
    ActLibrary,
    act_it_out_allowed,
    frame_problem,
    judge_poses,
    set_act_it_out_allowed,
)
from app.story.storage import ProfileStore
from ar.camera_sources import CameraFrame, CameraSource
from retrieval.motion import LANDMARK_INDEX, LANDMARK_NAMES

body = pytest.importorskip("ar.body", reason="the pose package ar.body is not in this checkout")

W, H = 640, 480
#: frame kinds the stand-in tracker answers: a whole body, one cut off at the bottom, a
#: bowed head, nobody
GOOD, CUT, BOWED, NOBODY = 0, 1, 2, 3


def standing_pose(kind: int = GOOD) -> "body.BodyPose":
    """A pose of a child standing in the middle of a 640x480 picture (head at the top,
    ankles near the bottom); CUT moves it down so the legs leave the picture, BOWED hides the face."""
    xy = np.zeros((33, 2), np.float32)
    xy[:, 0] = W / 2
    heights = {0: 70, 2: 62, 5: 62, 7: 66, 8: 66, 11: 120, 12: 120, 13: 180, 14: 180, 15: 230, 16: 230,
               23: 250, 24: 250, 25: 330, 26: 330, 27: 410, 28: 410, 29: 420, 30: 420, 31: 425, 32: 425}
    for i in range(33):
        xy[i, 1] = heights.get(i, 70)
        xy[i, 0] += (-1) ** i * 30 if i >= 11 else 0
    vis = np.ones(33, np.float32)
    if kind == CUT:
        xy[:, 1] += 160  # knees and ankles below the bottom edge
    if kind == BOWED:
        vis[:11] = 0.1
    world = np.random.default_rng(kind).normal(0, 0.3, (33, 3)).astype(np.float32)
    return body.BodyPose(image_xy=xy, image_z=np.zeros(33, np.float32), visibility=vis,
                         presence=np.ones(33, np.float32), world=world, score=1.0)


class KindSource(CameraSource):
    """A recording at ``fps`` whose frames are made fresh on each read (none kept here):
    pixel (0, 0) holds the frame's kind. ``made`` holds weak references to them."""

    def __init__(self, kinds: list[int], fps: float = 30.0, size=(W, H)):
        super().__init__("<kinds>")
        self.kinds, self.fps, self.size, self._next = list(kinds), fps, size, 0
        self.made: list[weakref.ref] = []

    def _grab(self):
        if self._next >= len(self.kinds):
            return None
        frame = np.zeros((self.size[1], self.size[0], 3), np.uint8)
        frame[0, 0, 0] = self.kinds[self._next]
        self._next += 1
        self.made.append(weakref.ref(frame))
        return frame


class FakeTracker:
    """Answers the pose of the kind written in the frame."""

    def __init__(self):
        self.calls = 0

    def process(self, frame, timestamp_s):
        self.calls += 1
        kind = int(frame[0, 0, 0])
        return None if kind == NOBODY else standing_pose(kind)


class FakeSearch:
    def __init__(self):
        self.calls = []

    def search_take(self, world, image_xy, valid, fps, image_size=None, k=5, exclude=()):
        self.calls.append({"T": len(valid), "valid": int(valid.sum()), "fps": fps, "size": image_size, "k": k,
                           "exclude": list(exclude), "world_finite": bool(np.isfinite(world[valid]).all())})
        return [f"hit{i}" for i in range(k)]


def flow(search=None) -> ActItOut:
    return ActItOut(search or FakeSearch(), tracker_factory=FakeTracker)


# ----------------------------------------------------------------------------- the verdict


def test_landmark_numbers_are_blazeposes():
    """One table of BlazePose's landmarks: the tracker's names are the verdict's indices."""
    assert body.LANDMARK_NAMES is LANDMARK_NAMES
    for name, i in LANDMARK_INDEX.items():
        assert body.LANDMARK_NAMES[i] == name
    assert [body.LANDMARK_NAMES[i] for i in act.FACE] == ["nose", "left_eye", "right_eye"]


def test_one_frame_is_judged_by_what_of_the_body_it_shows():
    assert frame_problem(standing_pose(GOOD), (W, H)) is None
    assert frame_problem(None, (W, H)) == NO_BODY
    assert frame_problem(standing_pose(CUT), (W, H)) == STEP_BACK
    assert frame_problem(standing_pose(BOWED), (W, H)) == LIFT_HEAD
    assert frame_problem(standing_pose(GOOD), (W, 400)) == STEP_BACK  # the ankles (y 410) below a 400-row picture
    hidden_knee = standing_pose(GOOD)
    hidden_knee.visibility[25] = 0.2
    assert frame_problem(hidden_knee, (W, H)) == STEP_BACK


@pytest.mark.parametrize("good, bad, kind, ok, reason", [
    (80, 20, CUT, True, None),  # exactly 80 %: enough
    (79, 21, CUT, False, STEP_BACK),
    (79, 21, BOWED, False, LIFT_HEAD),
    (40, 60, NOBODY, False, NO_BODY),
    (0, 0, GOOD, False, NO_BODY),  # an empty take
])
def test_a_take_needs_80_percent_of_frames_showing_the_whole_body(good, bad, kind, ok, reason):
    poses = [standing_pose(GOOD)] * good + [None if kind == NOBODY else standing_pose(kind)] * bad
    v = judge_poses(poses, (W, H))
    assert (v.ok, v.reason) == (ok, reason)
    assert v.frames == good + bad
    if poses:
        assert v.seen == pytest.approx(good / (good + bad))


def test_the_more_frequent_problem_is_the_prompt():
    poses = [standing_pose(GOOD)] * 5 + [standing_pose(CUT)] * 3 + [standing_pose(BOWED)] * 4 + [None] * 2
    v = judge_poses(poses, (W, H))
    assert not v.ok and v.reason == LIFT_HEAD and v.problems == {STEP_BACK: 3, LIFT_HEAD: 4, NO_BODY: 2}
    assert v.detected == pytest.approx(12 / 14)
    assert json.loads(json.dumps(v.as_dict()))["reason"] == LIFT_HEAD


# ----------------------------------------------------------------------------- the take


def test_a_take_lasts_its_seconds_on_the_cameras_clock():
    f = flow()
    source = KindSource([GOOD] * 300, fps=30.0)
    take = f.take_from_source(source, seconds=3.5)
    assert len(take.poses) == 105 and take.fps == 30.0 and take.image_size == (W, H)
    assert len(take.pose_ms) == 105 and f.tracker.calls == 106 - 1  # the 106th frame (at 3.5 s) is not tracked
    assert f.judge(take).ok
    rest = f.take_from_source(source, seconds=0)  # to the end of the recording
    assert len(rest.poses) == 300 - 106


def test_a_take_stops_when_the_recording_ends_or_when_told():
    f = flow()
    assert len(f.take_from_source(KindSource([GOOD] * 20)).poses) == 20
    stop = threading.Event()
    stop.set()
    assert f.take_from_source(KindSource([GOOD] * 20), stop=stop).poses == []
    assert len(f.take_from_source(KindSource([GOOD] * 20), max_frames=7).poses) == 7


def test_a_live_cameras_rate_comes_from_the_frame_times():
    class Live(KindSource):  # a device: no rate of its own, frames stamped by arrival (every 1/20 s here)
        def read(self):
            frame = self._grab()
            if frame is None:
                return None
            i = self._next - 1
            return CameraFrame(frame, i, 100.0 + i / 20.0)
    source = Live([GOOD] * 40)
    source.fps = None
    take = flow().take_from_source(source, seconds=1.0)
    assert len(take.poses) == 20 and take.fps == pytest.approx(20.0)


def test_a_picture_that_changes_size_mid_take_is_an_error():
    class Resizing(KindSource):
        def _grab(self):
            frame = super()._grab()
            return None if frame is None else (frame if self._next < 5 else np.zeros((240, 320, 3), np.uint8))
    with pytest.raises(ActItOutError, match="changed size during the take"):
        flow().take_from_source(Resizing([GOOD] * 10))


def test_the_preview_tracks_until_told_and_shows_every_frame():
    f = flow()
    shown = []
    source = KindSource([GOOD] * 50)
    n = f.watch(source, until=lambda: len(shown) >= 12, on_frame=lambda i, frame, pose: shown.append((i, pose)))
    assert n == 12 and [i for i, _ in shown] == list(range(12)) and all(p is not None for _, p in shown)
    take = f.take_from_source(source, seconds=1.0)  # the take goes on from the preview's next frame
    assert len(take.poses) == 30 and f.tracker.calls == 12 + 30  # the frame at 1.0 s is read, not tracked


def test_results_search_the_takes_landmarks():
    search = FakeSearch()
    f = flow(search)
    take = f.take_from_source(KindSource([GOOD] * 30 + [NOBODY] * 10 + [BOWED] * 5))
    assert f.results(take, k=4, exclude=("02_01",)) == ["hit0", "hit1", "hit2", "hit3"]
    assert search.calls == [{"T": 45, "valid": 35, "fps": 30.0, "size": (W, H), "k": 4, "exclude": ["02_01"],
                             "world_finite": True}]
    assert f.results(f.take_from_source(KindSource([NOBODY] * 10))) == []  # no body at all: nothing to search
    with pytest.raises(ActItOutError, match="no motion library"):
        ActItOut(None, tracker_factory=FakeTracker).results(take)


# ----------------------------------------------------------------------------- privacy


class _WriteWatch:
    """Records every file opened for writing while ``on`` (a Python audit hook)."""

    def __init__(self):
        self.on, self.writes = False, []
        sys.addaudithook(self._hook)

    def _hook(self, event, args):
        if self.on and event == "open" and len(args) > 1 and isinstance(args[1], str) \
                and any(c in args[1] for c in "wax+"):
            self.writes.append(args[0])


_WATCH = _WriteWatch()


def test_no_frame_outlives_the_take_and_nothing_is_written_or_logged(tmp_path, monkeypatch, caplog):
    monkeypatch.chdir(tmp_path)
    caplog.set_level(logging.DEBUG)
    f = flow()
    source = KindSource([GOOD] * 60 + [CUT] * 10)
    shown = []
    _WATCH.on = True
    try:
        f.watch(source, until=lambda: len(shown) >= 10, on_frame=lambda i, frame, pose: shown.append(frame.shape))
        take = f.take_from_source(source, seconds=1.5, on_frame=lambda i, frame, pose: shown.append(frame.shape))
        verdict = f.judge(take)
        hits = f.results(take)
    finally:
        _WATCH.on = False
    gc.collect()
    assert verdict.ok and hits and len(source.made) == 10 + 46
    alive = [r for r in source.made if r() is not None]
    assert alive == [], f"{len(alive)} camera frames are still referenced after the take"
    assert _WATCH.writes == [] and list(tmp_path.iterdir()) == []
    for record in caplog.records:  # counts only: no array of a frame (or of landmarks) in any log line
        assert not any(isinstance(a, np.ndarray) for a in (record.args or ())), record.getMessage()
        assert len(record.getMessage()) < 200
    # what the take keeps: landmarks (arrays of 33 points), not pictures
    world, image_xy, visibility, valid = take.arrays()
    assert world.shape == (45, 33, 3) and image_xy.shape == (45, 33, 2)
    assert not any(isinstance(v, np.ndarray) and v.ndim == 3 and v.shape[:2] == (H, W)
                   for v in vars(take).values())


def test_the_write_watch_can_fail(tmp_path):
    _WATCH.on = True
    try:
        (tmp_path / "frame.png").write_bytes(b"x")
    finally:
        _WATCH.on = False
    assert str(tmp_path / "frame.png") in map(str, _WATCH.writes)
    _WATCH.writes.clear()


# ----------------------------------------------------------------------------- library, teacher


def test_the_library_loads_once_in_the_background_and_reports_failure(tmp_path):
    built = []
    lib = ActLibrary(tmp_path, build=lambda folder: built.append(folder) or "search")
    called = []
    lib.when_ready(lambda: called.append(lib.search))
    assert lib.wait(10) and lib.search == "search" and built == [tmp_path] and called == ["search"]
    lib.when_ready(lambda: called.append("again"))  # ready: at once
    assert called == ["search", "again"]

    def broken(folder):
        raise ActItOutError(f"{folder}: no clips")
    bad = ActLibrary(tmp_path, build=broken)
    assert bad.wait(10) and bad.search is None and "no clips" in bad.error


def test_the_teachers_switch_is_kept_in_the_profile(tmp_path):
    db = tmp_path / "profile.db"
    with ProfileStore(db) as store:
        assert act_it_out_allowed(store)  # on by default
        set_act_it_out_allowed(store, False)
        assert not act_it_out_allowed(store)
    with ProfileStore(db) as store:  # reopened: still off
        assert not act_it_out_allowed(store)
        set_act_it_out_allowed(store, True)
        assert act_it_out_allowed(store)


# ----------------------------------------------------------------------------- the command line


@pytest.mark.parametrize("argv, message", [
    (["--video", "missing.mp4"], "--video missing.mp4: not found"),
    (["--video", "{tmp}/notes.txt"], "not a video file"),
    (["--video", "{tmp}/take.mp4", "--query", "{tmp}/q.bvh"], "give one of --query FILE or --pose FILE:FRAME or --video"),
    (["--query", "{tmp}/q.bvh", "--exclude", "02_01"], "--exclude goes with --video"),
    (["--video", "{tmp}/take.mp4", "--data", "{tmp}"], "a video search needs a labelled folder"),
])
def test_search_by_video_refuses_bad_input_plainly(tmp_path, capsys, argv, message):
    (tmp_path / "notes.txt").write_text("not a video")
    (tmp_path / "take.mp4").write_bytes(b"\0" * 10)
    (tmp_path / "q.bvh").write_text("")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(["search", *argv]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_search_by_video_says_when_the_pose_estimator_is_missing(tmp_path, capsys, monkeypatch):
    (tmp_path / "take.mp4").write_bytes(b"\0" * 10)
    monkeypatch.setattr(act, "pose_runtime_problem", lambda: "no TFLite runtime (stand-in)")
    assert main(["search", "--video", str(tmp_path / "take.mp4"), "--data", str(Path("assets/motions"))]) == 1
    assert "no TFLite runtime (stand-in)" in capsys.readouterr().err
