"""The live rig's path, fed a recorded handheld session with known truth.

The session (:func:`ar.synthetic.record_rig_session`: a moving hand-held rig, a quick
turn with motion blur, noise, an exposure dip, a hand over the board) is written as a
folder of PNGs and as an MP4, then played -- paced at 30 fps, like a camera -- through the
same path the app uses: a camera source, :class:`ar.live.LiveTracker` (grabber and
tracker threads, newest frame wins) stepping the rig's frame loop
(:class:`ar.rig.RigTracker`: the region search and the Kalman tracker). Each
test prints the pose error, the detect rate and the frames dropped.
"""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from ar.boards import DEFAULT_BOARD_SPEC, Board
from ar.camera_sources import CameraSourceError, FrameListSource, open_camera_source
from ar.filtering import HOLDING, TRACKING
from ar.geometry import pose_error
from ar.live import LiveTracker
from ar.pose import RegionPoseEstimator
from ar.rig import LiveRig, RigTracker, SyntheticRig, open_rig
from ar.synthetic import SessionConfig, SyntheticCamera, load_session_truth, record_rig_session

pytestmark = pytest.mark.slow  # records a board session and plays it through the live rig's threads

N_FRAMES = 90


@pytest.fixture(scope="module")
def board():
    return Board(DEFAULT_BOARD_SPEC)


@pytest.fixture(scope="module")
def session(board, tmp_path_factory):
    folder = tmp_path_factory.mktemp("rig_session")
    rec = record_rig_session(board, N_FRAMES, cfg=SessionConfig(supersample=1, seed=3))
    written = rec.write(folder / "frames", video="session.mp4")
    return rec, written


def _play(source, board, truth, camera_K, camera_dist, estimator=None):
    results = []
    live = LiveTracker(source, RigTracker(board, camera_K, camera_dist, estimator=estimator), on_result=results.append)
    with live:
        assert live.wait(120), "the recording did not play through"
    stats = live.stats()
    errors = np.array([pose_error(r.estimate.T_cam_from_board, truth[r.frame_index])
                       for r in results if r.estimate is not None]).reshape(-1, 2)
    return results, stats, errors


def _report(name, results, stats, errors):
    rot, mm = (np.median(errors, 0) if len(errors) else (np.nan, np.nan))
    p95 = np.percentile(errors, 95, 0) if len(errors) else (np.nan, np.nan)
    print(f"\n{name}: {stats.captured} frames captured, {stats.processed} processed, {stats.dropped} dropped; "
          f"detected in {stats.detected}/{stats.processed} = {100 * stats.detected / max(1, stats.processed):.1f} %; "
          f"pose error median {rot:.3f} deg / {mm:.3f} mm, p95 {p95[0]:.3f} deg / {p95[1]:.3f} mm; "
          f"detect+pose median {np.median([r.detect_pose_ms for r in results]):.1f} ms")


def test_session_is_what_it_claims(session, board):
    """Blur, exposure dip and hand really happen, and the frames are not clean renders."""
    rec, written = session
    assert len(rec.frames) == len(rec.poses) == N_FRAMES
    assert rec.blur_px.max() > 2.5 and np.median(rec.blur_px) < 1.5
    assert rec.exposure.min() < 0.6 and rec.exposure.max() > 1.0
    assert rec.hand.max() == pytest.approx(0.3, abs=0.02) and (rec.hand > 0.1).sum() >= 15
    clean = SyntheticCamera(board, camera=rec.camera, supersample=1).render(rec.poses[40])
    assert np.abs(clean.astype(int) - rec.frames[40]).mean() > 2.0
    truth = load_session_truth(written["folder"])
    np.testing.assert_allclose(truth["poses"], np.asarray(rec.poses))
    assert float(truth["fps"]) == rec.fps and written["video"].is_file()


def test_recorded_session_plays_through_the_live_path(session, board):
    rec, written = session
    truth = load_session_truth(written["folder"])
    source = open_camera_source(str(written["folder"]), fps=float(truth["fps"]))  # paced, as a camera
    results, stats, errors = _play(source, board, truth["poses"], truth["K"], truth["dist"])
    _report("PNG session", results, stats, errors)
    assert stats.error is None and stats.captured == N_FRAMES
    assert stats.processed + stats.dropped == stats.captured  # every frame is handled or counted dropped
    idx = [r.frame_index for r in results]
    assert idx == sorted(set(idx))  # newest first, never an older frame after a newer one
    assert stats.detected / stats.processed >= 0.85
    assert np.median(errors[:, 0]) < 0.3 and np.median(errors[:, 1]) < 1.0
    assert np.median(errors[:, 1]) > 0.0  # measured, not the truth handed back
    states = {r.output.state for r in results}
    assert TRACKING in states
    # the hand and the blur cost detections, and the tracker held the pose through them
    missed = [r.frame_index for r in results if r.estimate is None]
    assert not missed or HOLDING in states


