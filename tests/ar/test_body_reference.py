"""ar.body against MediaPipe's own pipeline (issue 18): the stored reference in
tests/ar/data/blazepose/ was made once with mediapipe 0.10.21's legacy
``mp.solutions.pose.Pose(model_complexity=1)`` in a separate environment
(scripts/make_pose_reference.py, docs/notebook/pose.md) on synthetic renders: a human-proportioned
figure ("person": a walk and a jump) and StoryBeam's kid character (a walk, and a
pirouette in which both pipelines lose and find it again), 640x480, consecutive frames
at 30 fps.

Three modes, compared per landmark on the frames where both report a pose: ``static``
(detector on every frame), ``track`` (tracking, no smoothing), ``smooth`` (video mode);
all without StoryBeam's tile pass (``search=False``), which MediaPipe does not have (it
finds the pirouetting kid on frames where MediaPipe loses it).
The issue asks for 1 cm (world) and 2 px (image); measured on this desktop (docs/notebook/pose.md)
the two agree to float rounding (under 1e-4 px and 1e-4 cm) in every mode, since ar.body
replays MediaPipe's float32 arithmetic and OpenCV 4's crop to the bit. Asserted: the
issue's bounds everywhere, 0.05 px / 0.05 cm on the person, the same frames with a pose,
visibility within 1e-3 (the legacy solution leaves presence unset).
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from ar.body import BodyTracker, pose_runtime_available, track_frames
from ar.camera_sources import FrameListSource

DATA = Path(__file__).parent / "data" / "blazepose"
pytestmark = pytest.mark.skipif(not pose_runtime_available(),
                                reason="no TFLite interpreter: pip install ai-edge-litert (desktop)")
MODES = {"static": dict(smooth=False, track=False, search=False), "track": dict(smooth=False, redetect=False, search=False),
         "smooth": dict(smooth=True, redetect=False, search=False)}


@pytest.fixture(scope="module")
def reference():
    ref = np.load(DATA / "reference.npz")
    meta = json.loads(str(ref["meta"]))
    assert meta["mediapipe"] == "0.10.21" and "model_complexity=1" in meta["solution"]
    frames = {s: [cv2.imread(str(DATA / str(n))) for n in ref[f"{s}/frames"]] for s in meta["sequences"]}
    return ref, frames


@pytest.fixture(scope="module")
def agreement(reference):
    """mode -> sequence -> dict of per-landmark errors on the frames where both found a
    pose (px, cm, z in px, visibility) and both validity vectors. (Presence is not
    compared: the legacy solution leaves it unset, 0.)"""
    ref, frames = reference
    out: dict[str, dict] = {}
    for mode, kw in MODES.items():
        tracker = BodyTracker(**kw)
        out[mode] = {}
        for seq, imgs in frames.items():
            tracker.reset()
            err: dict[str, list] = {"px": [], "cm": [], "z": [], "vis": []}
            ours = []
            theirs = ref[f"{seq}/{mode}/valid"]
            for k, img in enumerate(imgs):
                pose = tracker.process(img, (k + 1) * 33333e-6)  # the legacy solution's clock
                ours.append(pose is not None)
                if pose is None or not theirs[k]:
                    continue
                im = ref[f"{seq}/{mode}/image"][k]
                err["px"].append(np.linalg.norm(pose.image_xy - im[:, :2], axis=1))
                err["cm"].append(100 * np.linalg.norm(pose.world - ref[f"{seq}/{mode}/world"][k], axis=1))
                err["z"].append(np.abs(pose.image_z - im[:, 2]))
                err["vis"].append(np.abs(pose.visibility - im[:, 3]))
            out[mode][seq] = {**{k: np.array(v) for k, v in err.items()}, "ours": np.array(ours), "theirs": theirs}
    return out


PERSON = ("person_walk", "person_jump")


@pytest.mark.parametrize("mode", sorted(MODES))
def test_agreement_with_mediapipe(agreement, mode):
    for seq, e in agreement[mode].items():
        assert (e["ours"] == e["theirs"]).all(), (seq, e["ours"], e["theirs"])  # a pose on the same frames
        assert e["theirs"].sum() >= 2, seq
        assert e["px"].max() <= 2.0 and e["cm"].max() <= 1.0, (seq, e["px"].max(), e["cm"].max())
        assert e["vis"].max() <= 1e-3, seq
        if seq in PERSON:
            assert e["theirs"].all(), seq
            assert e["px"].max() <= 0.05 and e["cm"].max() <= 0.05 and e["z"].max() <= 0.05, seq
    assert (agreement[mode]["kid_dance"]["theirs"] == False).any()  # noqa: E712 -- a lost body is part of the check


def test_smoothing_is_applied_as_mediapipe_s(reference):
    """Smoothing really changes the video (the reference's smoothed and unsmoothed runs
    differ), so agreeing with both modes checks the filters."""
    ref, _ = reference
    seq = "person_walk"
    change = np.abs(ref[f"{seq}/smooth/image"][1:, :, :2] - ref[f"{seq}/track/image"][1:, :, :2]).mean()
    assert change > 0.3  # pixels


def test_track_frames_on_a_camera_source(reference):
    _, frames = reference
    take = track_frames(FrameListSource(frames["person_walk"], fps=30.0), max_frames=10)
    assert len(take.poses) == 10 and take.detect_rate == 1.0 and take.fps == 30.0
    assert take.image_size == (640, 480) and len(take.pose_ms) == 10
    world, xy, vis, valid = take.arrays()
    assert valid.all() and np.isfinite(world).all()
    hips = xy[:, 23:25].mean(axis=1)
    assert (abs(hips[:, 0] - 320) < 60).all()  # the performer stands in the middle of the frame
    assert abs(world[:, 23:25].mean(axis=1)).max() < 0.05  # world origin: the hips' midpoint


def _shifted(img: np.ndarray, dx: float) -> np.ndarray:
    m = np.float32([[1, 0, dx], [0, 1, 0]])
    return cv2.warpAffine(img, m, (img.shape[1], img.shape[0]), borderMode=cv2.BORDER_REPLICATE)


@pytest.mark.parametrize("smooth", [False, True])
def test_a_lost_track_is_found_again_in_the_same_frame(reference, smooth):
    """The walk cut at frame 6 (the figure jumps 200 px sideways): the region tracked from
    frame 5 misses it. MediaPipe's graph (``redetect=False``) reports no pose for frame 6
    and detects on frame 7; StoryBeam's default detects again in frame 6 itself, and its
    pose there is the one a tracker meeting that frame fresh finds, to the bit.
    (``hold_s=0``: a jump of 200 px in one frame, 0.56 of the body region's side, is
    further than a person moves, so by default the tracker takes the body there for
    someone else until its match gate has widened: tests/ar/test_body_search.py.)"""
    _, frames = reference
    walk = frames["person_walk"]
    stream = walk[:6] + [_shifted(img, 200.0) for img in walk[6:]]
    found = {}
    for redetect in (False, True):
        tracker = BodyTracker(smooth=smooth, redetect=redetect, hold_s=0.0)
        found[redetect] = [tracker.process(img, (k + 1) / 30.0) for k, img in enumerate(stream)]
    assert [p is not None for p in found[False]] == [True] * 6 + [False] + [True] * 5
    assert all(p is not None for p in found[True])
    fresh = BodyTracker(smooth=smooth).process(stream[6], 7 / 30.0)
    np.testing.assert_array_equal(found[True][6].image_xy, fresh.image_xy)
    np.testing.assert_array_equal(found[True][6].world, fresh.world)
    # before the cut both trackers are MediaPipe's loop, bit for bit
    for a, b in zip(found[False][:6], found[True][:6]):
        np.testing.assert_array_equal(a.image_xy, b.image_xy)
