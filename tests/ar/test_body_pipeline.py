"""ar.body's pieces, each against MediaPipe's calculators' maths: SSD anchors, detection
decoding, weighted NMS, letterbox, the body region, crop and projection, heatmap
refinement, the one-euro filters; model-file and runtime errors; BodyTake."""
from __future__ import annotations

import shutil
import sys

import cv2
import numpy as np
import pytest

from ar.body import (
    DEFAULT_MODEL_DIR,
    LANDMARK_NAMES,
    MODEL_FILES,
    BodyPose,
    BodyTake,
    BodyTracker,
    PoseModelError,
    pose_runtime_available,
)
from ar.body import blazepose as bp
from ar.body.smoothing import LANDMARKS, LowPassFilter, OneEuroConfig, OneEuroFilter
from retrieval.errors import StoryBeamError

needs_runtime = pytest.mark.skipif(not pose_runtime_available(),
                                   reason="no TFLite interpreter: pip install ai-edge-litert (desktop)")


# ---------------------------------------------------------------------------- detector
def test_ssd_anchors_match_the_graph():
    a = bp.ssd_anchors()
    assert a.shape == (bp.NUM_ANCHORS, 2) == (2254, 2)
    # stride 8: a 28x28 map, two anchors per cell, row-major (x fastest)
    np.testing.assert_allclose(a[0], [0.5 / 28, 0.5 / 28])
    np.testing.assert_allclose(a[1], a[0])
    np.testing.assert_allclose(a[2], [1.5 / 28, 0.5 / 28])
    np.testing.assert_allclose(a[2 * 28], [0.5 / 28, 1.5 / 28])
    # stride 16 starts after 28*28*2; the three stride-32 layers share a 7x7 map, 6 per cell
    np.testing.assert_allclose(a[1568], [0.5 / 14, 0.5 / 14])
    np.testing.assert_allclose(a[1568 + 392: 1568 + 392 + 6], [[0.5 / 7, 0.5 / 7]] * 6)
    np.testing.assert_allclose(a[-1], [6.5 / 7, 6.5 / 7])


def test_decoding_scales_offsets_by_224_around_the_anchor():
    anchors = np.array([[0.25, 0.5], [0.75, 0.75]], np.float32)
    raw = np.zeros((2, 12), np.float32)
    raw[0, :4] = [22.4, -11.2, 44.8, 22.4]  # x, y offsets and w, h in 224ths
    raw[0, 4:6] = [0.0, 22.4]  # keypoint 0
    scores = np.array([2.0, -1.0], np.float32)  # sigmoid 0.88 and 0.27
    dets = bp.decode_detections(raw, scores, anchors)
    assert len(dets) == 1
    d = dets[0]
    assert d.score == pytest.approx(1 / (1 + np.exp(-2.0)))
    np.testing.assert_allclose(d.box, [0.35 - 0.1, 0.45 - 0.05, 0.2, 0.1], atol=1e-6)
    np.testing.assert_allclose(d.keypoints[0], [0.25, 0.6], atol=1e-6)
    np.testing.assert_allclose(d.keypoints[1], [0.25, 0.5], atol=1e-6)
    # scores are clipped at +-100 before the sigmoid: no overflow, still a score
    assert len(bp.decode_detections(raw, np.array([1e6, -1e6], np.float32), anchors)) == 1


def _det(score, box, kp=0.0):
    return bp.Detection(score, np.array(box, np.float32), np.full((4, 2), kp, np.float32))


