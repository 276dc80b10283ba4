"""Dropping the outputs StoryBeam never reads from a TFLite model, and the operators that
only feed them.

Why: BlazePose's "full" landmark model has five outputs; StoryBeam reads four. The fifth
is a 256×256 segmentation mask whose head (46 of its 332 operators, ending in a bilinear
upsampling to the full crop) costs a third of every landmark inference: 13.8 ms against
9.2 ms without it (one core, XNNPACK; ``storybeam bench act-it-out`` and docs/notebook/pose.md).
MediaPipe runs that head on every frame even with ``enable_segmentation=False``.

Method: the model is a FlatBuffer (TFLite schema ``Model -> subgraphs[0] -> outputs,
operators``). :func:`prune_outputs` reads it with a minimal FlatBuffer reader (offsets
and vtables only, no schema package: python-for-android's ``tflite-runtime`` ships
none) and patches a copy in place:

1. the subgraph's ``outputs`` vector is rewritten with the kept tensor indices (its
   length shrinks; the spare bytes at its end are left unused, which FlatBuffers allow);
2. liveness backwards from the kept outputs: an operator is kept when one of its output
   tensors is needed, and then its inputs are needed. Operators are stored in execution
   order, so one reverse pass is exact;
3. the ``operators`` vector keeps the live operators in their order. Its elements are
   offsets relative to their own position and point forward (FlatBuffers are built back
   to front), so moving an element to an earlier slot only grows its offset.

Every kept operator sees the same inputs and runs the same kernel, so the kept outputs
are bit for bit those of the unpruned model (tested, with LiteRT's own schema as the
reference reader). The vendored file itself is never changed: its SHA-256 is checked
before pruning.
"""
from __future__ import annotations

import struct
from collections.abc import Callable, Sequence

from retrieval.errors import StoryBeamError

#: TFLite schema field numbers (tensorflow/lite/schema/schema.fbs)
_MODEL_SUBGRAPHS = 2
_SUBGRAPH_TENSORS, _SUBGRAPH_OUTPUTS, _SUBGRAPH_OPERATORS = 0, 2, 3
_TENSOR_SHAPE = 0
_OPERATOR_INPUTS, _OPERATOR_OUTPUTS = 1, 2


class TfliteGraphError(StoryBeamError):
    """The bytes are not a TFLite FlatBuffer this reader can patch."""


class _Reader:
    """Bounds-checked reads of a FlatBuffer (little-endian)."""

    def __init__(self, buf: bytes | bytearray):
        self.buf = buf

    def _check(self, pos: int, size: int) -> None:
        if pos < 0 or pos + size > len(self.buf):
            raise TfliteGraphError(f"offset {pos} outside the {len(self.buf)}-byte model")

    def u16(self, pos: int) -> int:
        self._check(pos, 2)
        return struct.unpack_from("<H", self.buf, pos)[0]

    def u32(self, pos: int) -> int:
        self._check(pos, 4)
        return struct.unpack_from("<I", self.buf, pos)[0]

    def i32(self, pos: int) -> int:
        self._check(pos, 4)
        return struct.unpack_from("<i", self.buf, pos)[0]

    def field(self, table: int, index: int) -> int | None:
        """Absolute position of field ``index`` of the table at ``table`` (None: absent)."""
        vtable = table - self.i32(table)
        entry = 4 + 2 * index
        if entry + 2 > self.u16(vtable):
            return None
        offset = self.u16(vtable + entry)
        return table + offset if offset else None

    def deref(self, pos: int | None) -> int | None:
        """Follow the forward offset stored at ``pos`` (to a table, vector or string)."""
        return None if pos is None else pos + self.u32(pos)

    def vector(self, table: int, index: int) -> tuple[int, int]:
        """(position of the first element, length) of the vector field (0, 0 when absent)."""
        start = self.deref(self.field(table, index))
        if start is None:
            return 0, 0
        n = self.u32(start)
        self._check(start + 4, 4 * n)
        return start + 4, n

    def ints(self, table: int, index: int) -> list[int]:
        first, n = self.vector(table, index)
        return list(struct.unpack_from(f"<{n}i", self.buf, first)) if n else []

    def tables(self, table: int, index: int) -> list[int]:
        first, n = self.vector(table, index)
        return [first + 4 * k + self.u32(first + 4 * k) for k in range(n)]


def _subgraph(reader: _Reader) -> int:
    if len(reader.buf) < 8 or bytes(reader.buf[4:8]) != b"TFL3":
        raise TfliteGraphError("not a TFLite model (no TFL3 identifier)")
    root = reader.u32(0)
    subgraphs = reader.tables(root, _MODEL_SUBGRAPHS)
    if len(subgraphs) != 1:
        raise TfliteGraphError(f"expected one subgraph, found {len(subgraphs)}")
    return subgraphs[0]


def output_shapes(model: bytes) -> list[tuple[int, ...]]:
    """The shape of each output of the model's subgraph, in order."""
    reader = _Reader(model)  # read only: no copy
    sg = _subgraph(reader)
    tensors = reader.tables(sg, _SUBGRAPH_TENSORS)
    return [tuple(reader.ints(tensors[i], _TENSOR_SHAPE)) for i in reader.ints(sg, _SUBGRAPH_OUTPUTS)]


def prune_outputs(model: bytes, keep: Callable[[tuple[int, ...]], bool] | Sequence[tuple[int, ...]]) -> bytes:
    """A copy of ``model`` with only the outputs whose shape passes ``keep`` (a predicate,
    or the shapes to keep), and only the operators they need (module docstring). Returns
    the bytes unchanged when every output is kept; raises :class:`TfliteGraphError` when
    none would be, or when the bytes cannot be read."""
    wanted = keep if callable(keep) else (lambda shape, shapes=frozenset(map(tuple, keep)): shape in shapes)
    buf = bytearray(model)
    reader = _Reader(buf)
    try:
        sg = _subgraph(reader)
        tensors = reader.tables(sg, _SUBGRAPH_TENSORS)
        outputs = reader.ints(sg, _SUBGRAPH_OUTPUTS)
        kept = [o for o in outputs if 0 <= o < len(tensors) and wanted(tuple(reader.ints(tensors[o], _TENSOR_SHAPE)))]
        if len(kept) == len(outputs):
            return bytes(model)
        if not kept:
            raise TfliteGraphError("no output would be left")
        operators = reader.tables(sg, _SUBGRAPH_OPERATORS)
        needed = set(kept)
        live = []
        for op in reversed(operators):
            if needed.intersection(reader.ints(op, _OPERATOR_OUTPUTS)):
                live.append(op)
                needed.update(i for i in reader.ints(op, _OPERATOR_INPUTS) if i >= 0)
        live.reverse()
    except struct.error as exc:  # pragma: no cover - _Reader checks bounds first
        raise TfliteGraphError(f"unreadable model ({exc})") from exc
    first, _ = reader.vector(sg, _SUBGRAPH_OUTPUTS)
    struct.pack_into("<I", buf, first - 4, len(kept))
    struct.pack_into(f"<{len(kept)}i", buf, first, *kept)
    first, _ = reader.vector(sg, _SUBGRAPH_OPERATORS)
    struct.pack_into("<I", buf, first - 4, len(live))
    for k, target in enumerate(live):
        slot = first + 4 * k
        struct.pack_into("<I", buf, slot, target - slot)
    return bytes(buf)


__all__ = ["TfliteGraphError", "output_shapes", "prune_outputs"]