def test_recorded_video_plays_through_the_live_path(session, board):
    rec, written = session
    truth = load_session_truth(written["folder"])
    source = open_camera_source(str(written["video"]))
    results, stats, errors = _play(source, board, truth["poses"], truth["K"], truth["dist"])
    _report("MP4 session (lossy mp4v)", results, stats, errors)
    assert stats.captured == N_FRAMES and stats.processed + stats.dropped == stats.captured
    assert stats.detected / stats.processed >= 0.8
    assert np.median(errors[:, 0]) < 0.5 and np.median(errors[:, 1]) < 2.0


class _SlowEstimator(RegionPoseEstimator):
    """Takes three frame periods per frame, and notes how many frames had arrived when it began."""

    def __init__(self, *args, live_ref, period_s, **kw):
        super().__init__(*args, **kw)
        self.live_ref = live_ref
        self.period_s = period_s
        self.seen_captured: list[int] = []

    def estimate(self, image, select=None, **kw):
        self.seen_captured.append(self.live_ref[0].stats().captured)
        time.sleep(3 * self.period_s)
        return super().estimate(image, select, **kw)


def test_a_slow_tracker_drops_frames_and_always_takes_the_newest(session, board):
    rec, _ = session
    frames = rec.frames[:30]
    live_ref = []
    est = _SlowEstimator(board, rec.camera.K, rec.camera.dist, live_ref=live_ref, period_s=1 / 30)
    results = []
    live = LiveTracker(FrameListSource(frames, fps=30.0, paced=True),
                       RigTracker(board, rec.camera.K, rec.camera.dist, estimator=est), on_result=results.append)
    live_ref.append(live)
    with live:
        assert live.wait(60)
    stats = live.stats()
    print(f"\nslow tracker: {stats.captured} captured, {stats.processed} processed, {stats.dropped} dropped")
    assert stats.captured == 30 and stats.processed + stats.dropped == 30
    assert stats.dropped >= 10  # three frame times per frame: about two of three are dropped
    # newest wins: each frame processed was the last one captured when the tracker took it
    for r, seen in zip(results, est.seen_captured):
        assert r.frame_index >= seen - 2, (r.frame_index, seen)
    assert results[-1].frame_index == 29  # the last frame is never lost


def test_latest_never_blocks_while_tracking(session, board):
    rec, _ = session
    live = LiveTracker(FrameListSource(rec.frames[:20], fps=30.0, paced=True),
                       RigTracker(board, rec.camera.K, rec.camera.dist))
    waits = []
    with live:
        while live.stats().running:
            t0 = time.perf_counter()
            live.latest()
            waits.append(time.perf_counter() - t0)
            time.sleep(0.005)
    assert live.latest() is not None and live.latest().frame_index == 19
    assert threading.current_thread() is threading.main_thread()
    assert np.median(waits) < 0.005  # a lock read, not a detection (which takes milliseconds)


def test_the_app_opens_a_recording_as_its_live_rig(session, board, tmp_path):
    """``open_rig`` with a recording (``storybeam app --camera dir/``): a live rig tracked on
    its own threads, calibration from the recording's folder; without calibration files,
    or with a source that does not open, the synthetic rig (never an exception)."""
    pytest.importorskip("pyrender")  # the stage draws the light with the pyrender renderer
    rec, written = session
    rig = open_rig(None, board, camera=str(written["folder"]))
    try:
        assert isinstance(rig, LiveRig) and rig.live
        assert rig.step().image.shape == (480, 640, 3)
        deadline = time.monotonic() + 20
        while rig.stats().detected < 5 and time.monotonic() < deadline:
            time.sleep(0.05)
        state = rig.step()
        assert rig.stats().detected >= 5 and state.state in (TRACKING, HOLDING)
        assert state.T_proj_from_board is not None  # the projector's pose, through projector.json
        # the projector stage draws the demo story's characters from the live rig's newest pose
        from app.player.stage import StageRenderer
        from app.story.demo_story import demo_story

        stage = StageRenderer(rig=rig)
        shot = stage.render(demo_story().scenes[0], 1.0)
        assert shot.live and shot.state in (TRACKING, HOLDING) and shot.problems == []
        assert shot.projector.shape == (480, 640, 3) and shot.projector.max() > 100  # light where they stand
        assert len(shot.character_px) == 2
        stage.close()  # the projector's GL context, and the rig (closing it twice is harmless)
    finally:
        rig.close()
    assert isinstance(open_rig(None, board, camera=str(tmp_path)), SyntheticRig)  # no images, no calibration
    assert isinstance(open_rig(written["folder"], board, camera=str(tmp_path / "nope.mp4")), SyntheticRig)
    assert isinstance(open_rig(None, board, camera=None), SyntheticRig)


class _DyingSource(FrameListSource):
    """Sends a few frames, then fails like an unplugged camera."""

    def _grab(self):
        if self._next >= 3:
            raise CameraSourceError(self.name, "the camera stopped sending frames")
        return super()._grab()


def test_a_camera_that_dies_is_reported_not_hung(session, board):
    rec, _ = session
    live = LiveTracker(_DyingSource(rec.frames[:10], fps=30.0, name="usb0"), RigTracker(board, rec.camera.K, rec.camera.dist))
    with live:
        assert live.wait(20)
    stats = live.stats()
    assert stats.error == "camera usb0: the camera stopped sending frames"
    assert stats.captured == 3 and stats.processed + stats.dropped == 3 and not stats.running
