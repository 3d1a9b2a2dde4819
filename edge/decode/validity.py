"""Stages 3 and 5 of `edge.decode.decode`: eligibility and the validity rule.

`eligibility`: (H, W) int32 top-1 column and (H, W) bool eligible = contrast >= min_contrast and
a column.  `valid_mask`: the valid mask of the settings (see `edge.decode.decoder`) from the
spatial stage's output.

Fused per-pixel passes of `decode`'s valid mask (numba, one pass each instead of a chain of
whole-image numpy temporaries).

Thresholds are compared in float32, as numpy compares a float32 array with a Python float
(NEP 50): contrast ``(float32(white) - float32(black)) * float32(scale)`` against
``float32(min_contrast)``, confidence (float32) against ``float32(min_confidence)`` and
``float32(t_low)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..capture import CodedCapture
from .settings import DecodeSettings
from .spatial import Spatial


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


def eligibility(stack: CodedCapture, candidates: np.ndarray, min_contrast: float) -> tuple[np.ndarray, np.ndarray]:
    """(column (H, W) int32 = candidates[..., 0], eligible (H, W) bool): contrast
    ``(white - black) * scale >= min_contrast`` (normalised units, float32) and a column."""
    h, w = stack.shape
    column = np.empty((h, w), np.int32)
    eligible = np.empty((h, w), np.bool_)
    eligible_column(candidates, stack.white, stack.black, np.float32(stack.scale), np.float32(min_contrast),
                    column, eligible)
    return column, eligible


def valid_mask(spatial: Spatial, confidence: np.ndarray, eligible: np.ndarray,
               settings: DecodeSettings) -> tuple[np.ndarray, np.ndarray]:
    """The validity rule: (column (H, W) int32, -1 where invalid; valid (H, W) bool).

    Where the spatial stage decided validity ("list" / "median" filters) its mask is kept;
    otherwise ``eligible & (confidence >= min_confidence | (spatial_check & confidence >= t_low
    & support))``.
    """
    if spatial.valid is not None:
        column = np.where(spatial.valid, spatial.column, -1).astype(np.int32)
        return column, column >= 0
    h, w = spatial.column.shape
    column = np.empty((h, w), np.int32)
    valid = np.empty((h, w), np.bool_)
    use_support = spatial.support is not None
    final_mask(spatial.column, confidence, eligible, spatial.support if use_support else eligible, use_support,
               np.float32(settings.min_confidence), np.float32(settings.t_low), column, valid)
    return column, valid
