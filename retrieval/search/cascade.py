"""The fast search's candidate loop, compiled (numba): every stage of one query's search.

:func:`refine` visits the candidates in bound order (best-first over bounds refined lazily
when the segment filter is in use), prunes by bound, rejects by the segment- and
range-cover bounds, runs the exact DP with early abandoning and keeps the k best;
:func:`search_query` runs one query's stages (table rows, cheap bounds, the loop) and
:func:`search_batch` / :func:`search_serial` a batch of queries over all cores or on one
thread. The method, and why it returns the brute force's answers, is in
:mod:`retrieval.search.fast`'s docstring; the numpy twin of the loop is
:mod:`retrieval.search.numpy_path`.
"""
from __future__ import annotations

import numpy as np

from retrieval.dtw.jit import HAVE_NUMBA, numba

#: query segments of the segment-cover filter (:mod:`retrieval.search.segment_bound`); 0: off.
#: Tried 3, 6, 8, 12, 16, each side by side with the search without the filter on the derived
#: library: 6-12 gained most, 3 and 16 less (docs/notebook/retrieval-speed.md)
SEGMENTS = 8
#: a second, finer level of the segment-cover filter for long queries: query runs per
#: segment (0: off), used when it gives at least twice SEGMENTS segments. Measured on the
#: derived libraries, 69 queries, one core, same answers (docs/notebook/retrieval-speed.md):
#: 33 204 clips p95 214.8 -> 172.7 ms, total 4 980 -> 4 595 ms; 3 382 clips total 654 ->
#: 593 ms (3 runs per segment about the same, 4 and 6 less, 1 the same as 2). Its segments
#: are cut where the query's codes change most (``segment_split_adaptive``): 33 204 clips
#: p95 about 155 -> 128 ms with the same segment count; 3 runs per segment cut so: 160 ms
SEGMENTS_FINE = 2

