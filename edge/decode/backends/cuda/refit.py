"""Level self-calibration (``levels="refit"``) on the GPU: `edge.decode.levels` per pixel, float32.

Three kernels, each one thread per pixel, each the numpy expression of `levels` with the same
float32 operations in the same order (numpy reduces an (n, H, W) stack over axis 0 by adding
whole frames in order, so the per-pixel sums here run i = 0..n-1 too):

* `normalise`: frames, white, black -> float32 ``raw.astype(float32) * float32(scale)``.
* `initial_levels`: where ``white <= black``, the means of the lower / upper half of the
  pixel's sorted n + 2 samples (white = max(upper, lower + MIN_CONTRAST)); numpy reduces that
  (samples, pixels) array along its contiguous axis, so the means use its pairwise order.
* `refine_levels`: the least-squares on / off levels from the decoded codebook rows.
"""

from __future__ import annotations

import numpy as np
from numba import cuda

from ...levels import MIN_CONTRAST
from .cost import mul32, pixel_of, sort_small

TPB = 128
_MINC = np.float32(MIN_CONTRAST)
#: Largest n + 2 of `initial_levels`' per-pixel sample sort (local memory).
MAX_SAMPLES = 66


@cuda.jit
def normalise(frames, white, black, scale, out_f, out_w, out_b):
    """out_* (float32) = raw.astype(float32) * scale (scale float32)."""
    n = frames.shape[0]
    yy, xx, inside = pixel_of(cuda.grid(1), frames.shape[1], frames.shape[2])
    if not inside:
        return
    for i in range(n):
        out_f[i, yy, xx] = mul32(np.float32(frames[i, yy, xx]), scale)
    out_w[yy, xx] = mul32(np.float32(white[yy, xx]), scale)
    out_b[yy, xx] = mul32(np.float32(black[yy, xx]), scale)


@cuda.jit(device=True)
def _pairwise_sum(s, start, count):
    """float32 sum of s[start:start + count] in numpy's pairwise order (count <= 128: one block of
    eight accumulators), the order of `levels.initial_levels`' means (a contiguous reduction)."""
    if count < 8:
        res = np.float32(0.0)
        for i in range(count):
            res = res + s[start + i]
        return res
    r0 = s[start]
    r1 = s[start + 1]
    r2 = s[start + 2]
    r3 = s[start + 3]
    r4 = s[start + 4]
    r5 = s[start + 5]
    r6 = s[start + 6]
    r7 = s[start + 7]
    i = 8
    while i < count - count % 8:
        r0 = r0 + s[start + i]
        r1 = r1 + s[start + i + 1]
        r2 = r2 + s[start + i + 2]
        r3 = r3 + s[start + i + 3]
        r4 = r4 + s[start + i + 4]
        r5 = r5 + s[start + i + 5]
        r6 = r6 + s[start + i + 6]
        r7 = r7 + s[start + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < count:
        res = res + s[start + i]
        i += 1
    return res


@cuda.jit
def initial_levels(f, w, b):
    """In place: where not w > b, w, b = max(hi, lo + MIN_CONTRAST), lo (`levels.initial_levels`)."""
    s = cuda.local.array(MAX_SAMPLES, np.float32)
    n = f.shape[0]
    yy, xx, inside = pixel_of(cuda.grid(1), f.shape[1], f.shape[2])
    if not inside:
        return
    if w[yy, xx] > b[yy, xx]:
        return
    m = n + 2
    for i in range(n):
        s[i] = f[i, yy, xx]
    s[n] = w[yy, xx]
    s[n + 1] = b[yy, xx]
    sort_small(s, m)  # values only: the order of equal samples is moot
    half = m // 2
    lo = _pairwise_sum(s, 0, half) / np.float32(half)
    hi = _pairwise_sum(s, m - half, half) / np.float32(half)
    w[yy, xx] = max(hi, lo + _MINC)
    b[yy, xx] = lo


@cuda.jit
def refine_levels(f, w, b, xtab, sx_tab, sxx_tab, cand, out_w, out_b):
    """`levels.refine_levels`: xtab (size, n) float32 symbols s / (q - 1) of each codebook row,
    sx_tab / sxx_tab (size,) float32 their sums + 1 and sums of squares + 1 (`refit_tables`);
    cand (H, W, 3) int32 candidates: the column is cand[..., 0] (-1: keep w, b)."""
    n = f.shape[0]
    yy, xx, inside = pixel_of(cuda.grid(1), f.shape[1], f.shape[2])
    if not inside:
        return
    c = cand[yy, xx, 0]
    if c < 0:
        out_w[yy, xx] = w[yy, xx]
        out_b[yy, xx] = b[yy, xx]
        return
    zero = np.float32(0.0)
    mm = np.float32(n + 2)
    sr = zero
    sxr = zero
    for i in range(n):
        x = xtab[c, i]
        r = f[i, yy, xx]
        if i == 0:
            sr = r
            sxr = mul32(x, r)
        else:
            sr = sr + r
            sxr = sxr + mul32(x, r)
    wv = w[yy, xx]
    bv = b[yy, xx]
    sx = sx_tab[c]
    sxx = sxx_tab[c]
    sr = (sr + wv) + bv
    sxr = sxr + wv
    den = mul32(mm, sxx) - mul32(sx, sx)
    slope = (mul32(mm, sxr) - mul32(sx, sr)) / den
    intercept = (sr - mul32(slope, sx)) / mm
    bb = max(intercept, zero)
    out_b[yy, xx] = bb
    out_w[yy, xx] = bb + max(slope, _MINC)


def refit_tables(code) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(xtab (size, n), sx_tab (size,), sxx_tab (size,)) float32 for `refine_levels`.

    The sums over a codeword's symbols are taken by the same numpy reduction as
    `levels.refine_levels` (a reduction over a contiguous axis: numpy's pairwise order), so
    they are its float32 values exactly; the sums over frames run frame by frame in both."""
    xt = code.codebook.astype(np.float32) / np.float32(code.q - 1)
    x = np.moveaxis(xt[None], -1, 0)  # (n, 1, size), the layout refine_levels reduces
    sx = (x.sum(axis=0) + 1.0)[0]
    sxx = ((x * x).sum(axis=0) + 1.0)[0]
    return np.ascontiguousarray(xt), np.ascontiguousarray(sx, np.float32), np.ascontiguousarray(sxx, np.float32)
