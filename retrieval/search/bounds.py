"""The fast search's lower and upper bounds of a candidate's distance, compiled (numba).

Their numpy twin is :func:`retrieval.dtw.library_bounds` (the same three bounds, LB_Kim and
both envelopes, for a whole library at once, proven in :mod:`retrieval.dtw.lower_bounds`),
which the tablet's path (:mod:`retrieval.search.numpy_path`) uses; here:

* :func:`query_rows` — one pass per query: its table rows over the library's vocabulary and
  every vocabulary code's cheapest query code; after it each bound costs one load per cell;
* :func:`lb_cheap` / :func:`lbs_cheap` — max(LB_Kim, envelope columns), one load per distinct
  candidate code (the lazy cascade's first stage, every candidate);
* :func:`envelope_rows`, :func:`lb_pair` / :func:`lbs_parallel` — the rows' envelope, and all
  three at once (over all cores for a single query);
* :func:`block_corner_cap` — an *upper* bound of the k-th best distance from the
  block-corner DTW (:func:`retrieval.dtw.block_corner.runs_dtw_raw`) of a few candidates.

``Q`` is the query's :meth:`PackedCodes.arrays <retrieval.search.packed.PackedCodes.arrays>`,
``L`` the library's with its distinct codes as indices into its vocabulary (the columns of
the query's table rows).
"""
from __future__ import annotations

import numpy as np

from retrieval.dtw.jit import HAVE_NUMBA, numba

