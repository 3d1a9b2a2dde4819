"""The cost model and its quantisation (every soft search kernel starts here).

Per-sample costs.  Each sample gets two non-negative costs ``e0, e1`` (one per bit value, for
N-ary codes one per symbol) such that the distance of a codeword is ``sum_i e_i(c_i)``:

* ``METRIC_ML`` (0): ``-2 log p(r | symbol)`` up to a per-pixel constant under the heteroscedastic
  Gaussian model ``r ~ N(mu_s, sigma_r**2 + sigma_s**2 * mu_s)``, with ``mu_1`` = white and
  ``mu_0`` = black (intensities normalised to [0, 1]); with inverse frames the sample is
  ``r - r_inv ~ N(+-(white - black), v_white + v_black)``.  ``e0 - e1 = 2 * LLR``.
* ``METRIC_NORMALIZED`` (1): the paper's plain normalised distance, ``(x - s)**2`` with
  ``x = (r - black) / (white - black)`` (with inverse: ``x = ((r - r_inv)/(white - black) + 1)/2``).
* ``METRIC_HARD`` (2): Hamming distance to the hard decision (``r > (white + black)/2`` or
  ``r > r_inv``); the distance output is then the exact Hamming distance.

Quantisation: ``y_i = round(q_scale * (e0 - e1))`` (int64, clipped to ``Y_CLIP``); ``h`` = bits with
``y > 0``; ``w_i = |y_i|``; ``dmin = sum_i min(e0, e1)``.  The search kernels work on y alone
(see `edge.decode.kernels`).  `_pixel_llr` does one pixel, `_block_llr` LANES pixels of a row.

Per-pixel constants: for integer frames under METRIC_ML without inverse frames the two logs of
`_pixel_params` come from a table over the raw levels (`log_levels`, the same log); the
lane-parallel sample loop of `_block_llr` has an unswitched copy for that metric.  Both give the
same values bit for bit.

`CostModel` is the kernels' ``cost`` argument.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .top3 import _band


class CostModel(NamedTuple):
    """The cost model of a search (the kernels' ``cost`` argument).

    metric: METRIC_ML / METRIC_NORMALIZED / METRIC_HARD; sr2, ss2: sigma_r**2, sigma_s**2
    (normalised intensity units); q_scale: quantisation steps per unit of cost
    (`edge.decode.backends.Q_SCALE`); ltab: (levels,) float64 `log_levels` table (empty: the
    logs are computed per pixel).
    """

    metric: int
    sr2: float
    ss2: float
    q_scale: float
    ltab: np.ndarray


METRIC_ML = 0
METRIC_NORMALIZED = 1
METRIC_HARD = 2
#: Largest |quantised per-sample cost difference|.
Y_CLIP = 1 << 24
#: Pixels decoded together by `soft_lanes` (consecutive x of one row); a compile-time constant
#: so that every loop over lanes has a fixed trip count and vectorises.
LANES = 64
_U1 = np.uint64(1)
_U0 = np.uint64(0)


@njit(cache=True)
def _pixel_params(a, b, has_inv, metric, sr2, ss2):
    """Per-pixel constants of `_sample_costs`: (1/v_white, 1/v_black, log terms la, lb,
    1/(v_white + v_black), 1/(white - black)); reciprocals so the per-sample work has no
    division."""
    va = sr2 + ss2 * a
    vb = sr2 + ss2 * b
    la = 0.0
    lb = 0.0
    if metric == METRIC_ML and not has_inv:
        la = np.log(va)
        lb = np.log(vb)
        m = min(la, lb)
        la -= m
        lb -= m
    return 1.0 / va, 1.0 / vb, la, lb, 1.0 / (va + vb), 1.0 / (a - b)


@njit(cache=True)
def _pixel_params_tab(a, b, log_va, log_vb, sr2, ss2):
    """`_pixel_params` for METRIC_ML without inverse frames with the two logs given (from
    `log_levels`): the same values, bit for bit."""
    va = sr2 + ss2 * a
    vb = sr2 + ss2 * b
    m = min(log_va, log_vb)
    return 1.0 / va, 1.0 / vb, log_va - m, log_vb - m, 1.0 / (va + vb), 1.0 / (a - b)


@njit(cache=True)
def log_levels(levels, scale, sr2, ss2):
    """(levels,) float64 table of log(sr2 + ss2 * (v * scale)) for raw values v = 0..levels-1:
    the logs `_pixel_params` takes of a pixel's white / black variance (METRIC_ML without
    inverse frames), so integer frames pay 2 logs per raw level instead of per pixel.  Computed
    here (not in numpy) so that it is the same log, bit for bit."""
    out = np.empty(levels, np.float64)
    for v in range(levels):
        out[v] = np.log(sr2 + ss2 * (v * scale))
    return out


@njit(cache=True)
def _sample_costs(r, ri, a, b, has_inv, metric, iva, ivb, la, lb, ivs, idiff):
    """(e0, e1) of one binary sample (see module docstring); constants from `_pixel_params`."""
    d = a - b
    if metric == METRIC_ML:
        if has_inv:
            s = r - ri
            e1 = (s - d) * (s - d) * ivs
            e0 = (s + d) * (s + d) * ivs
        else:
            e1 = (r - a) * (r - a) * iva + la
            e0 = (r - b) * (r - b) * ivb + lb
    elif metric == METRIC_NORMALIZED:
        if has_inv:
            x = 0.5 * ((r - ri) * idiff + 1.0)
        else:
            x = (r - b) * idiff
        e1 = (x - 1.0) * (x - 1.0)
        e0 = x * x
    else:
        if has_inv:
            one = r > ri
        else:
            one = r > 0.5 * (a + b)
        e1 = 0.0 if one else 1.0
        e0 = 1.0 if one else 0.0
    return e0, e1


@njit(cache=True)
def _quantise(e0, e1, q_scale):
    """round(q_scale * (e0 - e1)) clipped to [-Y_CLIP, Y_CLIP], as int64 (clipped as a float)."""
    t = np.round((e0 - e1) * q_scale)
    t = min(max(t, -float(Y_CLIP)), float(Y_CLIP))
    return np.int64(t)


@njit(cache=True)
def _pixel_llr(frames, inverse, has_inv, yy, xx, n, scale, a, b, metric, sr2, ss2, q_scale, y, w):
    """Fill y (quantised e0 - e1) and w = |y| for one pixel; return (hard mask h, dmin)."""
    iva, ivb, la, lb, ivs, idiff = _pixel_params(a, b, has_inv, metric, sr2, ss2)
    h = _U0
    dmin = 0.0
    for i in range(n):
        r = frames[i, yy, xx] * scale
        ri = 0.0
        if has_inv:
            ri = inverse[i, yy, xx] * scale
        e0, e1 = _sample_costs(r, ri, a, b, has_inv, metric, iva, ivb, la, lb, ivs, idiff)
        dmin += min(e0, e1)
        t = _quantise(e0, e1, q_scale)
        y[i] = t
        if t > 0:
            h |= _U1 << np.uint64(i)
            w[i] = t
        else:
            w[i] = -t
    return h, dmin


@njit(cache=True)
def _block_llr(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab, yy,
               x0, use_band, min_d, max_d, stripe, ncols, R, RI, PA, Y, dmin, active, lo, hi):
    """Quantised cost differences of the LANES pixels x0.. of row yy, lane-parallel.

    ltab: `log_levels` table (empty: the logs of `_pixel_params` are computed per pixel).

    Fills Y (n, LANES) int32 (= `_pixel_llr`'s y, bit for bit), dmin, active (white > black,
    inside the image, non-empty band [lo, hi]); inactive lanes get finite dummy values.
    Scratch: R, RI (n, LANES) float64, PA (8, LANES) float64.  Returns the active lane count.
    """
    n, height, width = frames.shape
    L = LANES
    nact = 0
    for l in range(L):
        xx = x0 + l
        act = False
        a = 1.0
        b = 0.0
        if xx < width:
            a = white[yy, xx] * scale
            b = black[yy, xx] * scale
            llo, lhi = _band(xx, use_band, min_d, max_d, stripe, ncols)
            lo[l] = llo
            hi[l] = lhi
            act = (a > b) and (llo <= lhi)
        if not act:
            a = 1.0
            b = 0.0
        active[l] = act
        nact += np.int64(act)
        if act and ltab.shape[0] > 0:
            iva, ivb, la, lb, ivs, idiff = _pixel_params_tab(a, b, ltab[np.int64(white[yy, xx])],
                                                             ltab[np.int64(black[yy, xx])], sr2, ss2)
        else:
            iva, ivb, la, lb, ivs, idiff = _pixel_params(a, b, has_inv, metric, sr2, ss2)
        PA[0, l] = a
        PA[1, l] = b
        PA[2, l] = iva
        PA[3, l] = ivb
        PA[4, l] = la
        PA[5, l] = lb
        PA[6, l] = ivs
        PA[7, l] = idiff
        dmin[l] = 0.0
    full = x0 + L <= width
    if full and metric == METRIC_ML and not has_inv:
        # the common case, unswitched: the same arithmetic as `_sample_costs`, bit for bit
        a = PA[0]
        b = PA[1]
        iva = PA[2]
        ivb = PA[3]
        la = PA[4]
        lb = PA[5]
        for i in range(n):
            row = frames[i, yy, x0:x0 + L]
            yr = Y[i]
            for l in range(L):
                r = row[l] * scale
                e1 = (r - a[l]) * (r - a[l]) * iva[l] + la[l]
                e0 = (r - b[l]) * (r - b[l]) * ivb[l] + lb[l]
                dmin[l] += min(e0, e1)
                yr[l] = np.int32(_quantise(e0, e1, q_scale))
        return nact
    if full:
        for i in range(n):
            row = frames[i, yy, x0:x0 + L]
            for l in range(L):
                R[i, l] = row[l] * scale
            if has_inv:
                rowi = inverse[i, yy, x0:x0 + L]
                for l in range(L):
                    RI[i, l] = rowi[l] * scale
    else:
        for i in range(n):
            for l in range(L):
                xx = min(x0 + l, width - 1)
                R[i, l] = frames[i, yy, xx] * scale
                if has_inv:
                    RI[i, l] = inverse[i, yy, xx] * scale
    for i in range(n):
        for l in range(L):
            e0, e1 = _sample_costs(R[i, l], RI[i, l], PA[0, l], PA[1, l], has_inv, metric,
                                   PA[2, l], PA[3, l], PA[4, l], PA[5, l], PA[6, l], PA[7, l])
            dmin[l] += min(e0, e1)
            Y[i, l] = np.int32(_quantise(e0, e1, q_scale))
    return nact