def test_weighted_nms_merges_overlaps_by_score_and_keeps_the_rest():
    a = _det(0.9, [0.0, 0.0, 1.0, 1.0], 0.0)
    b = _det(0.6, [0.1, 0.0, 1.0, 1.0], 1.0)  # IoU 0.82 with a
    c = _det(0.7, [3.0, 3.0, 1.0, 1.0], 5.0)  # far away
    out = bp.weighted_nms([b, c, a])
    assert [round(d.score, 2) for d in out] == [0.9, 0.7]
    w = np.array([0.9, 0.6]) / 1.5
    np.testing.assert_allclose(out[0].box, [w @ [0.0, 0.1], 0.0, 1.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(out[0].keypoints, np.full((4, 2), w @ [0.0, 1.0]), atol=1e-6)
    np.testing.assert_allclose(out[1].keypoints, 5.0)
    # IoU exactly at or below 0.3 is kept apart
    assert bp.iou(np.array([0, 0, 1, 1.0]), np.array([0.5, 0, 1, 1.0])) == pytest.approx(1 / 3)
    assert len(bp.weighted_nms([_det(0.9, [0, 0, 1, 1]), _det(0.8, [0.6, 0, 1, 1])])) == 2
    assert bp.iou(np.array([0, 0, 1, 1.0]), np.array([2, 2, 1, 1.0])) == 0.0


def test_letterbox_pads_the_short_side_and_is_removed():
    matrix, pad = bp.letterbox_transform((640, 480))
    assert pad == (0.0, 0.125)
    corners = cv2.perspectiveTransform(np.array([[[0, 0], [640, 480]]], np.float32), matrix)[0]
    np.testing.assert_allclose(corners, [[0, 28], [224, 196]], atol=1e-3)  # 480/640*224 = 168 tall, centred
    d = bp.remove_letterbox(_det(0.9, [0.25, 0.125, 0.5, 0.75], 0.125), pad)
    np.testing.assert_allclose(d.box, [0.25, 0.0, 0.5, 1.0], atol=1e-6)
    np.testing.assert_allclose(d.keypoints[:, 1], 0.0, atol=1e-6)


# ---------------------------------------------------------------------------- region
def test_roi_from_hip_and_body_point():
    size = (640, 480)
    hip = np.array([0.5, 0.5])
    up = np.array([0.5, 0.5 - 100 / 480])  # 100 px straight above the hips: upright body
    r = bp.roi_from_points(hip, up, size)
    assert r.rotation == pytest.approx(0.0, abs=1e-9)
    assert (r.x_center, r.y_center) == (0.5, 0.5)
    assert r.width * 640 == pytest.approx(2 * 100 * 1.25) and r.height * 480 == pytest.approx(250)
    right = np.array([0.5 + 100 / 640, 0.5])  # body lying towards the image's right
    assert bp.roi_from_points(hip, right, size).rotation == pytest.approx(np.pi / 2)
    left = np.array([0.5 - 100 / 640, 0.5])
    assert bp.roi_from_points(hip, left, size).rotation == pytest.approx(-np.pi / 2)
    assert bp.normalize_radians(3 * np.pi / 2) == pytest.approx(-np.pi / 2)


def test_degenerate_regions_are_refused():
    hip = np.array([0.5, 0.5])
    r = bp.roi_from_points(hip, hip, (640, 480))  # both keypoints on one spot: no size
    assert not r.usable and bp.Rect(0.5, 0.5, 0.2, 0.3).usable
    assert not bp.Rect(float("nan"), 0.5, 0.2, 0.3).usable
    with pytest.raises(ValueError, match="degenerate region"):
        bp.rect_transform(r, (640, 480), 256)
    corners = np.zeros((4, 2), np.float32)  # all corners on one point
    with pytest.raises(ValueError, match="degenerate region: singular"):
        bp.perspective_transform(corners, np.array([[0, 256], [0, 0], [256, 0], [256, 256]], np.float32))


def test_crop_and_projection_are_inverse():
    """A dot placed in the frame lands where the crop says, and projecting its crop
    position back gives the frame position (rotated regions included)."""
    img = np.zeros((480, 640, 3), np.uint8)
    cv2.circle(img, (400, 200), 3, (255, 255, 255), -1)
    for rot in (0.0, 0.5, -2.0):
        rect = bp.Rect(380 / 640, 230 / 480, 200 / 640, 200 / 480, rot)
        matrix, padding = bp.rect_transform(rect, (640, 480), 256)
        assert padding == (0.0, 0.0)  # a square region needs no letterbox
        x = bp.warp_to_tensor(img, matrix, 256, (0.0, 1.0), cv2.BORDER_REPLICATE)
        ys, xs = np.nonzero(x[0, ..., 0] > 0.5)
        crop = np.array([[xs.mean() / 256, ys.mean() / 256, 0, 0, 0]])
        back = bp.project_landmarks(crop, rect)[0, :2] * (640, 480)
        np.testing.assert_allclose(back, [400, 200], atol=0.8)
    m, _ = bp.rect_transform(bp.Rect(0.5, 0.5, 0.4, 0.5, 0.3), (640, 480), 256)
    xy, frac = bp.warp_maps(m, 256)
    assert xy.dtype == np.int16 and frac.dtype == np.uint16 and frac.max() < 1024


def test_opencv4_geometry_is_replayed():
    """The corner points, perspective solve and inverse are OpenCV's (checked here against
    the installed OpenCV: the inverse exactly; the corners and matrix to rounding, since
    OpenCV 5 rounds the last bits differently from the OpenCV 4 inside MediaPipe)."""
    corners = bp.box_points(300.5, 200.25, 180.0, 120.0, 17.0)
    np.testing.assert_allclose(corners, cv2.boxPoints(((300.5, 200.25), (180.0, 120.0), 17.0)), atol=1e-4)
    dst = np.array([[0, 256], [0, 0], [256, 0], [256, 256]], np.float32)
    m = bp.perspective_transform(corners, dst)
    np.testing.assert_allclose(m, cv2.getPerspectiveTransform(corners, dst), atol=1e-6)
    np.testing.assert_array_equal(bp.invert_3x3(m), cv2.invert(m)[1])
    # the fixed-point maps are the inverse mapping in 1/32 pixel: as OpenCV's convertMaps
    # rounds the float maps of the same inverse (a tie may round the other way)
    xy, frac = bp.warp_maps(m, 256)
    inv = np.linalg.inv(m)
    gy, gx = np.mgrid[0:256, 0:256].astype(np.float64)
    den = inv[2, 0] * gx + inv[2, 1] * gy + inv[2, 2]
    mx = ((inv[0, 0] * gx + inv[0, 1] * gy + inv[0, 2]) / den).astype(np.float32)
    my = ((inv[1, 0] * gx + inv[1, 1] * gy + inv[1, 2]) / den).astype(np.float32)
    cxy, cfrac = cv2.convertMaps(mx, my, cv2.CV_16SC2)
    ours = xy.astype(np.int64) * 32 + np.stack([frac & 31, frac >> 5], -1)
    theirs = cxy.astype(np.int64) * 32 + np.stack([cfrac & 31, cfrac >> 5], -1)
    assert np.abs(ours - theirs).max() <= 1 and (ours != theirs).mean() < 0.01


def test_world_rotation_and_landmark_decoding():
    w = np.array([[1.0, 0.0, 0.3]])
    np.testing.assert_allclose(bp.rotate_world(w, np.pi / 2), [[0.0, 1.0, 0.3]], atol=1e-6)
    raw = np.zeros(39 * 5, np.float32)
    raw[:5] = [128, 64, 25.6, 0.0, 100.0]
    lm = bp.decode_landmarks(raw)
    np.testing.assert_allclose(lm[0], [0.5, 0.25, 0.1, 0.5, 1.0], atol=1e-6)


def test_heatmap_refinement_moves_confident_landmarks_only():
    hm = np.full((1, 64, 64, 39), -10.0, np.float32)
    hm[0, 10, 20, 0] = 10.0  # landmark 0: a confident peak at row 10, col 20
    hm[0, 40, 40, 1] = -0.5  # landmark 1: nothing above 0.5 confidence
    lm = np.zeros((39, 5), np.float32)
    lm[:, :2] = 0.9
    lm[0, :2] = [22 / 64, 12 / 64]  # within the 7x7 window of the peak
    lm[1, :2] = [40 / 64, 40 / 64]
    lm[2, :2] = [-0.5, 0.5]  # outside the map: kept
    out = bp.refine_from_heatmap(lm, hm)
    np.testing.assert_allclose(out[0, :2], [20 / 64, 10 / 64], atol=1e-3)
    np.testing.assert_allclose(out[1:, :2], lm[1:, :2])


# ---------------------------------------------------------------------------- smoothing
def test_one_euro_filter_follows_mediapipe():
    f = OneEuroFilter(OneEuroConfig(min_cutoff=1.0, beta=0.0))
    assert f.apply(np.array([5.0]), 0.1)[0] == 5.0  # first value passes
    # 30 Hz from then on: alpha = 1 / (1 + tau / te), tau = 1 / (2 pi), te = 1 / 30
    alpha = 1 / (1 + (1 / (2 * np.pi)) * 30)
    out = f.apply(np.array([6.0]), 0.1 + 1 / 30)[0]
    assert out == pytest.approx(5.0 + alpha * 1.0)
    assert f.apply(np.array([9.0]), 0.1)[0] == 9.0  # a timestamp not after the last: unfiltered
    # a fast mover is followed more closely than a slow one (beta)
    slow, fast = OneEuroFilter(LANDMARKS), OneEuroFilter(LANDMARKS)
    for k in range(10):
        s = slow.apply(np.array([0.1 * k]), k / 30, value_scale=1 / 200)
        q = fast.apply(np.array([20.0 * k]), k / 30, value_scale=1 / 200)
    assert abs(q[0] - 180.0) / 180.0 < abs(s[0] - 0.9) / 0.9
    lp = LowPassFilter(0.1)
    assert lp.apply(np.array([1.0]))[0] == 1.0 and lp.apply(np.array([0.0]))[0] == pytest.approx(0.9)


# ---------------------------------------------------------------------------- errors
def test_landmark_names():
    assert len(LANDMARK_NAMES) == 33 and LANDMARK_NAMES[0] == "nose"
    assert LANDMARK_NAMES[11:13] == ("left_shoulder", "right_shoulder")
    assert LANDMARK_NAMES[23:25] == ("left_hip", "right_hip")
    assert LANDMARK_NAMES[31:] == ("left_foot_index", "right_foot_index")


def test_missing_or_altered_model_files_name_the_file(tmp_path):
    with pytest.raises(PoseModelError, match="pose_detection.tflite: pose model file not found"):
        BodyTracker(model_dir=tmp_path)
    for role, (name, _) in MODEL_FILES.items():
        shutil.copy(DEFAULT_MODEL_DIR / name, tmp_path / name)
    (tmp_path / "pose_landmark_full.tflite").write_bytes(b"not a model")
    if pose_runtime_available():
        with pytest.raises(PoseModelError, match=r"pose_landmark_full.tflite: pose model file altered: sha256"):
            BodyTracker(model_dir=tmp_path)
    assert isinstance(PoseModelError("x"), StoryBeamError)


def test_vendored_models_match_their_hashes():
    from ar.body.models import model_path

    for role in MODEL_FILES:
        assert model_path(role).is_file()  # raises on a hash mismatch
    readme = (DEFAULT_MODEL_DIR / "README.md").read_text(encoding="utf-8")
    assert all(digest in readme for _, digest in MODEL_FILES.values()) and "mediapipe" in readme
    assert "Apache License" in (DEFAULT_MODEL_DIR / "LICENSE").read_text(encoding="utf-8")


def test_without_an_interpreter_the_tracker_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "ai_edge_litert", None)
    monkeypatch.setitem(sys.modules, "ai_edge_litert.interpreter", None)
    monkeypatch.setitem(sys.modules, "tflite_runtime", None)
    monkeypatch.setitem(sys.modules, "tflite_runtime.interpreter", None)
    assert not pose_runtime_available()
    with pytest.raises(PoseModelError, match="no TFLite interpreter: install ai-edge-litert"):
        BodyTracker()


@needs_runtime
def test_bad_frames_are_refused_clearly():
    tracker = BodyTracker()
    with pytest.raises(StoryBeamError, match="expected a BGR uint8 frame"):
        tracker.process(np.zeros((480, 640), np.uint8), 0.0)
    assert tracker.process(np.zeros((480, 640, 3), np.uint8), 0.0) is None  # nobody there
    assert tracker.timing.detected


# ---------------------------------------------------------------------------- take
def _pose(v: float) -> BodyPose:
    z = np.full(33, v, np.float32)
    return BodyPose(np.full((33, 2), v, np.float32), z, z, z, np.full((33, 3), v, np.float32), 0.9)


def test_body_take_arrays_and_rates():
    take = BodyTake([_pose(1.0), None, _pose(2.0), None], 30.0, (640, 480), [10.0, 4.0, 12.0, 5.0])
    world, xy, vis, valid = take.arrays()
    assert world.shape == (4, 33, 3) and xy.shape == (4, 33, 2) and vis.shape == (4, 33)
    assert valid.tolist() == [True, False, True, False]
    assert np.isnan(world[1]).all() and np.isnan(xy[3]).all() and (vis[1] == 0).all()
    assert world[2, 0, 0] == 2.0
    assert take.detect_rate == 0.5 and take.pose_ms_median == 7.5
    assert BodyTake([], 30.0, (0, 0)).detect_rate == 0.0