if HAVE_NUMBA:  # optional: numba (the kernels below exist only where it is installed)
    from retrieval.dtw.block_corner import runs_dtw_raw
    from retrieval.dtw.runlength import diff_cost

    @numba.njit(cache=True, nogil=True)
    def query_rows(q_dv, vocab, F, absdiff, shift, mask):
        """R[u, t] = D[q_dv[u], vocab[t]] for every code of the library's vocabulary (float32,
        exact: the table's values are float32), and per vocabulary code its cheapest query
        code, colmin[t] = min_u R[u, t]. Columns are vocabulary indices (the library's
        arrays used with R hold them), so a row is as wide as the codes the library uses
        (about a quarter of the 4ⁿ) and stays in cache. After this one pass per query every
        bound costs one load per cell, and a candidate's column envelope costs one load per
        distinct candidate code."""
        nv = vocab.shape[0]
        R = np.empty((q_dv.shape[0], nv), np.float32)
        colmin = np.full(nv, np.inf)
        for u in range(q_dv.shape[0]):
            Ru = R[u]
            ulo = q_dv[u] & mask
            uhi = q_dv[u] >> shift
            for t in range(nv):
                v = vocab[t]
                x = F[np.int64(absdiff[ulo, v & mask]) | (np.int64(absdiff[uhi, v >> shift]) << shift)]
                Ru[t] = x
                d = np.float64(x)
                if d < colmin[t]:
                    colmin[t] = d
        return R, colmin

    @numba.njit(cache=True, nogil=True)
    def envelope_rows(q_dc, c_dv, RT, row_out):
        """Raw envelope bound of the rows: every query code's cheapest candidate code
        (``row_out[u]``, float32, exact: the table's values are float32) times its count,
        summed in query-code order. ``RT`` (the query's table rows transposed, ``RT[t, u]
        = R[u, t]``) gives one contiguous row per candidate code, folded into the minima
        of every query code at once (a vector minimum)."""
        nq = q_dc.shape[0]
        for u in range(nq):
            row_out[u] = np.float32(np.inf)
        for v in range(c_dv.shape[0]):
            r = RT[c_dv[v]]
            for u in range(nq):
                row_out[u] = min(row_out[u], r[u])
        rows = 0.0
        for u in range(nq):
            rows += np.float64(row_out[u]) * q_dc[u]
        return rows

    @numba.njit(cache=True, nogil=True)
    def lb_cheap(nx, q_first, q_last, c_dv, c_dc, ny, c_first, c_last, F, absdiff, shift, mask, colmin):
        """Raw max(LB_Kim, envelope columns): one load per distinct candidate code."""
        cols = 0.0
        for v in range(c_dv.shape[0]):
            cols += colmin[c_dv[v]] * c_dc[v]
        kim = diff_cost(q_first, c_first, F, absdiff, shift, mask)
        if nx > 1 or ny > 1:
            kim += diff_cost(q_last, c_last, F, absdiff, shift, mask)
        return cols if cols > kim else kim

    @numba.njit(cache=True, nogil=True)
    def lb_pair(q_dc, nx, q_first, q_last, c_dv, c_dc, ny, c_first, c_last,
                F, absdiff, shift, mask, colmin, RT, row_out):
        """Normalised max(LB_Kim, envelope rows, envelope columns): :func:`envelope_rows`
        (``row_out``: each query code's cheapest candidate code, which the exact search's
        envelopes reuse) and :func:`lb_cheap`."""
        rows = envelope_rows(q_dc, c_dv, RT, row_out)
        cheap = lb_cheap(nx, q_first, q_last, c_dv, c_dc, ny, c_first, c_last, F, absdiff, shift, mask, colmin)
        best = rows if rows > cheap else cheap
        return best / (nx + ny)

    @numba.njit(cache=True, nogil=True)
    def lbs_cheap(qi, Q, L, F, absdiff, shift, mask, colmin, out):
        """Normalised :func:`lb_cheap` of every candidate (the lazy cascade's first stage)."""
        (qc, qco, qrv, qrl, qro, qrd, qdv, qdc, qdo) = Q
        (lc, lco, lrv, lrl, lro, lrd, ldv, ldc, ldo) = L
        a0, a1 = qco[qi], qco[qi + 1]
        for c in range(lco.shape[0] - 1):
            b0, b1 = lco[c], lco[c + 1]
            out[c] = lb_cheap(a1 - a0, qc[a0], qc[a1 - 1], ldv[ldo[c]:ldo[c + 1]], ldc[ldo[c]:ldo[c + 1]], b1 - b0,
                              lc[b0], lc[b1 - 1], F, absdiff, shift, mask, colmin) / (a1 - a0 + b1 - b0)

    @numba.njit(cache=True, nogil=True, parallel=True)
    def lbs_parallel(qi, Q, L, F, absdiff, shift, mask, RT, colmin, out, rowmins):
        (qc, qco, qrv, qrl, qro, qrd, qdv, qdc, qdo) = Q
        (lc, lco, lrv, lrl, lro, lrd, ldv, ldc, ldo) = L
        a0, a1 = qco[qi], qco[qi + 1]
        for c in numba.prange(lco.shape[0] - 1):
            b0, b1 = lco[c], lco[c + 1]
            out[c] = lb_pair(qdc[qdo[qi]:qdo[qi + 1]], a1 - a0, qc[a0], qc[a1 - 1],
                             ldv[ldo[c]:ldo[c + 1]], ldc[ldo[c]:ldo[c + 1]], b1 - b0, lc[b0], lc[b1 - 1],
                             F, absdiff, shift, mask, colmin, RT, rowmins[c])

    @numba.njit(cache=True, nogil=True)
    def block_corner_cap(cands, k, q_val, q_len, nx, L, F, absdiff, shift, mask, row_prev, row_next):
        """The k-th smallest normalised block-corner DTW of the first ``k + 2`` of ``cands``
        (at least ``k`` of them): each is an upper bound of that candidate's exact distance
        (exact mode, exact arithmetic), so this bounds the k-th best distance from above."""
        (lc, lco, lrv, lrl, lro, lrd, ldv, ldc, ldo) = L
        m_ub = k + 2 if k + 2 < cands.shape[0] else cands.shape[0]
        ubs = np.empty(m_ub)
        for pos in range(m_ub):
            c = cands[pos]
            ubs[pos] = runs_dtw_raw(q_val, q_len, lrv[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]], F, absdiff, shift,
                                    mask, np.zeros(q_val.shape[0]), np.inf, 1.0,
                                    row_prev, row_next) / float(nx + lco[c + 1] - lco[c])
        ubs.sort()
        return ubs[k - 1]
