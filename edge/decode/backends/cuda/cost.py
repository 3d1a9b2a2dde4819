"""Device-side cost model: the same quantised integer costs as the CPU kernels, bit for bit.

Mirrors `edge.decode.kernels` (`_pixel_params`, `_sample_costs`, `_quantise`, `_insert`,
`_write`) in numba-cuda device functions, in float64 where the CPU uses float64.  Three things
keep the GPU arithmetic identical to the CPU's:

* No fused multiply-add: NVVM contracts ``a * b + c`` into one FMA by default (one rounding
  instead of two), the CPU kernels do not.  Every product here is `mul64` / `mul32`
  (libdevice ``__nv_dmul_rn`` / ``__nv_fmul_rn``, which are never contracted).
* Logs come from the host: CUDA's ``log`` may differ from the CPU's in the last bit, so the
  per-pixel variance logs (METRIC_ML without inverse frames) are looked up in
  `edge.decode.kernels.log_levels` (integer frames, indexed by the raw white / black value)
  or computed per pixel on the host by `pixel_logs` (float frames), both with the CPU's log.
* Rounding half to even (`rint`, libdevice ``rint``), as ``np.round`` on the CPU.

Under the simulator (``NUMBA_ENABLE_CUDASIM=1``) the helpers are plain Python / numpy scalar
operations, which are IEEE float64 / float32 operations with one rounding each.

Top-3 keys: ``cost << IDX_BITS | column`` (int64), ties to the lower column, `NO_KEY` empty.
"""

from __future__ import annotations

import numpy as np
from numba import config, cuda, njit

from ...kernels import IDX_BITS, IDX_MASK, METRIC_HARD, METRIC_ML, METRIC_NORMALIZED, NO_KEY, Y_CLIP

# The integer-only helpers are the CPU kernels' own functions (numba-cuda compiles an @njit
# function that a kernel calls for the device), so the candidate band and the top-3 tie rule are
# one piece of code; the float helpers below keep device copies, because the device must round
# every product explicitly (mul64 / mul32).
from ...kernels.top3 import _band as band_of  # noqa: F401  (re-exported to the kernel modules)
from ...kernels.top3 import _insert as insert  # noqa: F401

SIM = bool(config.ENABLE_CUDASIM)

#: Log modes of the device kernels: no logs needed, table over raw levels, per-pixel array.
LOG_NONE, LOG_TABLE, LOG_PIXEL = 0, 1, 2
#: Largest n of a binary code (codewords packed into int64 masks, as on the CPU).
MAX_N = 64

_NO_KEY = int(NO_KEY)
_IDX_BITS = IDX_BITS
_IDX_MASK = IDX_MASK
_YC = float(Y_CLIP)
_ML, _NORM, _HARD = METRIC_ML, METRIC_NORMALIZED, METRIC_HARD

if SIM:
    @cuda.jit(device=True)
    def mul64(a, b):
        """a * b in float64, one rounding."""
        return np.float64(a) * np.float64(b)

    @cuda.jit(device=True)
    def mul32(a, b):
        """a * b in float32, one rounding."""
        return np.float32(a) * np.float32(b)

    @cuda.jit(device=True)
    def rint(x):
        """Round half to even (float64)."""
        return np.rint(np.float64(x))
else:  # pragma: no cover - needs a CUDA device
    from numba.cuda import libdevice

    @cuda.jit(device=True)
    def mul64(a, b):
        """a * b in float64, one rounding (never contracted into an FMA)."""
        return libdevice.dmul_rn(np.float64(a), np.float64(b))

    @cuda.jit(device=True)
    def mul32(a, b):
        """a * b in float32, one rounding (never contracted into an FMA)."""
        return libdevice.fmul_rn(np.float32(a), np.float32(b))

    @cuda.jit(device=True)
    def rint(x):
        """Round half to even (float64)."""
        return libdevice.rint(np.float64(x))



@cuda.jit(device=True)
def pixel_of(p, height, width):
    """Thread ``p`` (one thread per pixel, row-major) -> (yy, xx, inside ``p < height * width``)."""
    yy = p // width
    return yy, p - yy * width, p < height * width


@cuda.jit(device=True)
def sort_small(a, m):
    """`kernels.sort_small` on the device: a[:m] sorted ascending in place (insertion sort)."""
    for i in range(1, m):
        t = a[i]
        j = i - 1
        while j >= 0 and a[j] > t:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = t


@cuda.jit(device=True)
def pixel_logs_of(white, black, lmode, ltab, plog, yy, xx):
    """(log v_white, log v_black) of pixel (yy, xx) from the host-computed logs (0 when unused)."""
    if lmode == LOG_TABLE:
        return ltab[np.int64(white[yy, xx])], ltab[np.int64(black[yy, xx])]
    if lmode == LOG_PIXEL:
        return plog[0, yy, xx], plog[1, yy, xx]
    return 0.0, 0.0


