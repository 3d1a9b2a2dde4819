"""The valid mask on the GPU: `edge.decode.validity` + `edge.decode.spatial.spatial_support`.

* `eligible_column`: column0 = candidates[..., 0]; eligible = contrast >= min_contrast and
  column0 >= 0, contrast ``(float32(white) - float32(black)) * float32(scale)`` (float32
  compares, as on the CPU).
* `support_mask`: per pixel the voters of its window (eligible, column >= 0, confidence >=
  t_vote compared in float64 as `spatial._support` does; itself excluded) are sorted in local
  memory; supported when there are at least `min_votes` and their median (even count: the
  floor of the mean of the middle pair) is within `tol` of the pixel's column; then the final
  rule ``valid = eligible & (conf >= min_confidence | (use_support & conf >= t_low & supported))``.
"""

from __future__ import annotations

import numpy as np
from numba import cuda

from .cost import mul32, pixel_of

TPB = 128
#: Window radius the GPU support check implements (`spatial_support`'s default 5 x 5 window).
RADIUS = 2
_MAXV = (2 * RADIUS + 1) ** 2 - 1


@cuda.jit
def eligible_column(cand, white, black, scale, min_contrast, out_col, out_eligible):
    yy, xx, inside = pixel_of(cuda.grid(1), white.shape[0], white.shape[1])
    if not inside:
        return
    c = cand[yy, xx, 0]
    contrast = mul32(np.float32(white[yy, xx]) - np.float32(black[yy, xx]), scale)
    out_col[yy, xx] = c
    out_eligible[yy, xx] = (contrast >= min_contrast) and (c >= 0)


@cuda.jit
def support_mask(column, conf, eligible, use_support, t_vote, min_votes, tol, min_confidence, t_low,
                 out_col, out_valid):
    v = cuda.local.array(_MAXV, np.int32)
    height = column.shape[0]
    width = column.shape[1]
    yy, xx, inside = pixel_of(cuda.grid(1), height, width)
    if not inside:
        return
    c = column[yy, xx]
    el = eligible[yy, xx]
    supported = False
    if use_support and el and c >= 0:
        m = 0
        for y2 in range(max(0, yy - RADIUS), min(height, yy + RADIUS + 1)):
            for x2 in range(max(0, xx - RADIUS), min(width, xx + RADIUS + 1)):
                if y2 == yy and x2 == xx:
                    continue
                c2 = column[y2, x2]
                if eligible[y2, x2] and np.float64(conf[y2, x2]) >= t_vote and c2 >= 0:
                    t = c2
                    j = m - 1
                    while j >= 0 and v[j] > t:  # insertion into the sorted voters
                        v[j + 1] = v[j]
                        j -= 1
                    v[j + 1] = t
                    m += 1
        if m >= min_votes:
            if m % 2 == 1:
                med = v[m // 2]
            else:
                med = (v[m // 2 - 1] + v[m // 2]) // 2
            supported = abs(med - c) <= tol
    cf = conf[yy, xx]
    ok = cf >= min_confidence
    if use_support:
        ok = ok or ((cf >= t_low) and supported)
    ok = ok and el
    out_valid[yy, xx] = ok
    out_col[yy, xx] = c if ok else np.int32(-1)
