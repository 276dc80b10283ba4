"""`storybeam bench act-it-out --videos DIR` (lab/bench/act_videos.py, issue 27): a folder of
real clips with labels.csv through the product's flow.

* the folder's labels.csv is checked (file and line in every message);
* the figures (per-class top-1/top-k, balanced accuracy, confusion matrix with a ``none``
  column, clips with a body in >= 95 % of frames) come out right on known per-clip results,
  and the confusion picture is drawn;
* end to end on the committed real clip (tests/lab/data/act_real/: a rugby drop kick from
  lucamagnasco/human_pose_test, MIT, cut and downscaled) with the real pose estimator and the
  bundled library: the JSON has every key, the body is found, the landmark cache is reused.
  Skipped, saying why, without a TFLite interpreter. The whole development set
  (/work/data/act_real, made by scripts/act_real.py) is the bench's, not the tests'.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from lab.bench.act_videos import (NONE, VideoSetError, confusion, draw_confusion, format_videos_table,
                                  read_video_labels, summarise)

DATA = Path(__file__).resolve().parent / "data" / "act_real"


def _clip(label: str, predicted: str, in_top: bool, detect: float = 1.0) -> dict:
    return {"file": f"{label}.mp4", "label": label, "predicted": predicted, "in_top3": in_top, "detect_rate": detect}


@pytest.mark.parametrize("labels, message", [
    (None, "no labels.csv"),
    ("clip,class\na.mp4,walk\n", r"labels.csv:1: expected the columns file,label"),
    ("file,label\nb.mp4,walk\n", r"labels.csv:2: .*b.mp4 not found"),
    ("file,label\na.mp4,walk\nnotes.txt,run\n", r"labels.csv:3: notes.txt is not a video"),
    ("file,label\na.mp4,\n", r"labels.csv:2: empty file or label"),
    ("file,label\n", r"labels.csv: no clips listed"),
])
def test_labels_csv_problems_name_the_file_and_line(labels, message, tmp_path):
    (tmp_path / "a.mp4").write_bytes(b"")
    if labels is not None:
        (tmp_path / "labels.csv").write_text(labels)
    with pytest.raises(VideoSetError, match=message):
        read_video_labels(tmp_path)


def test_a_good_labels_csv_lists_the_clips(tmp_path):
    (tmp_path / "a.mp4").write_bytes(b"")
    (tmp_path / "labels.csv").write_text("file,label\na.mp4,walk\n")
    assert read_video_labels(tmp_path) == [(tmp_path / "a.mp4", "walk")]


def test_figures_from_known_answers():
    clips = [_clip("jump", "jump", True), _clip("jump", "walk", True), _clip("jump", "walk", False, 0.5),
             _clip("walk", "walk", True), _clip("kick", NONE, False, 0.0), _clip("kick", "kick", True, 0.96)]
    r = summarise(clips, top=3)
    assert r["classes"] == ["walk", "jump", "kick"]  # the project's class order, those present
    assert r["per_class"]["jump"] == {"clips": 3, "top1": pytest.approx(1 / 3), "top3": pytest.approx(2 / 3),
                                      "detect_rate_median": 1.0}
    assert r["accuracy_top1"] == pytest.approx(3 / 6) and r["accuracy_top3"] == pytest.approx(4 / 6)
    assert r["balanced_top1"] == pytest.approx((1 + 1 / 3 + 1 / 2) / 3)
    cols = r["confusion_columns"]
    assert cols == ["walk", "run", "jump", "kick", "dance", NONE]
    m = {c: dict(zip(cols, row)) for c, row in zip(r["classes"], r["confusion"])}
    assert m["jump"]["jump"] == 1 and m["jump"]["walk"] == 2 and m["kick"][NONE] == 1 and m["kick"]["kick"] == 1
    assert sum(map(sum, r["confusion"])) == len(clips)
    assert r["clips_body_95"] == 4  # 1.0, 1.0, 1.0 and 0.96 of the frames; not 0.5 nor 0.0


def test_an_answer_outside_the_columns_counts_as_none():
    assert confusion(["walk", "walk"], ["walk", "teleport"], ["walk"], ["walk", NONE]) == [[1, 1]]


def test_confusion_picture_is_drawn(tmp_path):
    import cv2

    path = draw_confusion([[3, 1, 0], [0, 2, 1]], ["walk", "jump"], ["walk", "jump", NONE], tmp_path / "c.png", "t")
    img = cv2.imread(str(path))
    assert img is not None and img.shape[0] > 200 and img.shape[1] > 300
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 10  # cells, text and axes, not a blank page


def test_table_lists_classes_and_marks_misses():
    clips = [dict(_clip("jump", "walk", True), top=[{"label": "walk"}, {"label": "jump"}], frames=90, fps=30.0,
                  image_size=[640, 480])]
    r = summarise(clips, 3)
    r.update({"clips": clips, "pose_ms_median": 12.0, "pose_frames": 90, "search_ms_median": 5.0, "pinned_cpu": 0,
              "library_clips": 37})
    text = format_videos_table(r)
    assert "| jump | 1 | 0.00 | 1.00 | 100% |" in text and "| jump.mp4 | jump | walk ✗ | walk,jump | - | 100% |" in text


@pytest.fixture()
def runtime():
    """Skips without the pose runtime; gives the test process its CPUs and OpenCV threads
    back afterwards (the bench pins itself to one core)."""
    import os

    import cv2
    from ar.body import pose_runtime_available

    if not pose_runtime_available():
        pytest.skip("no TFLite interpreter (ai-edge-litert) installed: the bench needs the pose estimator")
    cpus = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    threads = cv2.getNumThreads()
    yield
    cv2.setNumThreads(threads)
    if cpus is not None:
        os.sched_setaffinity(0, cpus)


@pytest.mark.slow
def test_bench_on_the_committed_real_clip(runtime, tmp_path, capsys):
    from app.paths import MOTIONS_DIR

    assert read_video_labels(DATA), f"{DATA} should hold the committed real clips"
    out, cache = tmp_path / "v.json", tmp_path / "cache"
    argv = ["bench", "act-it-out", "--videos", str(DATA), "--data", str(MOTIONS_DIR), "--json", str(out),
            "--cache", str(cache), "--quiet"]
    assert main(argv) == 0
    r = json.loads(out.read_text())
    assert set(r) >= {"per_class", "accuracy_top1", "accuracy_top3", "balanced_top1", "confusion", "clips",
                      "pose_ms_median", "search_ms_median", "clips_body_95", "confusion_png", "library_clips"}
    with open(MOTIONS_DIR / "labels.csv", newline="", encoding="utf-8") as fh:
        listed = sum(1 for _ in fh) - 1  # the bundled library with its moves, each once
    assert Path(r["confusion_png"]).is_file() and r["library_clips"] == listed
    clip = r["clips"][0]
    assert clip["label"] == "kick" and clip["detect_rate"] >= 0.9 and not clip["cached_landmarks"]
    assert clip["predicted"] in {"walk", "run", "jump", "kick", "dance"} and len(clip["top"]) == 3
    assert 0 < r["pose_ms_median"] < 1000 and 0 < r["search_ms_median"] < 1000  # sanity; the figures are the bench's
    assert "| kick | 1 |" in capsys.readouterr().out
    assert main(argv) == 0  # again: the landmarks come from the cache, the answers are the same
    r2 = json.loads(out.read_text())
    assert r2["clips"][0]["cached_landmarks"] and r2["clips"][0]["top"] == clip["top"]


def test_missing_videos_folder_is_a_one_line_error(tmp_path, capsys):
    from app.paths import MOTIONS_DIR

    assert main(["bench", "act-it-out", "--videos", str(tmp_path / "none"), "--data", str(MOTIONS_DIR),
                 "--json", str(tmp_path / "v.json")]) == 1
    assert "no labels.csv" in capsys.readouterr().err


def test_describe_take_sees_a_jump_and_a_performer_coming_nearer():
    from lab.bench.act_videos import describe_take
    from retrieval.motion import canonical_joint_map, positions
    from tests.retrieval.test_frontal_landmarks import fake_landmarks
    from tests.support.synthetic_motion import make_motion, make_skeleton

    sk = make_skeleton()
    jm = canonical_joint_map(sk)
    pos = positions(make_motion(sk, frames=60, arm_swing=10.0))
    pos[..., [0, 2]] -= pos[:, [jm["hips"]]][..., [0, 2]]  # in place
    ok = np.ones(len(pos), bool)

    def shows(p: np.ndarray) -> dict:
        world, image = fake_landmarks(p, jm)
        return describe_take(world, image, ok, 30.0, (640, 480))

    still = shows(pos)
    jump = pos.copy()
    jump[20:40, :, 1] += 0.4 * np.sin(np.linspace(0, np.pi, 20))[:, None]  # 0.4 m up and down
    nearer = pos.copy()
    nearer[..., 2] += np.linspace(0.0, 1.5, len(pos))[:, None]  # walks 1.5 m towards the camera
    up = pos.copy()
    up[:, [jm["left_hand"], jm["right_hand"]], 1] = up[:, [jm["head"]], 1] + 0.2  # hands above the head
    assert still["rise_L"] < 0.15 and shows(jump)["rise_L"] > still["rise_L"] + 0.3
    assert 0.95 < still["nearer"] < 1.05 and shows(nearer)["nearer"] > 1.3
    assert still["hands_up"] == 0.0 and shows(up)["hands_up"] == 1.0
    assert 0.2 < still["body_height"] < 0.9
