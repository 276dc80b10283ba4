"""Frames to integer codes and code-to-code distances: PCA + 2-bit quantiser
(:mod:`~retrieval.codes.quantizer`) and every form of the distance table
(:mod:`~retrieval.codes.tables`): the seed's full 4ⁿ×4ⁿ table, its exact split form for
large n, and the compact difference and component tables. :func:`make_table` builds any
layout and :func:`table_lookup` reads any of them."""
from __future__ import annotations

from retrieval.codes.quantizer import PCA, Quantizer, levels, pack_codes, unpack_codes
from retrieval.codes.tables import (
    LAYOUTS,
    LEVEL_WEIGHTS,
    MAX_DIMS,
    MAX_FULL_DIMS,
    ComponentTable,
    DiffTable,
    SplitTable,
    absdiff_table,
    code_table,
    component_lookup,
    component_table,
    difference_table,
    full_table,
    make_table,
    reference_table,
    table_bytes,
    table_lookup,
)
from retrieval.errors import QuantizerError

__all__ = [
    "QuantizerError",
    "LEVEL_WEIGHTS",
    "MAX_FULL_DIMS",
    "MAX_DIMS",
    "LAYOUTS",
    "full_table",
    "SplitTable",
    "code_table",
    "DiffTable",
    "difference_table",
    "absdiff_table",
    "ComponentTable",
    "component_table",
    "component_lookup",
    "make_table",
    "table_lookup",
    "table_bytes",
    "reference_table",
    "PCA",
    "Quantizer",
    "levels",
    "pack_codes",
    "unpack_codes",
]