@cuda.jit(device=True)
def pixel_params(a, b, has_inv, metric, sr2, ss2, log_a, log_b):
    """`kernels._pixel_params` (logs given): (1/v_white, 1/v_black, la, lb, 1/(v_w + v_b), 1/(a - b))."""
    va = sr2 + mul64(ss2, a)
    vb = sr2 + mul64(ss2, b)
    la = 0.0
    lb = 0.0
    if metric == _ML and not has_inv:
        m = min(log_a, log_b)
        la = log_a - m
        lb = log_b - m
    return 1.0 / va, 1.0 / vb, la, lb, 1.0 / (va + vb), 1.0 / (a - b)


@cuda.jit(device=True)
def sample_costs(r, ri, a, b, has_inv, metric, iva, ivb, la, lb, ivs, idiff):
    """`kernels._sample_costs`: (e0, e1) of one binary sample."""
    d = a - b
    if metric == _ML:
        if has_inv:
            s = r - ri
            e1 = mul64(mul64(s - d, s - d), ivs)
            e0 = mul64(mul64(s + d, s + d), ivs)
        else:
            e1 = mul64(mul64(r - a, r - a), iva) + la
            e0 = mul64(mul64(r - b, r - b), ivb) + lb
    elif metric == _NORM:
        if has_inv:
            x = mul64(0.5, mul64(r - ri, idiff) + 1.0)
        else:
            x = mul64(r - b, idiff)
        e1 = mul64(x - 1.0, x - 1.0)
        e0 = mul64(x, x)
    else:
        if has_inv:
            one = r > ri
        else:
            one = r > mul64(0.5, a + b)
        e1 = 0.0 if one else 1.0
        e0 = 1.0 if one else 0.0
    return e0, e1


@cuda.jit(device=True)
def quantise(e0, e1, q_scale):
    """`kernels._quantise`: round(q_scale * (e0 - e1)) clipped to [-Y_CLIP, Y_CLIP], int64."""
    t = rint(mul64(e0 - e1, q_scale))
    t = min(max(t, -_YC), _YC)
    return np.int64(t)


@cuda.jit(device=True)
def pixel_llr(frames, inverse, has_inv, yy, xx, n, scale, a, b, metric, sr2, ss2, q_scale,
              log_a, log_b, y):
    """Fill y[0:n] (int32 quantised e0 - e1) of pixel (yy, xx); return (dmin, C0 = sum max(y, 0))."""
    iva, ivb, la, lb, ivs, idiff = pixel_params(a, b, has_inv, metric, sr2, ss2, log_a, log_b)
    dmin = 0.0
    c0 = np.int32(0)
    for i in range(n):
        r = mul64(frames[i, yy, xx], scale)
        ri = 0.0
        if has_inv:
            ri = mul64(inverse[i, yy, xx], scale)
        e0, e1 = sample_costs(r, ri, a, b, has_inv, metric, iva, ivb, la, lb, ivs, idiff)
        dmin += min(e0, e1)
        t = np.int32(quantise(e0, e1, q_scale))
        y[i] = t
        if t > 0:
            c0 += t
    return dmin, c0


@cuda.jit(device=True)
def write_top3(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale):
    """`kernels._write`: columns, distances dmin + cost / q_scale (float32) and (d2 - d1) / d2."""
    for j in range(3):
        kk = k1 if j == 0 else (k2 if j == 1 else k3)
        if kk == _NO_KEY:
            out_col[yy, xx, j] = -1
            out_dist[yy, xx, j] = np.inf
        else:
            out_col[yy, xx, j] = np.int32(kk & _IDX_MASK)
            out_dist[yy, xx, j] = np.float32(dmin + np.float64(kk >> _IDX_BITS) / q_scale)
    if k2 == _NO_KEY:
        out_conf[yy, xx] = np.float32(0.0)
    else:
        d1 = dmin + np.float64(k1 >> _IDX_BITS) / q_scale
        d2 = dmin + np.float64(k2 >> _IDX_BITS) / q_scale
        out_conf[yy, xx] = np.float32((d2 - d1) / d2) if d2 > 0 else np.float32(0.0)


@cuda.jit(device=True)
def write_none(out_col, out_dist, out_conf, yy, xx):
    """An undecoded pixel: no candidates, infinite distances, confidence 0."""
    for j in range(3):
        out_col[yy, xx, j] = -1
        out_dist[yy, xx, j] = np.inf
    out_conf[yy, xx] = np.float32(0.0)


@njit(cache=True)
def pixel_logs(white, black, scale, sr2, ss2):
    """(2, H, W) float64 host logs of each pixel's white / black variance, computed exactly as
    `kernels._pixel_params` computes them on the CPU (same expression, same log)."""
    h, w = white.shape
    out = np.empty((2, h, w), np.float64)
    for yy in range(h):
        for xx in range(w):
            a = white[yy, xx] * scale
            b = black[yy, xx] * scale
            out[0, yy, xx] = np.log(sr2 + ss2 * a)
            out[1, yy, xx] = np.log(sr2 + ss2 * b)
    return out
