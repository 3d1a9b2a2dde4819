"""The "band-scan" path: exact top-3 of any binary code within a disparity band, by a scan of
the band (brute force beats pruning when the band holds a small share of the codebook).

Per pixel cost(c) = C0 - sum_i (masks_t[i, c] & y_i) over the contiguous candidate columns, then a
BAND_NET-wide (16) min/max network.  Tables: `edge.decode.tables.ScanTables`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .cost import LANES, _block_llr
from .top3 import IDX_BITS, NO_KEY, _insert, _write, _write_none


#: Width of the top-3 min/max network of `soft_band` (columns per step).
BAND_NET = 16


@njit(cache=True)
def _band_row(yy, frames, inverse, has_inv, white, black, scale, model, tables, band,
              out_col, out_dist, out_conf, out_stats):
    """Row yy of `soft_band` (a plain function: keeps the parallel kernel small to compile)."""
    metric, sr2, ss2, q_scale, ltab = model.metric, model.sr2, model.ss2, model.q_scale, model.ltab
    masks_t = tables.masks_t
    ncols, min_d, max_d, stripe = band.ncols, band.min_d, band.max_d, band.stripe
    n, height, width = frames.shape
    L = LANES
    R = np.zeros((n, L), np.float64)
    RI = np.zeros((n, L), np.float64)
    PA = np.zeros((8, L), np.float64)
    Y = np.zeros((n, L), np.int32)
    dmin = np.zeros(L, np.float64)
    active = np.zeros(L, np.bool_)
    lo = np.zeros(L, np.int32)
    hi = np.zeros(L, np.int32)
    acc = np.zeros(ncols + BAND_NET, np.int32)
    K1 = np.empty(BAND_NET, np.int64)
    K2 = np.empty(BAND_NET, np.int64)
    K3 = np.empty(BAND_NET, np.int64)
    pixels = 0
    evaluated = 0
    n4 = n - n % 4
    for x0 in range(0, width, L):
        _block_llr(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale,
                   ltab, yy, x0, True, min_d, max_d, stripe, ncols, R, RI, PA, Y, dmin, active,
                   lo, hi)
        for ln in range(L):
            xx = x0 + ln
            if xx >= width:
                break
            if not active[ln]:
                _write_none(out_col, out_dist, out_conf, yy, xx)
                continue
            clo = lo[ln]
            chi = hi[ln]
            c0 = np.int32(0)
            for i in range(n):
                c0 += max(Y[i, ln], 0)
            nb = chi - clo + 1
            pixels += 1
            evaluated += nb
            for c in range(nb):
                acc[c] = c0
            for i in range(0, n4, 4):  # 4 rows per pass: fewer loads / stores of acc
                y0 = Y[i, ln]
                y1 = Y[i + 1, ln]
                y2 = Y[i + 2, ln]
                y3 = Y[i + 3, ln]
                r0 = masks_t[i, clo:chi + 1]
                r1 = masks_t[i + 1, clo:chi + 1]
                r2 = masks_t[i + 2, clo:chi + 1]
                r3 = masks_t[i + 3, clo:chi + 1]
                for c in range(nb):
                    acc[c] -= (r0[c] & y0) + (r1[c] & y1) + (r2[c] & y2) + (r3[c] & y3)
            for i in range(n4, n):
                yi = Y[i, ln]
                row = masks_t[i, clo:chi + 1]
                for c in range(nb):
                    acc[c] -= row[c] & yi
            for l in range(BAND_NET):
                K1[l] = NO_KEY
                K2[l] = NO_KEY
                K3[l] = NO_KEY
            for cb in range(0, nb, BAND_NET):
                for l in range(BAND_NET):
                    c = cb + l
                    key = (np.int64(acc[c]) << IDX_BITS) | np.int64(clo + c)
                    key = key if c < nb else NO_KEY
                    t = K1[l]
                    K1[l] = min(t, key)
                    key = max(t, key)
                    t = K2[l]
                    K2[l] = min(t, key)
                    key = max(t, key)
                    K3[l] = min(K3[l], key)
            k1 = NO_KEY
            k2 = NO_KEY
            k3 = NO_KEY
            for l in range(BAND_NET):
                if K1[l] < k3:
                    k1, k2, k3 = _insert(K1[l], k1, k2, k3)
                    if K2[l] < k3:
                        k1, k2, k3 = _insert(K2[l], k1, k2, k3)
                        if K3[l] < k3:
                            k1, k2, k3 = _insert(K3[l], k1, k2, k3)
            _write(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin[ln], q_scale)
    out_stats[yy, 0] = pixels
    out_stats[yy, 1] = evaluated


@njit(cache=True, parallel=True)
def soft_band(frames, inverse, has_inv, white, black, scale, model, tables, band,
              out_col, out_dist, out_conf, out_stats):
    """Exact top-3 soft decoding of any binary code within a disparity band, by scanning the
    band: cost(c) = C0 - sum_i (masks_t[i, c] & y_i) with C0 = sum_i max(y_i, 0) (the cost of
    the all-zero word; masks_t is 0 / -1), a loop over contiguous candidate columns, then a
    lane-wise top-3 network over BAND_NET columns at a time.  out_stats (H, 2): decoded pixels,
    candidate evaluations.  model: `CostModel`; tables: `edge.decode.tables.ScanTables`;
    band: `Band` (the band is always applied)."""
    height = frames.shape[1]
    for yy in prange(height):
        _band_row(yy, frames, inverse, has_inv, white, black, scale, model, tables, band,
                  out_col, out_dist, out_conf, out_stats)
