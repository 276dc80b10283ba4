"""ar.body.tflite_graph: dropping unread outputs (the landmark model's segmentation head)
and the operators that only feed them, checked against LiteRT's own schema reader and
against the unpruned model's outputs, bit for bit."""
from __future__ import annotations

import numpy as np
import pytest

from ar.body import DEFAULT_MODEL_DIR, MODEL_FILES, PoseModelError, pose_runtime_available
from ar.body.models import load_model
from ar.body.tflite_graph import TfliteGraphError, output_shapes, prune_outputs
from ar.body.tracker import _DETECTOR_OUTPUTS, _LANDMARK_OUTPUTS
from retrieval.errors import StoryBeamError

LANDMARK_FILE = DEFAULT_MODEL_DIR / MODEL_FILES["landmarks"][0]
DETECTOR_FILE = DEFAULT_MODEL_DIR / MODEL_FILES["detector"][0]
SEGMENTATION = (1, 256, 256, 1)

needs_runtime = pytest.mark.skipif(not pose_runtime_available(),
                                   reason="no TFLite interpreter: pip install ai-edge-litert (desktop)")


@pytest.fixture(scope="module")
def landmark_bytes() -> bytes:
    return LANDMARK_FILE.read_bytes()


@pytest.fixture(scope="module")
def pruned(landmark_bytes) -> bytes:
    return prune_outputs(landmark_bytes, list(_LANDMARK_OUTPUTS.values()))


def test_output_shapes_are_read_from_the_flatbuffer(landmark_bytes):
    assert output_shapes(landmark_bytes) == [(1, 195), (1, 1), SEGMENTATION, (1, 64, 64, 39), (1, 117)]
    assert output_shapes(DETECTOR_FILE.read_bytes()) == [(1, 2254, 12), (1, 2254, 1)]


def test_the_segmentation_output_is_dropped_and_the_rest_kept_in_order(pruned):
    assert output_shapes(pruned) == [(1, 195), (1, 1), (1, 64, 64, 39), (1, 117)]
    # a predicate works as the list of shapes does
    assert output_shapes(prune_outputs(LANDMARK_FILE.read_bytes(), lambda s: s != SEGMENTATION)) == output_shapes(pruned)


def test_a_model_whose_outputs_are_all_read_is_returned_unchanged():
    raw = DETECTOR_FILE.read_bytes()
    assert prune_outputs(raw, list(_DETECTOR_OUTPUTS.values())) == raw


def test_pruning_matches_liveness_computed_with_litert_schema(landmark_bytes, pruned):
    """The reference: LiteRT's generated schema reads both models; the pruned one holds
    exactly the operators a liveness pass over the original (via the schema) keeps."""
    schema = pytest.importorskip("ai_edge_litert.schema_py_generated",
                                 reason="LiteRT's schema module ships with ai-edge-litert (desktop only)")
    orig = schema.Model.GetRootAsModel(landmark_bytes, 0).Subgraphs(0)
    ops = [(o.OpcodeIndex(), tuple(o.InputsAsNumpy()), tuple(o.OutputsAsNumpy()))
           for o in (orig.Operators(k) for k in range(orig.OperatorsLength()))]
    shapes = {i: tuple(orig.Tensors(i).ShapeAsNumpy()) for i in range(orig.TensorsLength())}
    keep = [int(i) for i in orig.OutputsAsNumpy() if shapes[int(i)] != SEGMENTATION]
    needed, live = set(keep), []
    for op in reversed(ops):
        if needed & set(op[2]):
            live.append(op)
            needed |= {i for i in op[1] if i >= 0}
    live.reverse()
    new = schema.Model.GetRootAsModel(pruned, 0).Subgraphs(0)
    got = [(o.OpcodeIndex(), tuple(o.InputsAsNumpy()), tuple(o.OutputsAsNumpy()))
           for o in (new.Operators(k) for k in range(new.OperatorsLength()))]
    assert list(new.OutputsAsNumpy()) == keep
    assert got == live
    assert len(ops) == 332 and 250 < len(live) < len(ops)  # the head is a real share of the graph
    assert new.TensorsLength() == orig.TensorsLength()  # tensors untouched: indices stay valid


@needs_runtime
def test_the_kept_outputs_are_bit_identical_to_the_unpruned_model(landmark_bytes, pruned):
    from ar.body.models import _interpreter_class

    interpreter_class, _ = _interpreter_class()
    full = interpreter_class(model_content=landmark_bytes, num_threads=1)
    small = interpreter_class(model_content=pruned, num_threads=1)
    for it in (full, small):
        it.allocate_tensors()
    by_name = {d["name"]: d["index"] for d in small.get_output_details()}
    assert len(by_name) == 4
    rng = np.random.default_rng(7)
    for x in (rng.random((1, 256, 256, 3), np.float32), np.full((1, 256, 256, 3), 0.5, np.float32)):
        for it in (full, small):
            it.set_tensor(it.get_input_details()[0]["index"], x)
            it.invoke()
        for d in full.get_output_details():
            if tuple(d["shape"]) == SEGMENTATION:
                assert d["name"] not in by_name
                continue
            np.testing.assert_array_equal(small.get_tensor(by_name[d["name"]]), full.get_tensor(d["index"]))


@needs_runtime
def test_the_tracker_loads_the_pruned_landmark_model():
    model = load_model("landmarks", _LANDMARK_OUTPUTS)
    assert sorted(model.outputs) == sorted(_LANDMARK_OUTPUTS)
    assert len(model.interpreter.get_output_details()) == 4
    assert output_shapes(model.content) == [(1, 195), (1, 1), (1, 64, 64, 39), (1, 117)]


@pytest.mark.parametrize("blob, problem", [
    (b"", "TFL3"),
    (b"\x00" * 64, "TFL3"),
    (b"\xff\xff\xff\x7fTFL3" + b"\x00" * 32, "outside"),
])
def test_unreadable_bytes_are_a_project_error(blob, problem):
    with pytest.raises(TfliteGraphError, match=problem) as info:
        prune_outputs(blob, [(1, 1)])
    assert isinstance(info.value, StoryBeamError)


def test_a_truncated_model_is_refused_not_crashed(landmark_bytes):
    with pytest.raises(TfliteGraphError):
        prune_outputs(landmark_bytes[: len(landmark_bytes) // 3], [(1, 1)])


def test_keeping_no_output_is_refused(landmark_bytes):
    with pytest.raises(TfliteGraphError, match="no output"):
        prune_outputs(landmark_bytes, [(9, 9)])


@needs_runtime
def test_load_model_names_the_file_when_it_cannot_be_pruned(tmp_path, monkeypatch):
    import ar.body.models as models

    (tmp_path / MODEL_FILES["landmarks"][0]).write_bytes(LANDMARK_FILE.read_bytes())
    monkeypatch.setattr(models, "prune_outputs", lambda *a: (_ for _ in ()).throw(TfliteGraphError("boom")))
    with pytest.raises(PoseModelError, match="pose_landmark_full.tflite.*boom"):
        load_model("landmarks", _LANDMARK_OUTPUTS, tmp_path)
