"""Top-3 keys and candidate ranges shared by every search kernel.

A key is ``(cost << IDX_BITS) | column`` (int64, cost >= 0 the quantised cost of
`edge.decode.kernels.cost`), so the smaller key is the better candidate and ties go to the lower
column; ``NO_KEY`` marks an empty slot.  `_write` turns the three best keys of a pixel into the
decoder's outputs (column, distance ``dmin + cost / q_scale``, confidence ``(d2 - d1) / d2``).
`Band` / `_band`: the candidate columns of a camera column under a disparity band.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


class Band(NamedTuple):
    """Candidate columns of every pixel (the kernels' ``band`` argument).

    ncols: codebook rows in use (columns 0..ncols-1); use_band: restrict to the disparity band;
    min_d, max_d: band in camera pixels (disparity = x - column * stripe); stripe: projector
    columns per codebook row.
    """

    ncols: int
    use_band: bool
    min_d: int
    max_d: int
    stripe: int


#: Bits of a top-3 key that hold the column; the cost sits above them.
IDX_BITS = 16
IDX_MASK = (1 << IDX_BITS) - 1
NO_KEY = np.int64(1) << np.int64(62)
#: A slot of a search with a margin (`edge.decode.kernels.lanes`) that holds a codeword at least
#: the margin behind the best, not located: `_write` gives it the row `BEYOND` and distance inf.
BEYOND_KEY = NO_KEY - np.int64(1)
#: The candidate row of a `BEYOND_KEY` slot (-1 is an empty slot).
BEYOND = -2


@njit(cache=True)
def _insert(key, k1, k2, k3):
    if key < k3:
        if key < k2:
            k3 = k2
            if key < k1:
                k2 = k1
                k1 = key
            else:
                k2 = key
        else:
            k3 = key
    return k1, k2, k3


@njit(cache=True)
def _band(x, use_band, min_d, max_d, stripe, ncols):
    """Candidate columns [lo, hi] of camera column x (empty when lo > hi)."""
    if not use_band:
        return 0, ncols - 1
    lo = (x - max_d) // stripe
    hi = (x - min_d) // stripe
    if lo < 0:
        lo = 0
    if hi > ncols - 1:
        hi = ncols - 1
    return lo, hi


@njit(cache=True)
def _pixel_start(white, black, yy, xx, scale, use_band, min_d, max_d, stripe, ncols):
    """(a, b, lo, hi, ok) of pixel (yy, xx): normalised white / black levels, candidate columns
    [lo, hi] and whether it can be decoded (white > black and a non-empty band)."""
    a = white[yy, xx] * scale
    b = black[yy, xx] * scale
    lo, hi = _band(xx, use_band, min_d, max_d, stripe, ncols)
    return a, b, lo, hi, (a > b) and lo <= hi


@njit(cache=True)
def sort_small(a, m):
    for i in range(1, m):
        t = a[i]
        j = i - 1
        while j >= 0 and a[j] > t:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = t


@njit(cache=True)
def _write(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale, margin=np.inf):
    """One pixel's outputs from its three keys: rows (-1 empty, `BEYOND` not located), distances
    ``float32(dmin + cost / q_scale)`` (inf for both), confidence ``(d2 - d1) / d2`` (0 without a
    second; with k2 = `BEYOND_KEY` its lower bound ``margin / (d1 + margin)``, d2 >= d1 + margin)."""
    keys = (k1, k2, k3)
    for j in range(3):
        kk = keys[j]
        if kk == NO_KEY:
            out_col[yy, xx, j] = -1
            out_dist[yy, xx, j] = np.inf
        elif kk == BEYOND_KEY:
            out_col[yy, xx, j] = BEYOND
            out_dist[yy, xx, j] = np.inf
        else:
            out_col[yy, xx, j] = np.int32(kk & IDX_MASK)
            out_dist[yy, xx, j] = np.float32(dmin + (kk >> IDX_BITS) / q_scale)
    if k2 == NO_KEY:
        out_conf[yy, xx] = 0.0
    elif k2 == BEYOND_KEY:
        d1 = dmin + (k1 >> IDX_BITS) / q_scale
        out_conf[yy, xx] = np.float32(margin / (d1 + margin)) if d1 + margin > 0 else np.float32(0.0)
    else:
        d1 = dmin + (k1 >> IDX_BITS) / q_scale
        d2 = dmin + (k2 >> IDX_BITS) / q_scale
        out_conf[yy, xx] = np.float32((d2 - d1) / d2) if d2 > 0 else np.float32(0.0)


@njit(cache=True)
def _write_none(out_col, out_dist, out_conf, yy, xx):
    for j in range(3):
        out_col[yy, xx, j] = -1
        out_dist[yy, xx, j] = np.inf
    out_conf[yy, xx] = 0.0
