"""Soft exact top-3 of an N-ary code (q levels) on the GPU: `kernels.soft_nary`, one thread per pixel.

Per sample and symbol the cost ``(obs - mu)**2 / var + log(var) - lmin`` (ML; lmin the pixel's
smallest log(var), `kernels.nary._nary_lmin`) or ``((obs - mu) / d)**2``,
hard: 0 for the nearest level, 1 otherwise; quantised relative to the sample's best symbol, then
a scan of the candidate rows with the codebook (uint8) from global memory.  ``log(var)`` comes
from the host (`nary_logs`, the CPU's log) so the costs are the CPU's bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import cuda, njit

from .cost import band_of, insert, mul64, pixel_of, rint, write_none, write_top3
from ...kernels import IDX_BITS, METRIC_HARD, METRIC_ML, NO_KEY, Y_CLIP
from ...kernels.nary import _nary_lmin

TPB = 64
#: Largest n * q of the per-pixel cost table (local memory).
MAX_NQ = 1024
_NO_KEY = int(NO_KEY)
_IDX_BITS = IDX_BITS
_ML, _HARD = METRIC_ML, METRIC_HARD
_YC = int(Y_CLIP)


@njit(cache=True)
def nary_logs(white, black, has_inv, scale, q, sr2, ss2):
    """(q, H, W) float64 log(var) - lmin of each symbol level, computed as `kernels.soft_nary` does."""
    h, w = white.shape
    out = np.zeros((q, h, w), np.float64)
    for yy in range(h):
        for xx in range(w):
            a = white[yy, xx] * scale
            b = black[yy, xx] * scale
            d = a - b
            lmin = _nary_lmin(a, b, has_inv, q, sr2, ss2)
            for s in range(q):
                frac = s / (q - 1)
                if has_inv:
                    var = 2.0 * sr2 + ss2 * (b + d * frac + b + d * (1.0 - frac))
                else:
                    mu = b + d * frac
                    var = sr2 + ss2 * mu
                out[s, yy, xx] = np.log(var) - lmin
    return out


@cuda.jit
def soft_nary(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, q, logs,
              codebook, ncols, use_band, min_d, max_d, stripe, out_col, out_dist, out_conf):
    e = cuda.local.array(MAX_NQ, np.float64)
    eq = cuda.local.array(MAX_NQ, np.int64)
    n = frames.shape[0]
    yy, xx, inside = pixel_of(cuda.grid(1), frames.shape[1], frames.shape[2])
    if not inside:
        return
    a = mul64(white[yy, xx], scale)
    b = mul64(black[yy, xx], scale)
    lo, hi = band_of(xx, use_band, min_d, max_d, stripe, ncols)
    if not (a > b) or lo > hi:
        write_none(out_col, out_dist, out_conf, yy, xx)
        return
    d = a - b
    dmin = 0.0
    for i in range(n):
        r = mul64(frames[i, yy, xx], scale)
        ri = mul64(inverse[i, yy, xx], scale) if has_inv else 0.0
        best = np.inf
        for s in range(q):
            frac = s / (q - 1)
            if has_inv:
                mu = mul64(d, mul64(2.0, frac) - 1.0)
                obs = r - ri
                var = mul64(2.0, sr2) + mul64(ss2, b + mul64(d, frac) + b + mul64(d, 1.0 - frac))
            else:
                mu = b + mul64(d, frac)
                obs = r
                var = sr2 + mul64(ss2, mu)
            if metric == _ML:
                val = (mul64(obs - mu, obs - mu) / var) + logs[s, yy, xx]
            else:
                x = (obs - mu) / d
                val = mul64(x, x)
            e[i * q + s] = val
            if val < best:
                best = val
        if metric == _HARD:
            arg = 0
            for s in range(q):
                if e[i * q + s] == best:
                    arg = s
                    break
            for s in range(q):
                e[i * q + s] = 0.0 if s == arg else 1.0
            best = 0.0
        dmin += best
        for s in range(q):
            t = np.int64(rint(mul64(e[i * q + s] - best, q_scale)))
            eq[i * q + s] = min(t, _YC)
    k1 = _NO_KEY
    k2 = _NO_KEY
    k3 = _NO_KEY
    for j in range(lo, hi + 1):
        cost = np.int64(0)
        for i in range(n):
            cost += eq[i * q + codebook[j, i]]
        key = (cost << _IDX_BITS) | np.int64(j)
        if key < k3:
            k1, k2, k3 = insert(key, k1, k2, k3)
    write_top3(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale)
