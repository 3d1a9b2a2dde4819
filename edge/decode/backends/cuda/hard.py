"""Hard decisions + nearest codeword on the GPU (binary linear codes with a coset-leader table).

`kernels.hard_lean` per pixel, one thread each: bit i is ``r_i > (white + black) / 2`` in raw
units (float64) or ``r_i > r_inv_i``; the syndrome and the information bits are XORs of the
per-position contributions ``syn_col`` / ``info_bit``; the coset leader gives the column and the
Hamming distance d1; confidence ``max(0, d_min - 2 d1) / max(1, d_min - d1)``.  The same tables
as the CPU (`edge.decode.tables`), so the same codeword wherever several are equally near.
Other binary codes use the soft kernels with METRIC_HARD (exact top-3 Hamming search).
"""

from __future__ import annotations

import numpy as np
from numba import cuda

from .cost import band_of, mul64, pixel_of

TPB = 128


@cuda.jit
def hard_syndrome(frames, inverse, has_inv, white, black, syn_col, info_bit, leader_info, leader_wt,
                  col_of_info, d_min, ncols, use_band, min_d, max_d, stripe, out_cand, out_dist, out_conf):
    n = frames.shape[0]
    yy, xx, inside = pixel_of(cuda.grid(1), frames.shape[1], frames.shape[2])
    if not inside:
        return
    thr = mul64(0.5, np.float64(white[yy, xx]) + np.float64(black[yy, xx]))
    syn = np.int64(0)
    inf = np.int64(0)
    for i in range(n):
        if has_inv:
            bit = frames[i, yy, xx] > inverse[i, yy, xx]
        else:
            bit = np.float64(frames[i, yy, xx]) > thr
        if bit:
            syn ^= syn_col[i]
            inf ^= info_bit[i]
    col = col_of_info[inf ^ leader_info[syn]]
    d1 = leader_wt[syn]
    lo, hi = band_of(xx, use_band, min_d, max_d, stripe, ncols)
    if white[yy, xx] > black[yy, xx] and col >= lo and col <= hi:
        out_cand[yy, xx, 0] = col
        out_dist[yy, xx, 0] = np.float32(d1)
        out_conf[yy, xx] = np.float32(max(d_min - 2 * d1, 0) / max(d_min - d1, 1))
    else:
        out_cand[yy, xx, 0] = -1
        out_dist[yy, xx, 0] = np.inf
        out_conf[yy, xx] = np.float32(0.0)
    out_cand[yy, xx, 1] = -1
    out_cand[yy, xx, 2] = -1
    out_dist[yy, xx, 1] = np.inf
    out_dist[yy, xx, 2] = np.inf
