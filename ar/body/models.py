"""The two vendored BlazePose models and the TFLite interpreter that runs them.

Files: ``assets/models/blazepose/`` (:data:`DEFAULT_MODEL_DIR`) holds
``pose_detection.tflite`` and ``pose_landmark_full.tflite``, copied unchanged from the
``mediapipe==0.10.21`` wheel (Apache-2.0; see the folder's README.md and LICENSE). Each
is checked against its SHA-256 (:data:`MODEL_FILES`) before it is loaded, so a truncated
or swapped file is a :class:`PoseModelError` naming the file, never a crash inside the
interpreter.

Interpreter: ``ai_edge_litert.interpreter.Interpreter`` (the desktop; its wheels accept
numpy 2), else ``tflite_runtime.interpreter.Interpreter`` (python-for-android's
``tflite-runtime`` recipe on the tablet). This module is the only importer of either;
both are imported on first use, so ``import ar.body`` works without them and
:func:`pose_runtime_available` says whether a tracker can run.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ar.body.tflite_graph import TfliteGraphError, prune_outputs
from retrieval.errors import StoryBeamError

#: The checkout's vendored models (the one path ar.body builds from ``__file__``: ar cannot
#: import app.paths, a higher layer).
DEFAULT_MODEL_DIR = Path(__file__).resolve().parents[2] / "assets" / "models" / "blazepose"
#: role -> (file name, SHA-256 of the file in the mediapipe 0.10.21 wheel)
MODEL_FILES: dict[str, tuple[str, str]] = {
    "detector": ("pose_detection.tflite", "9ba9dd3d42efaaba86b4ff0122b06f29c4122e756b329d89dca1e297fd8f866c"),
    "landmarks": ("pose_landmark_full.tflite", "e9a5c5cb17f736fafd4c2ec1da3b3d331d6edbe8a0d32395855aeb2cdfd64b9f"),
}
#: The interpreter modules tried, in order.
RUNTIMES = ("ai_edge_litert.interpreter", "tflite_runtime.interpreter")


class PoseModelError(StoryBeamError):
    """A pose model file is missing, altered or unreadable, or no TFLite interpreter is
    installed. The message names the file (when there is one) and the problem."""

    def __init__(self, problem: str, path: str | Path | None = None):
        self.path = str(path) if path is not None else None
        self.problem = problem
        super().__init__(f"{self.path}: {problem}" if self.path else problem)


def _interpreter_class() -> tuple[Any, str] | None:
    """The ``Interpreter`` class of the first importable runtime of :data:`RUNTIMES`, and its name."""
    try:
        # optional: ai_edge_litert, the desktop's TFLite interpreter (absent -> try tflite_runtime)
        from ai_edge_litert.interpreter import Interpreter
        return Interpreter, RUNTIMES[0]
    except ImportError:
        pass
    try:
        # optional: tflite_runtime, python-for-android's recipe on the tablet (absent -> no pose)
        from tflite_runtime.interpreter import Interpreter
        return Interpreter, RUNTIMES[1]
    except ImportError:
        return None


def pose_runtime_available() -> bool:
    """Whether a TFLite interpreter (``ai_edge_litert`` or ``tflite_runtime``) is importable."""
    return _interpreter_class() is not None


def runtime_name() -> str | None:
    """The interpreter module a tracker would use (``None``: none installed)."""
    found = _interpreter_class()
    return found[1] if found else None


def sha256_of(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def model_path(role: str, model_dir: str | Path | None = None, check: bool = True) -> Path:
    """The file of ``role`` (``"detector"`` / ``"landmarks"``) in ``model_dir`` (default
    :data:`DEFAULT_MODEL_DIR`), its SHA-256 checked when ``check``."""
    name = MODEL_FILES[role][0]
    path = Path(model_dir if model_dir is not None else DEFAULT_MODEL_DIR) / name
    if not path.is_file():
        raise PoseModelError("pose model file not found (copy it from the mediapipe 0.10.21 wheel: "
                             "see assets/models/blazepose/README.md)", path)
    if check:
        _check_digest(role, path, sha256_of(path))
    return path


def _check_digest(role: str, path: Path, got: str) -> None:
    name, digest = MODEL_FILES[role]
    if got != digest:
        raise PoseModelError(f"pose model file altered: sha256 {got[:12]}..., expected {digest[:12]}... "
                             f"(mediapipe 0.10.21's {name})", path)


@dataclass
class TfliteModel:
    """One loaded model: ``run(x, names)`` feeds the single float32 input and returns the
    named output tensors (``outputs``: name -> tensor index) as read-only views into the
    interpreter's memory: use or copy them before the next ``run`` (the interpreter
    refuses to run while a view is alive; copying the 0.6 MB heatmap every frame costs
    more than the refinement that reads 39 windows of it)."""

    path: Path
    interpreter: Any
    input_index: int
    input_shape: tuple[int, ...]
    outputs: dict[str, int]
    content: bytes = b""  #: the model as loaded (pruned); kept alive beside the interpreter reading it

    def run(self, x: np.ndarray, names: tuple[str, ...]) -> list[np.ndarray]:
        it = self.interpreter
        it.set_tensor(self.input_index, x)
        it.invoke()
        return [it.tensor(self.outputs[n])() for n in names]


def load_model(role: str, output_shapes: dict[str, tuple[int, ...]], model_dir: str | Path | None = None,
               num_threads: int = 1) -> TfliteModel:
    """Load the model of ``role``, check its one input and name its outputs by shape
    (``output_shapes``: name -> expected shape); any mismatch is a :class:`PoseModelError`.

    Outputs of other shapes are dropped before loading, with the operators that only feed
    them (:func:`ar.body.tflite_graph.prune_outputs`): the landmark model's segmentation
    head, a third of its inference time. The outputs read are unchanged bit for bit."""
    found = _interpreter_class()
    if found is None:
        raise PoseModelError("no TFLite interpreter: install ai-edge-litert (desktop: pip install ai-edge-litert) "
                             "or tflite-runtime (the tablet's python-for-android recipe)")
    interpreter_class, _ = found
    path = model_path(role, model_dir, check=False)
    raw = path.read_bytes()  # read once: the bytes hashed are the bytes loaded
    _check_digest(role, path, hashlib.sha256(raw).hexdigest())
    try:
        content = prune_outputs(raw, list(output_shapes.values()))
    except TfliteGraphError as exc:
        raise PoseModelError(f"not a TFLite model StoryBeam can read ({exc})", path) from exc
    try:
        it = interpreter_class(model_content=content, num_threads=int(num_threads))
        it.allocate_tensors()
    except (ValueError, RuntimeError) as exc:
        raise PoseModelError(f"not a loadable TFLite model ({exc})", path) from exc
    inputs = it.get_input_details()
    if len(inputs) != 1 or inputs[0]["dtype"] != np.float32:
        raise PoseModelError(f"expected one float32 input, found {[(d['shape'], d['dtype']) for d in inputs]}", path)
    by_shape = {tuple(int(v) for v in d["shape"]): int(d["index"]) for d in it.get_output_details()}
    outputs = {}
    for name, shape in output_shapes.items():
        if shape not in by_shape:
            raise PoseModelError(f"no output of shape {shape} ({name}); outputs: {sorted(by_shape)}", path)
        outputs[name] = by_shape[shape]
    return TfliteModel(path, it, int(inputs[0]["index"]), tuple(int(v) for v in inputs[0]["shape"]), outputs, content)


__all__ = ["DEFAULT_MODEL_DIR", "MODEL_FILES", "RUNTIMES", "PoseModelError", "pose_runtime_available", "runtime_name",
           "sha256_of", "model_path", "TfliteModel", "load_model"]
