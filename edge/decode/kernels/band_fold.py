"""The "band" path: exact top-3 of a column-linear binary code within a disparity band, by folded
Walsh-Hadamard transforms of 64-column blocks for LANES pixels at a time, top-3 on 32-bit keys
with an exact 64-bit redo of the rare pixels whose costs exceed them (see `soft_band_fold`).
Tables: `edge.decode.tables.FoldTables`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .cost import LANES, _block_llr
from .lanes import margin_block, margin_scratch
from .top3 import IDX_BITS, NO_KEY, _insert, _write, _write_none


#: Band limits of the lanes past the right image edge in `soft_band_fold` (beyond any column).
_FAR_COL = 1 << 30
#: Empty slot of the 32-bit top-3 keys of `soft_band_fold` (larger than any uncapped key).
NO_KEY32 = np.int32(0x7FFFFFFF)


@njit(cache=True)
def _band_lane_scan(Y, l, n, clo, chi, masks_t):
    """Exact top-3 keys (64-bit, as `_write` takes them) of lane l over columns clo..chi by the
    band-scan formula cost = C0 - sum_i (masks_t[i, c] & y_i) (`soft_band_fold`'s fallback)."""
    c0 = np.int64(0)
    for i in range(n):
        c0 += max(np.int64(Y[i, l]), 0)
    k1 = NO_KEY
    k2 = NO_KEY
    k3 = NO_KEY
    for c in range(clo, chi + 1):
        cost = c0
        for i in range(n):
            cost -= np.int64(masks_t[i, c]) & np.int64(Y[i, l])
        key = (cost << IDX_BITS) | c
        if key < k3:
            k1, k2, k3 = _insert(key, k1, k2, k3)
    return k1, k2, k3


@njit(cache=True)
def _key64(key32, s, cmin):
    """64-bit key (cost << IDX_BITS | column) of a 32-bit key (cost << s | column - cmin)."""
    if key32 == NO_KEY32:
        return NO_KEY
    return ((np.int64(key32) >> s) << IDX_BITS) | (cmin + (np.int64(key32) & ((1 << s) - 1)))


@njit(cache=True)
def _key32(zv, wl, zcap, mult, rc):
    """32-bit top-3 key of `soft_band_fold`: min(z, zcap) * mult | rc with z = zv + wl = 2 cost
    (int32 throughout, so the lane loops stay 8 x int32 wide)."""
    return np.int32(np.int32(min(np.int32(zv + wl), zcap) * mult) | rc)


@njit(cache=True)
def _top3_cols(Z, z0off, m, W, k1, k2, k3, lo, hi, cmin, c_first, c_last, zcap, mult, masked):
    """Top-3 update of every lane with columns c_first..c_last: column c, lane l at
    Z[z0off + c * m + l]; masked: lanes l with c outside [lo[l], hi[l]] skip column c."""
    L = LANES
    c = c_first
    if masked:
        while c + 1 <= c_last:
            zo = z0off + c * m
            z0 = Z[zo:zo + L]
            z1 = Z[zo + m:zo + m + L]
            rc = np.int32(c - cmin)
            ci = np.int32(c)
            ci1 = np.int32(c + 1)
            for l in range(L):
                wl = W[l]
                t1 = k1[l]
                t2 = k2[l]
                t3 = k3[l]
                key = _key32(z0[l], wl, zcap, mult, rc)
                key = key if (ci >= lo[l]) & (ci <= hi[l]) else NO_KEY32
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                key = _key32(z1[l], wl, zcap, mult, rc + 1)
                key = key if (ci1 >= lo[l]) & (ci1 <= hi[l]) else NO_KEY32
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                k1[l] = t1
                k2[l] = t2
                k3[l] = t3
            c += 2
    else:
        while c + 3 <= c_last:
            zo = z0off + c * m
            z0 = Z[zo:zo + L]
            z1 = Z[zo + m:zo + m + L]
            z2 = Z[zo + 2 * m:zo + 2 * m + L]
            z3 = Z[zo + 3 * m:zo + 3 * m + L]
            rc = np.int32(c - cmin)
            for l in range(L):
                wl = W[l]
                t1 = k1[l]
                t2 = k2[l]
                t3 = k3[l]
                key = _key32(z0[l], wl, zcap, mult, rc)
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                key = _key32(z1[l], wl, zcap, mult, rc + 1)
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                key = _key32(z2[l], wl, zcap, mult, rc + 2)
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                key = _key32(z3[l], wl, zcap, mult, rc + 3)
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                k1[l] = t1
                k2[l] = t2
                k3[l] = t3
            c += 4
    while c <= c_last:
        zo = z0off + c * m
        z0 = Z[zo:zo + L]
        rc = np.int32(c - cmin)
        ci = np.int32(c)
        for l in range(L):
            key = _key32(z0[l], W[l], zcap, mult, rc)
            key = key if (ci >= lo[l]) & (ci <= hi[l]) else NO_KEY32
            t1 = k1[l]
            t2 = k2[l]
            k3[l] = min(k3[l], max(t2, key))
            k2[l] = min(t2, max(t1, key))
            k1[l] = min(t1, key)
        c += 1


@njit(cache=True)
def _band_fold_row(yy, frames, inverse, has_inv, white, black, scale, model, tables, band, lane_tables,
                   margin_q, margin, out_col, out_dist, out_conf, out_stats):
    """Row yy of `soft_band_fold` (a plain function: keeps the parallel kernel small to compile)."""
    metric, sr2, ss2, q_scale, ltab = model.metric, model.sr2, model.ss2, model.q_scale, model.ltab
    fold_b, fold_v, fold_sgn = tables.fold_b, tables.fold_v, tables.fold_sgn
    fold_row, fold_usign, masks_t = tables.fold_row, tables.fold_usign, tables.masks_t
    ncols, min_d, max_d, stripe = band.ncols, band.min_d, band.max_d, band.stripe
    n, height, width = frames.shape
    L = LANES
    R = np.zeros((n, L), np.float64)
    RI = np.zeros((n, L), np.float64)
    PA = np.zeros((8, L), np.float64)
    Y = np.zeros((n, L), np.int32)
    YY = np.zeros((2, n, L), np.int32)
    dmin = np.zeros(L, np.float64)
    active = np.zeros(L, np.bool_)
    lo = np.zeros(L, np.int32)
    hi = np.zeros(L, np.int32)
    W = np.zeros(L, np.int32)
    bsz = 1 << fold_b
    nv = 1 << fold_v
    Z = np.zeros(bsz * L + 2 * L, np.int32)
    k1 = np.empty(L, np.int32)
    k2 = np.empty(L, np.int32)
    k3 = np.empty(L, np.int32)
    pixels = 0
    evaluated = 0
    wide = 0
    skipped = 0
    sc = margin_scratch(n, lane_tables.cls_weight.shape[0])
    for x0 in range(0, width, L):
        nact = _block_llr(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale,
                          ltab, yy, x0, True, min_d, max_d, stripe, ncols, R, RI, PA, Y, dmin, active, lo, hi)
        if nact == 0:
            for l in range(L):
                if x0 + l < width:
                    _write_none(out_col, out_dist, out_conf, yy, x0 + l)
            continue
        if margin_block(Y, n, lane_tables, active, lo, hi, dmin, q_scale, margin_q, margin, x0, width, sc,
                        out_col, out_dist, out_conf, yy):
            skipped += 1
            pixels += nact
            evaluated += nact
            continue
        # union of the active lanes' bands; lanes past the image get an empty band that keeps
        # lo and hi non-decreasing in l (so each column's lanes are one interval)
        cmin = ncols
        cmax = -1
        for l in range(L):
            if active[l]:
                cmin = min(cmin, lo[l])
                cmax = max(cmax, hi[l])
                pixels += 1
                evaluated += hi[l] - lo[l] + 1
            if x0 + l >= width:
                lo[l] = _FAR_COL
                hi[l] = _FAR_COL
        # 32-bit keys (min(cost, cap) << s) | (c - cmin), s = bits of c - cmin; a lane whose
        # top-3 holds a capped cost is redone exactly with 64-bit keys (`_band_lane_scan`)
        s = 2
        while (1 << s) <= cmax - cmin:
            s += 1
        zcap = np.int32((1 << (32 - s)) - 2)  # cap of z = 2 cost: cost <= 2**(31 - s) - 1
        mult = np.int32(1 << (s - 1))  # key = min(z, zcap) * mult | (c - cmin)
        for l in range(L):
            W[l] = 0
            k1[l] = NO_KEY32
            k2[l] = NO_KEY32
            k3[l] = NO_KEY32
        for i in range(n):
            yr = Y[i]
            y0 = YY[0, i]
            y1 = YY[1, i]
            for l in range(L):
                yv = yr[l]
                W[l] += max(yv, -yv)
                y0[l] = yv
                y1[l] = -yv
        for u in range(cmin >> fold_b, (cmax >> fold_b) + 1):
            cb = u << fold_b
            c_first = max(cmin, cb)
            c_last = min(cmax, cb + bsz - 1)
            # lanes whose band meets the block: q8 .. q8 + m - 1 (rounded out to multiples of
            # 8); Z holds just these, column c, lane l at Z[L + (c - cb) * m + l - q8] (the
            # margins of L entries keep the top-3 reads of other lanes in bounds: they are
            # outside the band, masked)
            q = 0
            while hi[q] < c_first:
                q += 1
            p = q
            while p < L and lo[p] <= c_last:
                p += 1
            q8 = q & ~7
            m = min(L, (p + 7) & ~7) - q8
            zb = Z[L:L + bsz * m]
            # fold: Z[(a, v), l] = sum over positions i with row a of +-y_i (sign of <g_i, col>
            # on the v and u bits)
            for j in range(bsz * m):
                zb[j] = 0
            for i in range(n):
                zr = fold_row[i] * nv
                su = fold_usign[u, i]
                for v in range(nv):
                    zo = (zr + v) * m
                    zrow = zb[zo:zo + m]
                    src = YY[fold_sgn[i, v] ^ su, i, q8:q8 + m]
                    for l in range(m):
                        zrow[l] += src[l]
            # Walsh-Hadamard transform over the row bits a: Z[(a, v), l] = corr(column)
            h = nv * m
            while h < bsz * m:
                for r0 in range(0, bsz * m, 2 * h):
                    za = zb[r0:r0 + h]
                    zz = zb[r0 + h:r0 + 2 * h]
                    for j in range(h):
                        a = za[j]
                        b = zz[j]
                        za[j] = a + b
                        zz[j] = a - b
                h *= 2
            # top-3 keys, columns inside every lane's band (lo[L-1] <= c <= hi[0]: lo, hi are
            # non-decreasing) unmasked, the others with the lanes outside their band masked out
            f_lo = max(c_first, lo[L - 1])
            f_hi = min(c_last, hi[0])
            if f_lo > f_hi:
                f_lo = c_last + 1
                f_hi = c_last
            zo = L - q8 - cb * m
            _top3_cols(Z, zo, m, W, k1, k2, k3, lo, hi, cmin, c_first, f_lo - 1, zcap, mult, True)
            _top3_cols(Z, zo, m, W, k1, k2, k3, lo, hi, cmin, f_lo, f_hi, zcap, mult, False)
            _top3_cols(Z, zo, m, W, k1, k2, k3, lo, hi, cmin, f_hi + 1, c_last, zcap, mult, True)
        cost_cap = (1 << (31 - s)) - 1
        for l in range(L):
            xx = x0 + l
            if xx >= width:
                break
            if not active[l]:
                _write_none(out_col, out_dist, out_conf, yy, xx)
                continue
            nb = hi[l] - lo[l] + 1
            last = k3[l] if nb >= 3 else (k2[l] if nb == 2 else k1[l])
            if (last >> s) < cost_cap:
                e1 = _key64(k1[l], s, cmin)
                e2 = _key64(k2[l], s, cmin) if nb >= 2 else NO_KEY
                e3 = _key64(k3[l], s, cmin) if nb >= 3 else NO_KEY
            else:
                wide += 1
                e1, e2, e3 = _band_lane_scan(Y, l, n, lo[l], hi[l], masks_t)
            _write(out_col, out_dist, out_conf, yy, xx, e1, e2, e3, dmin[l], q_scale)
    out_stats[yy, 0] = pixels
    out_stats[yy, 1] = evaluated
    out_stats[yy, 2] = wide
    out_stats[yy, 3] = skipped


@njit(cache=True, parallel=True)
def soft_band_fold(frames, inverse, has_inv, white, black, scale, model, tables, band, lane_tables,
                   margin_q, margin, out_col, out_dist, out_conf, out_stats):
    """Exact top-3 soft decoding of a column-linear binary code within a disparity band, LANES
    pixels of a row at a time, by folded Walsh-Hadamard transforms of 2**fold_b-column blocks.

    Column-linear: bit i of codeword `col` is <g_i, col> over GF(2) (g_i: `FoldTables` fold_*), so
    corr(col) = sum_i y_i (-1)**<g_i, col> and cost(col) = (sum_i |y_i| + corr(col)) / 2 (the
    cost of the module docstring, bit for bit: C0 - sum_{c_i = 1} y_i).  Split
    col = (u, a, v) (high bits, fold_b - fold_v row bits, fold_v low bits): within block u,
    corr(u, a, v) = WHT over a of Z[a', v] = sum_{i: row(g_i) = a'} +-y_i, the sign being
    (-1)**(<g_i, u> + <g_i, v>).  Per block and lane: n * 2**fold_v row adds and
    (fold_b - fold_v) * 2**fold_b butterflies instead of 2**fold_b * n masked adds; the blocks
    cover the union of the LANES pixels' bands.  The top-3 update (keys (cost << IDX_BITS) |
    column, ties to the lower column) runs per column over exactly the lanes whose band [lo, hi]
    holds it (lo, hi are non-decreasing in x, so these lanes form an interval).
    Keys are 32-bit: (min(cost, cap) << s) | (column - cmin), s the bits of the block's column
    span, cmin its first column, cap = 2**(31 - s) - 1 (so two int32 min/max per step, twice the
    SIMD width of 64-bit keys); a lane whose top-3 (or fewer, with fewer candidates) holds a
    capped cost is redone with 64-bit keys by the band-scan formula (`_band_lane_scan`) from
    masks_t, so the result is exact and bit-identical in every case.  Per
    column block the transform covers only the lanes whose band meets it (rounded out to 8).
    model: `CostModel`; tables: `edge.decode.tables.FoldTables`; band: `Band` (always applied).
    Same outputs as `soft_band`.  A margin (``margin_q >= 0``, `soft_lanes`' arguments, with its
    ``lane_tables``): a block whose every pixel's nearest codeword is in its band and more than
    the margin ahead of every other codeword is written as the lane search with that margin
    writes it (`lanes.margin_block`: the best exact, the other slots `BEYOND` or empty), without
    its transforms; every other block is searched as without a margin (exact top-3).
    out_stats (H, 4): decoded pixels, candidate evaluations (one per pixel of a block the margin
    finished), pixels redone with 64-bit keys, blocks the margin finished.
    """
    height = frames.shape[1]
    for yy in prange(height):
        _band_fold_row(yy, frames, inverse, has_inv, white, black, scale, model, tables, band, lane_tables,
                       margin_q, margin, out_col, out_dist, out_conf, out_stats)
