"""Hostile story packages and calibration files (short CI version of `storybeam stress
--only packages`): refused with a clear StoryBeamError before anything is written.
Regression tests for each defect the campaign found."""
from __future__ import annotations

import json
import random

import pytest

from app.story.storage import ProfileStore, StorageError, read_package
from app.story.model import Story, StoryError
from lab.stress import files
from ar.calibration import CameraCalibration, ProjectorCalibration
from ar.errors import CalibrationError


@pytest.mark.slow  # the package campaign
def test_package_campaign_refuses_everything_hostile_and_writes_nothing(tmp_path):
    out = files.run_package_campaign(tmp_path, n_mutants=60, seed=11)
    assert out["crashes"] == 0, out["crash_examples"]
    assert out["wrote_on_refusal"] == 0
    assert out["crafted_accepted"] == []
    # The valid package and the bzip2/lzma variants of it (valid zips, valid content) import.
    assert out["imported"] >= 1 + len(files.VALID_VARIANTS) and out["refused"] > 50


@pytest.mark.slow  # the calibration campaign
def test_calibration_campaign_only_raises_calibration_error(tmp_path):
    out = files.run_calibration_campaign(tmp_path, n=800, seed=5)
    assert out["crashes"] == 0, out["crash_examples"]
    assert out["loaded"] >= 2 and out["refused"] > 400


@pytest.fixture()
def store(tmp_path):
    with ProfileStore(tmp_path / "p.db") as s:
        yield s


@pytest.fixture(scope="module")
def crafted():
    return files.crafted_packages(random.Random(4))


@pytest.mark.parametrize("label", [
    "manifest deeply nested",  # RecursionError escaped
    "story.json deeply nested",  # RecursionError escaped
    "manifest unhashable name",  # TypeError: unhashable type: 'list'
    "story with a 400-digit integer",  # OverflowError from float()
    "mark time a 400-digit integer",  # OverflowError from float()
    "zip bomb (one entry over the entry limit)", "zip bomb (total over the unpack limit)", "too many entries",
    "traversal name '../evil.txt'", "traversal name '/etc/passwd'", "traversal name 'assets/../../x'",
    "wrong version 2", "wrong version '1'", "wrong version True", "story from a newer app", "lying size header",
])
def test_hostile_package_refused_before_writing(store, tmp_path, crafted, label):
    store.save_story(Story.new(title="mine"))
    before = files.snapshot(store)
    path = tmp_path / "in.sbpkg"
    path.write_bytes(crafted[label])
    with pytest.raises(StorageError):
        store.import_package(path)
    assert files.snapshot(store) == before
    assert not any(p.name.startswith(".import-") for p in store.assets_dir.glob("*")) if store.assets_dir.exists() else True


def test_damaged_deflate_stream_is_a_storage_error(store, tmp_path):
    """Found by package mutation: zlib.error ('invalid distance too far back') escaped."""
    src = Story.new(title="x")
    store.save_story(src)
    store.put_asset(src.id, "bg.png", bytes(range(256)) * 200)
    good = store.export_package(src.id, tmp_path / "good.sbpkg").read_bytes()
    rng = random.Random(0)
    errors = set()
    for _ in range(150):
        data = bytearray(good)
        for _ in range(3):
            data[rng.randrange(60, len(data) - 200)] ^= 1 << rng.randrange(8)
        p = tmp_path / "bad.sbpkg"
        p.write_bytes(bytes(data))
        try:
            read_package(p)
        except StorageError as exc:
            errors.add(type(exc))
    assert errors == {StorageError}


def test_story_model_refuses_huge_integers():
    story = Story.new()
    d = story.to_dict()
    d["scenes"][0]["characters"] = [{"id": "c", "kind": "robot", "path": [[10**400, 0, 0]], "motion": {"class": "walk"},
                                     "marks": []}]
    with pytest.raises(StoryError, match="finite"):
        Story.from_dict(d)
    d["scenes"][0]["characters"][0]["path"] = [[0.1, 0.1, 0]]
    d["scenes"][0]["characters"][0]["marks"] = [{"kind": "hop", "at": 10**400}]
    with pytest.raises(StoryError, match="finite"):
        Story.from_dict(d)


# ----------------------------------------------------------------------------- calibration regressions


def _write(tmp_path, doc) -> str:
    p = tmp_path / "calib.json"
    p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return p


@pytest.mark.parametrize("key, value", [("per_view_errors", None), ("per_view_errors", 3), ("rejected_views", [[1, 2, 3]]),
                                        ("rms", 10**400), ("camera_matrix", [[10**400, 0, 1], [0, 1, 1], [0, 0, 1]])])
def test_camera_file_bad_values_raise_calibration_error(tmp_path, key, value):
    """Found by calibration fuzzing: dict(None)/dict(3) raised TypeError, 400-digit
    integers OverflowError."""
    doc = files._valid_calibrations()["camera"]
    CameraCalibration.load(_write(tmp_path, doc))  # the unmodified file is fine
    doc[key] = value
    with pytest.raises(CalibrationError):
        CameraCalibration.load(_write(tmp_path, doc))


@pytest.mark.parametrize("value", ["x", None, 10**400, [1, 2], float("nan")])
def test_projector_stereo_rms_is_validated(tmp_path, value):
    """Found by calibration fuzzing: float(data['stereo_rms']) raised ValueError/TypeError/OverflowError."""
    doc = files._valid_calibrations()["projector"]
    ProjectorCalibration.load(_write(tmp_path, doc))
    doc["stereo_rms"] = value
    with pytest.raises(CalibrationError):
        ProjectorCalibration.load(_write(tmp_path, doc))


def test_deeply_nested_calibration_json(tmp_path):
    """Found by calibration fuzzing: RecursionError escaped from json.loads."""
    with pytest.raises(CalibrationError, match="nested"):
        CameraCalibration.load(_write(tmp_path, "[" * 100_000 + "]" * 100_000))


def test_oversized_calibration_file_refused_before_reading(tmp_path):
    p = tmp_path / "camera.json"
    with open(p, "wb") as fh:
        fh.truncate(64 * 1024 * 1024)  # sparse
    with pytest.raises(CalibrationError, match="MB"):
        CameraCalibration.load(p)
