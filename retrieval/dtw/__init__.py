"""Dynamic time warping: the look-up-table and Euclidean kernels (numba, with a numpy path
for machines without it), run-length DTW (exact, and the block-corner upper bound), the
row-scan DP of the fast search, the early-abandoning re-ranking DTW on float features,
lower bounds, the range-cover bound, and open-ended subsequence DTW. Each compiled kernel
sits beside its numpy twin in one module; :mod:`~retrieval.dtw.jit` is the one place numba
is imported."""
from __future__ import annotations

from retrieval.dtw.block_corner import runs_dtw_numpy, runs_dtw_rows_batch_numpy, runs_dtw_rows_numpy
from retrieval.dtw.jit import BACKENDS, HAVE_NUMBA, KERNEL_MODULES, kernel_cache_dir
from retrieval.dtw.kernels import (
    DTWError,
    band_limits,
    check_codes,
    dtw_codes,
    dtw_codes_to_many,
    dtw_cost_numpy,
    dtw_features,
    dtw_features_to_many,
    resolve_backend,
)
from retrieval.dtw.lower_bounds import (
    distinct_counts,
    envelope_sums,
    lb_envelope,
    lb_kim,
    library_bounds,
    lower_bound,
)
from retrieval.dtw.range_bound import (
    monotone_cover_numpy,
    range_cover_numpy,
    range_lower_bound,
)
from retrieval.dtw.rerank import (
    dtw_features_abandon,
    dtw_features_abandon_t,
    dtw_features_many,
    rows_kernel_ready,
    sequential_cost_matrix,
)
from retrieval.dtw.rowscan import dtw_rows_numpy
from retrieval.dtw.runlength import (
    rle_dtw_numpy,
    rle_is_exact,
    run_length_decode,
    run_length_encode,
)
from retrieval.dtw.subsequence import SubsequenceMatch, find_subsequence

__all__ = [
    "HAVE_NUMBA",
    "BACKENDS",
    "KERNEL_MODULES",
    "kernel_cache_dir",
    "DTWError",
    "band_limits",
    "resolve_backend",
    "check_codes",
    "dtw_cost_numpy",
    "dtw_codes",
    "dtw_features",
    "dtw_codes_to_many",
    "dtw_features_to_many",
    "distinct_counts",
    "lb_kim",
    "envelope_sums",
    "lb_envelope",
    "lower_bound",
    "library_bounds",
    "dtw_rows_numpy",
    "dtw_features_abandon",
    "dtw_features_abandon_t",
    "dtw_features_many",
    "rows_kernel_ready",
    "sequential_cost_matrix",
    "runs_dtw_numpy",
    "runs_dtw_rows_numpy",
    "runs_dtw_rows_batch_numpy",
    "run_length_encode",
    "run_length_decode",
    "rle_is_exact",
    "rle_dtw_numpy",
    "range_cover_numpy",
    "monotone_cover_numpy",
    "range_lower_bound",
    "SubsequenceMatch",
    "find_subsequence",
]