if HAVE_NUMBA:  # optional: numba (the kernels below exist only where it is installed)
    from retrieval.dtw.block_corner import runs_dtw_raw
    from retrieval.dtw.kernels import band_limits_nb
    from retrieval.dtw.range_bound import range_cover_both
    from retrieval.dtw.rowscan import plain_dtw_raw
    from retrieval.dtw.runlength import rle_dtw_raw
    from retrieval.search.bounds import block_corner_cap, envelope_rows, lbs_cheap, query_rows
    from retrieval.search.order import heap_pop, heap_push, least_first
    from retrieval.search.segment_bound import (
        segment_bounds_nb,
        segment_cover_nb,
        segment_rows,
        segment_split_adaptive_nb,
    )

    @numba.njit(cache=True, nogil=True)
    def _segment_key(Rs, H, c, L, lrv_v, nx, thr, floor, mx_buf, my_buf):
        """Candidate ``c``'s heap key at a segment level: its normalised segment-cover bound
        (the DP stops past ``thr``), raised to ``floor`` (a bound already known for it: the
        larger of two lower bounds is one)."""
        lco, lrl, lro = L[1], L[3], L[4]
        norm = float(nx + lco[c + 1] - lco[c])
        sb = segment_cover_nb(Rs, H, lrv_v[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]], mx_buf, my_buf,
                              thr * norm) / norm
        return sb if sb > floor else floor

    @numba.njit(cache=True, nogil=True)
    def refine(qi, Q, L, LV, F, absdiff, shift, mask, R, RT, lbs, rowmins, colmin, k, use_rle, band, out_idx,
               out_dist, stats, abandon, range_bound, lazy):
        """Candidates in bound order (best-first over refined bounds when the segment filter
        is in use, module docstring): prune, DTW with early abandoning, keep the k best
        (distance, then index). Writes out_idx/out_dist (k) and stats (5). ``LV``: the
        library's codes and run values as vocabulary indices (columns of ``R``)."""
        (qc, qco, qrv, qrl, qro, qrd, qdv, qdc, qdo) = Q
        (lc, lco, lrv, lrl, lro, lrd, ldv, ldc, ldo) = L
        (lc_v, lrv_v) = LV
        inf = np.inf
        ncand = lco.shape[0] - 1
        a0, a1 = qco[qi], qco[qi + 1]
        nx = a1 - a0
        r0, r1 = qro[qi], qro[qi + 1]
        nruns = r1 - r0
        for t in range(k):
            out_idx[t] = -1
            out_dist[t] = inf
        # the lazy cascade needs only the k + 2 least cheap bounds in order (for the first
        # cap), not all of them sorted: sorting 3 382 bounds took about a sixth of a median query
        order = least_first(lbs, k + 2) if lazy else np.argsort(lbs, kind="mergesort")
        maxlen = 1
        for c in range(ncand):
            if lco[c + 1] - lco[c] > maxlen:
                maxlen = lco[c + 1] - lco[c]
        big = maxlen
        if nx > big:
            big = nx
        row_prev = np.empty(big + 2)
        row_next = np.empty(big + 2)
        left = np.empty(big + 2)
        right = np.empty(big + 2)
        buf_a = np.empty(big + 2)
        buf_b = np.empty(big + 2)
        dq = np.empty(big + 2, np.int64)
        lo = np.empty(nx, np.int64)
        hi = np.empty(nx, np.int64)
        rest_run = np.empty(nruns)
        rest_row = np.empty(nx)
        row_didx = np.empty(nx, np.int64)  # query frame -> its distinct-code row of R
        i = 0
        for p in range(nruns):
            for t in range(qrl[r0 + p]):
                row_didx[i] = qrd[r0 + p]
                i += 1
        rest_col = np.empty(big + 2)
        # without exact arithmetic the bound sums may round differently from the DP: shrink them
        safety = 1.0 if use_rle >= 1 else 1.0 - 1e-9
        pruned = 0
        abandoned = 0
        completed = 0
        range_rejected = 0
        # range-cover bound (retrieval.range_bound): work arrays
        use_range = range_bound and use_rle == 1 and band < 0
        maxruns = 1
        for c in range(ncand):
            if lro[c + 1] - lro[c] > maxruns:
                maxruns = lro[c + 1] - lro[c]
        wide = maxruns if maxruns > nruns else nruns
        rest2_buf = np.empty(nruns * maxruns)
        before = np.empty(nruns)
        mx_buf = np.empty(wide)  # range_cover_both's work rows
        my_buf = np.empty(wide)
        cp_buf = np.empty(wide)
        # segment-cover filter (retrieval.search.segment_bound): the query's runs in a few segments
        nseg = SEGMENTS if SEGMENTS < nruns else nruns
        use_seg = use_range and SEGMENTS > 0 and nseg < nruns
        seg_b = segment_bounds_nb(nruns, nseg)  # cut evenly: cutting where the codes change gained nothing here
        Rs = np.empty((nseg, R.shape[1]), np.float32)
        seg_h = np.empty(nseg, np.int64)
        if use_seg:
            segment_rows(R, qrd[r0:r1], qrl[r0:r1], seg_b, Rs, seg_h)
        # the second, finer level for long queries: SEGMENTS_FINE runs per segment, cut
        # where the query's codes change most (retrieval.search.segment_bound, "Where to cut")
        nseg2 = nruns // SEGMENTS_FINE if SEGMENTS_FINE > 0 else 0
        use_seg2 = use_seg and nseg2 >= 2 * nseg and nseg2 <= nruns
        if not use_seg2:
            nseg2 = 1
        seg_b2 = segment_bounds_nb(nruns, nseg2) if not use_seg2 else segment_split_adaptive_nb(
            qrv[r0:r1], qrl[r0:r1], nseg2, F, absdiff, shift, mask)
        Rs2 = np.empty((nseg2, R.shape[1]), np.float32)
        seg_h2 = np.empty(nseg2, np.int64)
        if use_seg2:
            segment_rows(R, qrd[r0:r1], qrl[r0:r1], seg_b2, Rs2, seg_h2)
        # Exact mode with exact arithmetic: the block-corner DTW of a few best-bound
        # candidates is an upper bound of their exact distance, so its k-th smallest value
        # bounds the k-th best distance from above before any exact DTW has run.
        cap = inf
        if use_rle == 1 and band < 0 and ncand >= k:
            cap = block_corner_cap(order, k, qrv[r0:r1], qrl[r0:r1], nx, L, F, absdiff, shift, mask, row_prev, row_next)
        if not abandon:
            cap = inf
        n_loop = ncand
        loop_order = order
        loop_lb = np.empty(0)
        sel_rm = np.empty((0, 0), np.float32)
        if lazy:
            # the cascade's second stage: lbs holds max(LB_Kim, columns); the rows' envelope
            # only for the candidates whose cheap bound is within the cap (the others
            # cannot enter the k best), then those in order of the full bound
            nqd = qdo[qi + 1] - qdo[qi]
            within = np.nonzero(lbs <= cap)[0]  # in index order
            n_loop = within.shape[0]
            pruned += ncand - n_loop
            full = np.empty(n_loop)
            rows_sel = np.empty((n_loop, nqd), np.float32)
            for s in range(n_loop):
                c = within[s]
                r = envelope_rows(qdc[qdo[qi]:qdo[qi + 1]], ldv[ldo[c]:ldo[c + 1]], RT, rows_sel[s])
                r /= float(nx + lco[c + 1] - lco[c])
                full[s] = r if r > lbs[c] else lbs[c]
            sub = np.argsort(full, kind="mergesort")
            loop_order = within[sub]
            loop_lb = full[sub]
            sel_rm = rows_sel[sub]
            # the cap again from the best candidates by the full bound (usually nearer)
            if cap < inf and n_loop >= k:
                cap = min(cap, block_corner_cap(loop_order, k, qrv[r0:r1], qrl[r0:r1], nx, L, F, absdiff, shift,
                                                mask, row_prev, row_next))
        # Best-first over bounds refined lazily (module docstring, "Visiting order"): a
        # candidate enters a heap keyed by its segment-cover bound (coarse, then fine)
        # when the next envelope bound in the stream is no lower than the heap's least
        # key; the heap's least is verified (range cover, exact DP) once it is fully
        # refined. Without the segment filter: envelope order, as before.
        best_first = use_seg and abandon
        hk = np.empty(n_loop + 1 if best_first else 1)  # heap: key (a raw bound / norm)
        hp = np.empty(hk.shape[0], np.int64)  # position in loop_order
        hl = np.empty(hk.shape[0], np.int64)  # level of the key: 1 coarse, 2 fine
        nh = 0
        pos = 0
        while True:
            thr = out_dist[k - 1]
            if cap < thr:
                thr = cap
            if not abandon:
                thr = inf  # brute force: every DTW runs to the end
            nxt_lb = inf
            if pos < n_loop:
                nxt_lb = loop_lb[pos] if lazy else lbs[loop_order[pos]]
            if nh == 0 or nxt_lb < hk[0]:
                # the stream's next candidate
                if pos >= n_loop:
                    break
                if nxt_lb > thr:
                    pruned += n_loop - pos
                    pos = n_loop
                    if nh == 0:
                        break
                    continue
                vpos = pos
                pos += 1
                c = loop_order[vpos]
                level = 1 if best_first else 0  # 0: verify now (envelope order)
                floor = nxt_lb
            else:
                # the heap's least bound
                floor, vpos, lvl = hk[0], hp[0], hl[0]
                if floor > thr:  # so is every other bound left: all rejected
                    abandoned += nh
                    range_rejected += nh
                    pruned += n_loop - pos
                    break
                nh = heap_pop(hk, hp, hl, nh)
                c = loop_order[vpos]
                level = 2 if (lvl == 1 and use_seg2) else 0  # 0: fully refined, verify
            if level > 0:  # refine: the segment-cover bound of this level, back into the heap
                sb = _segment_key(Rs if level == 1 else Rs2, seg_h if level == 1 else seg_h2, c, L, lrv_v, nx, thr,
                                  floor, mx_buf, my_buf)
                if sb > thr:
                    abandoned += 1
                    range_rejected += 1
                else:
                    nh = heap_push(hk, hp, hl, nh, sb, vpos, level)
                continue
            # verify candidate c: range-cover bound, then the exact DP
            b0, b1 = lco[c], lco[c + 1]
            ny = b1 - b0
            norm = float(nx + ny)
            # per distinct query code: its cheapest code in this candidate
            rm = sel_rm[vpos] if lazy else rowmins[c]
            if not use_range:  # the envelope of the rows still to come, per run
                acc = 0.0
                for p in range(nruns - 1, -1, -1):
                    rest_run[p] = acc * safety
                    acc += rm[qrd[r0 + p]] * qrl[r0 + p]
            kyc = lro[c + 1] - lro[c]
            rest2 = rest2_buf[:nruns * kyc].reshape((nruns, kyc))
            if use_range:
                # order-aware bounds and "cost still to come" (retrieval.range_bound)
                acc = 0.0
                for p in range(nruns):
                    before[p] = acc
                    acc += rm[qrd[r0 + p]] * qrl[r0 + p]
                lb_raw = range_cover_both(R, qrd[r0:r1], qrl[r0:r1], lrv_v[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]],
                                          before, thr, norm, rest2, mx_buf, my_buf, cp_buf)
                if lb_raw == inf or lb_raw / norm > thr:
                    abandoned += 1
                    range_rejected += 1
                    continue
            else:
                for p in range(nruns):
                    for q in range(kyc):
                        rest2[p, q] = rest_run[p]
            if not (use_rle == 2 and band < 0):
                # the envelope of the columns still to come, per frame (for the frame-level
                # corridors; only survivors need it)
                acc = 0.0
                j = ny - 1
                for p in range(lro[c + 1] - lro[c] - 1, -1, -1):
                    per = colmin[lrv_v[lro[c] + p]]  # the run's cheapest query code
                    for s in range(lrl[lro[c] + p]):
                        rest_col[j] = acc * safety
                        acc += per
                        j -= 1
            if use_rle == 2 and band < 0:
                raw = runs_dtw_raw(qrv[r0:r1], qrl[r0:r1], lrv[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]],
                                   F, absdiff, shift, mask, rest_run, thr, norm, row_prev, row_next)
            elif use_rle == 1 and band < 0:
                raw = rle_dtw_raw(qrv[r0:r1], qrl[r0:r1], lrv[lro[c]:lro[c + 1]], lrl[lro[c]:lro[c + 1]],
                                  F, absdiff, shift, mask, rest2, rest_col, thr, norm,
                                  row_prev, row_next, left, right, buf_a, buf_b, dq)
            else:
                i = nx - 1
                for p in range(nruns - 1, -1, -1):
                    per = rm[qrd[r0 + p]]
                    acc = rest_run[p]
                    for s in range(qrl[r0 + p]):
                        rest_row[i] = acc * safety
                        acc += per
                        i -= 1
                band_limits_nb(nx, ny, band, lo, hi)
                raw = plain_dtw_raw(row_didx, lc_v[b0:b1], R, lo, hi, rest_row, rest_col, thr, norm,
                                    row_prev, row_next)
            if raw == inf:
                abandoned += 1
                continue
            completed += 1
            d = raw / norm
            kth = out_dist[k - 1]
            if d < kth or (d == kth and c < out_idx[k - 1]):
                t = k - 1
                while t > 0 and (out_dist[t - 1] > d or (out_dist[t - 1] == d and out_idx[t - 1] > c)):
                    out_dist[t] = out_dist[t - 1]
                    out_idx[t] = out_idx[t - 1]
                    t -= 1
                out_dist[t] = d
                out_idx[t] = c
        stats[0] = ncand
        stats[1] = pruned
        stats[2] = abandoned
        stats[3] = completed
        stats[4] = range_rejected

    @numba.njit(cache=True, nogil=True)
    def search_query(qi, Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats,
                     range_bound):
        """Every stage for query ``qi``: its table rows, every candidate's bounds, the
        candidate loop (writes row ``qi`` of the outputs)."""
        ncand = L[1].shape[0] - 1
        lbs = np.empty(ncand)
        R, colmin = query_rows(Q[6][Q[8][qi]:Q[8][qi + 1]], vocab, F, absdiff, shift, mask)
        lbs_cheap(qi, Q, L, F, absdiff, shift, mask, colmin, lbs)
        refine(qi, Q, L, LV, F, absdiff, shift, mask, R, np.ascontiguousarray(R.T), lbs,
               np.empty((0, 0), np.float32), colmin, k, use_rle, band, out_idx[qi], out_dist[qi], stats[qi], True,
               range_bound, True)

    @numba.njit(cache=True, nogil=True, parallel=True)
    def search_batch(Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats, range_bound):
        for qi in numba.prange(Q[1].shape[0] - 1):
            search_query(qi, Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats,
                         range_bound)

    @numba.njit(cache=True, nogil=True)
    def search_serial(Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats, range_bound):
        """:func:`search_batch` on one thread: every stage of every query in one compiled
        call (a single query's search crosses into compiled code once, not three times —
        each crossing unpacks some thirty arrays)."""
        for qi in range(Q[1].shape[0] - 1):
            search_query(qi, Q, L, LV, vocab, F, absdiff, shift, mask, k, use_rle, band, out_idx, out_dist, stats,
                         range_bound)
