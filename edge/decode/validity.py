"""Fused per-pixel passes of `decode`'s valid mask (numba, one pass each instead of a chain of
whole-image numpy temporaries).

Thresholds are compared in float32, as numpy compares a float32 array with a Python float
(NEP 50): contrast ``(float32(white) - float32(black)) * float32(scale)`` against
``float32(min_contrast)``, confidence (float32) against ``float32(min_confidence)`` and
``float32(t_low)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def eligible_column(cand, white, black, scale, min_contrast, out_col, out_eligible):
    """out_col (H, W) int32 = cand[..., 0]; out_eligible (H, W) bool = contrast >= min_contrast
    and cand[..., 0] >= 0.  cand: (H, W, 3) int32; white, black: (H, W) raw frames; scale,
    min_contrast: float32."""
    height, width = white.shape
    for yy in prange(height):
        for xx in range(width):
            c = cand[yy, xx, 0]
            contrast = (np.float32(white[yy, xx]) - np.float32(black[yy, xx])) * scale
            out_col[yy, xx] = c
            out_eligible[yy, xx] = (contrast >= min_contrast) & (c >= 0)


@njit(cache=True, parallel=True)
def final_mask(column, conf, eligible, support, use_support, min_confidence, t_low, out_col, out_valid):
    """valid = eligible & (conf >= min_confidence | (use_support & conf >= t_low & support));
    out_col = column where valid else -1; out_valid = valid.  column (H, W) int32, conf float32,
    eligible / support bool (support ignored unless use_support); thresholds float32."""
    height, width = column.shape
    for yy in prange(height):
        for xx in range(width):
            cf = conf[yy, xx]
            ok = cf >= min_confidence
            if use_support:
                ok = ok | ((cf >= t_low) & support[yy, xx])
            ok = ok & eligible[yy, xx]
            out_valid[yy, xx] = ok
            out_col[yy, xx] = column[yy, xx] if ok else np.int32(-1)
