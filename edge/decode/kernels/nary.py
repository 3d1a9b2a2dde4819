"""The "nary" path: exact top-3 of an N-ary code (q levels) by brute force over the band's rows."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .cost import METRIC_HARD, METRIC_ML, Y_CLIP
from .top3 import IDX_BITS, NO_KEY, _insert, _pixel_start, _write, _write_none


@njit(cache=True)
def _nary_lmin(a, b, has_inv, q, sr2, ss2):
    """The smallest ``log(var)`` of a pixel's q symbol levels (white a, black b normalised):
    the per-pixel constant `soft_nary`'s ML costs leave out (distances are -2 log-likelihoods
    up to a per-pixel constant; without it they went negative and ``(d2 - d1) / d2`` above 1)."""
    d = a - b
    lmin = np.inf
    for s in range(q):
        frac = s / (q - 1)
        if has_inv:
            var = 2.0 * sr2 + ss2 * (b + d * frac + b + d * (1.0 - frac))
        else:
            var = sr2 + ss2 * (b + d * frac)
        lmin = min(lmin, np.log(var))
    return lmin


@njit(cache=True, parallel=True)
def soft_nary(frames, inverse, has_inv, white, black, scale, model, tables, band, out_col, out_dist, out_conf):
    """Exact top-3 over the codebook rows in the band for an N-ary code (q levels).

    Symbol s has level mu_s = black + (white - black) * s / (q - 1) (with inverse frames the
    difference r - r_inv has mean (white - black) * (2 s / (q - 1) - 1)); per-sample costs as
    in `edge.decode.kernels.cost` (ML: Gaussian -2 log-likelihood, ``(obs - mu)**2 / var +
    log(var)``, less the pixel's smallest ``log(var)`` over the q levels so that every cost is
    non-negative, as the binary kernels' (`_nary_lmin`); normalised: (x - s/(q-1))**2; hard: 0
    for the nearest level, 1 otherwise).  Brute force over the candidate rows.
    model: `CostModel` (ltab unused); tables: `edge.decode.tables.NaryTables`; band: `Band`.
    """
    metric, sr2, ss2, q_scale = model.metric, model.sr2, model.ss2, model.q_scale
    q, codebook = tables.q, tables.codebook
    ncols, use_band, min_d, max_d, stripe = band.ncols, band.use_band, band.min_d, band.max_d, band.stripe
    n, height, width = frames.shape
    for yy in prange(height):
        e = np.zeros((n, q), np.float64)
        eq = np.zeros((n, q), np.int64)
        for xx in range(width):
            a, b, lo, hi, ok = _pixel_start(white, black, yy, xx, scale, use_band, min_d, max_d, stripe, ncols)
            if not ok:
                _write_none(out_col, out_dist, out_conf, yy, xx)
                continue
            d = a - b
            lmin = _nary_lmin(a, b, has_inv, q, sr2, ss2) if metric == METRIC_ML else 0.0
            dmin = 0.0
            for i in range(n):
                r = frames[i, yy, xx] * scale
                ri = inverse[i, yy, xx] * scale if has_inv else 0.0
                best = np.inf
                for s in range(q):
                    frac = s / (q - 1)
                    if has_inv:
                        mu = d * (2.0 * frac - 1.0)
                        obs = r - ri
                        var = 2.0 * sr2 + ss2 * (b + d * frac + b + d * (1.0 - frac))
                    else:
                        mu = b + d * frac
                        obs = r
                        var = sr2 + ss2 * mu
                    if metric == METRIC_ML:
                        val = (obs - mu) * (obs - mu) / var + (np.log(var) - lmin)
                    else:
                        x = (obs - mu) / d
                        val = x * x
                    e[i, s] = val
                    if val < best:
                        best = val
                if metric == METRIC_HARD:
                    arg = 0
                    for s in range(q):
                        if e[i, s] == best:
                            arg = s
                            break
                    for s in range(q):
                        e[i, s] = 0.0 if s == arg else 1.0
                    best = 0.0
                dmin += best
                for s in range(q):
                    t = np.int64(np.round((e[i, s] - best) * q_scale))
                    eq[i, s] = min(t, Y_CLIP)
            k1 = NO_KEY
            k2 = NO_KEY
            k3 = NO_KEY
            for j in range(lo, hi + 1):
                cost = np.int64(0)
                for i in range(n):
                    cost += eq[i, codebook[j, i]]
                if cost <= (k3 >> IDX_BITS):
                    k1, k2, k3 = _insert((cost << IDX_BITS) | j, k1, k2, k3)
            _write(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale)
