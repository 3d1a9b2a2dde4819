"""The "syndrome" path: hard decisions + coset-leader decoding of a binary linear code.

Syndrome and information bits of the hard-decision word as XORs of per-position contributions
over contiguous x, then one coset-leader lookup per pixel.  Tables: `edge.decode.tables.HardTables`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .top3 import _band


@njit(cache=True, parallel=True)
def hard_lean(frames, inverse, has_inv, white, black, tables, band, out_cand, out_dist, out_conf):
    """Hard decision + coset-leader decoding of a binary linear code, one image row at a time.

    Bits r > (white + black)/2 (or r > r_inv); the syndrome and information bits of the word are
    XORs of per-position contributions (loops over contiguous x); then per pixel the coset
    leader's information bits and weight give the column and the Hamming distance d1.
    Outputs: out_cand (H, W, 3) int32 [column, -1, -1] (-1 where white <= black or the column
    is outside the projector / band), out_dist (H, W, 3) float32 [d1, inf, inf], out_conf (H, W)
    float32 max(0, d_min - 2 d1) / max(1, d_min - d1) (0 where undecoded).
    tables: `edge.decode.tables.HardTables`; band: `Band`.
    """
    syn_col, info_bit, leader_info = tables.syn_col, tables.info_bit, tables.leader_info
    leader_wt, col_of_info, d_min = tables.leader_wt, tables.col_of_info, tables.d_min
    ncols, use_band, min_d, max_d, stripe = band.ncols, band.use_band, band.min_d, band.max_d, band.stripe
    n, height, width = frames.shape
    for yy in prange(height):
        syn = np.zeros(width, np.int64)
        inf = np.zeros(width, np.int64)
        thr = np.empty(width, np.float64)
        if not has_inv:
            for xx in range(width):
                thr[xx] = 0.5 * (np.float64(white[yy, xx]) + np.float64(black[yy, xx]))
        for i in range(n):
            sc = syn_col[i]
            ib = info_bit[i]
            if has_inv:
                for xx in range(width):
                    m = -np.int64(frames[i, yy, xx] > inverse[i, yy, xx])
                    syn[xx] ^= sc & m
                    inf[xx] ^= ib & m
            else:
                for xx in range(width):
                    m = -np.int64(np.float64(frames[i, yy, xx]) > thr[xx])
                    syn[xx] ^= sc & m
                    inf[xx] ^= ib & m
        for xx in range(width):
            s = syn[xx]
            col = col_of_info[inf[xx] ^ leader_info[s]]
            d1 = leader_wt[s]
            lo, hi = _band(xx, use_band, min_d, max_d, stripe, ncols)
            if white[yy, xx] > black[yy, xx] and col >= lo and col <= hi:
                out_cand[yy, xx, 0] = col
                out_dist[yy, xx, 0] = np.float32(d1)
                out_conf[yy, xx] = np.float32(max(d_min - 2 * d1, 0) / max(d_min - d1, 1))
            else:
                out_cand[yy, xx, 0] = -1
                out_dist[yy, xx, 0] = np.inf
                out_conf[yy, xx] = 0.0
            out_cand[yy, xx, 1] = -1
            out_cand[yy, xx, 2] = -1
            out_dist[yy, xx, 1] = np.inf
            out_dist[yy, xx, 2] = np.inf
