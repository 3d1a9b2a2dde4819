"""Spatial post-processing of decoded columns (paper section 3.2.4).

* `order_prior`: list decoding with the order prior.  Along each image row (an epipolar line in
  the rectified setup) pixels with confidence >= t_high are anchors.  On a continuous surface
  the projector column does not decrease from left to right, so a low-confidence pixel between
  a left anchor L and a right anchor R (each at most `max_gap` pixels away, with
  col(L) <= col(R)) takes the best of its top-3 candidates with col(L) <= c <= col(R); if none
  fits it is invalid.  Pixels without such a bracket keep their best candidate if their
  confidence is >= t_low.
* `confidence_median`: 5x5 (`window`) median filter in which only high-confidence pixels
  (>= t_high) vote.  A pixel below t_low takes the vote median; a pixel between t_low and
  t_high keeps its column if it is within `tol` of the vote median, else takes the median;
  pixels need at least `min_votes` votes, else low-confidence pixels become invalid.
* `spatial_outliers`: the evaluation test for smooth scenes: a valid column differing by more
  than `tol` from the median of the valid columns in its `window` x `window` neighbourhood.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def _order_prior(cand, conf, ok, t_high, t_low, max_gap, out_col, out_valid):
    height, width, _ = cand.shape
    for yy in prange(height):
        left_x = np.full(width, -1, np.int64)
        right_x = np.full(width, -1, np.int64)
        last = -1
        for xx in range(width):
            left_x[xx] = last
            if ok[yy, xx] and conf[yy, xx] >= t_high:
                last = xx
        last = -1
        for xx in range(width - 1, -1, -1):
            right_x[xx] = last
            if ok[yy, xx] and conf[yy, xx] >= t_high:
                last = xx
        for xx in range(width):
            c0 = cand[yy, xx, 0]
            out_col[yy, xx] = c0
            if not ok[yy, xx]:
                out_valid[yy, xx] = False
                continue
            if conf[yy, xx] >= t_high:
                out_valid[yy, xx] = True
                continue
            lx = left_x[xx]
            rx = right_x[xx]
            if lx >= 0 and rx >= 0 and xx - lx <= max_gap and rx - xx <= max_gap:
                cl = cand[yy, lx, 0]
                cr = cand[yy, rx, 0]
                if cl <= cr:
                    chosen = -1
                    for j in range(3):
                        c = cand[yy, xx, j]
                        if c >= 0 and cl <= c and c <= cr:
                            chosen = c
                            break
                    out_col[yy, xx] = chosen
                    out_valid[yy, xx] = chosen >= 0
                    continue
            out_valid[yy, xx] = conf[yy, xx] >= t_low


def order_prior(
    candidates: np.ndarray,
    confidence: np.ndarray,
    ok: np.ndarray,
    *,
    t_high: float,
    t_low: float,
    max_gap: int = 16,
) -> tuple[np.ndarray, np.ndarray]:
    """Order-prior list decoding (see module docstring).

    candidates: (H, W, 3) int32 best-first; confidence: (H, W) float32; ok: (H, W) bool pixels
    eligible at all (contrast).  Returns column (H, W) int32 and valid (H, W) bool.
    """
    cand = np.ascontiguousarray(candidates, dtype=np.int32)
    h, w, _ = cand.shape
    col = np.empty((h, w), np.int32)
    valid = np.empty((h, w), np.bool_)
    _order_prior(cand, np.ascontiguousarray(confidence, np.float32), np.ascontiguousarray(ok, np.bool_),
                 float(t_high), float(t_low), int(max_gap), col, valid)
    return col, valid


@njit(cache=True, inline="always")
def _median_sorted(buf, m):
    for i in range(1, m):
        t = buf[i]
        j = i - 1
        while j >= 0 and buf[j] > t:
            buf[j + 1] = buf[j]
            j -= 1
        buf[j + 1] = t
    if m % 2 == 1:
        return buf[m // 2]
    return (buf[m // 2 - 1] + buf[m // 2]) // 2


@njit(cache=True, parallel=True)
def _conf_median(col, conf, eligible, t_low, t_high, radius, min_votes, tol, out_col, out_valid):
    height, width = col.shape
    for yy in prange(height):
        buf = np.empty((2 * radius + 1) ** 2, np.int64)
        for xx in range(width):
            c = col[yy, xx]
            out_col[yy, xx] = c
            if not eligible[yy, xx]:
                out_valid[yy, xx] = False
                continue
            cf = conf[yy, xx]
            if cf >= t_high and c >= 0:
                out_valid[yy, xx] = True
                continue
            m = 0
            for dy in range(-radius, radius + 1):
                y2 = yy + dy
                if y2 < 0 or y2 >= height:
                    continue
                for dx in range(-radius, radius + 1):
                    x2 = xx + dx
                    if x2 < 0 or x2 >= width or (dx == 0 and dy == 0):
                        continue
                    if eligible[y2, x2] and conf[y2, x2] >= t_high and col[y2, x2] >= 0:
                        buf[m] = col[y2, x2]
                        m += 1
            if m < min_votes:
                out_valid[yy, xx] = cf >= t_low and c >= 0
                continue
            med = _median_sorted(buf, m)
            if cf >= t_low and c >= 0 and abs(c - med) <= tol:
                out_valid[yy, xx] = True
            else:
                out_col[yy, xx] = med
                out_valid[yy, xx] = True


def confidence_median(
    column: np.ndarray,
    confidence: np.ndarray,
    eligible: np.ndarray,
    *,
    t_low: float,
    t_high: float,
    window: int = 5,
    min_votes: int = 3,
    tol: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Confidence-based median filter (see module docstring).

    column: (H, W) int32 (-1 = none); confidence (H, W) float32; eligible (H, W) bool pixels that
    may vote or be filled.  Returns column (H, W) int32 and valid (H, W) bool.
    """
    if window < 1 or window % 2 == 0:
        raise ValueError(f"window: expected an odd size >= 1, got {window}")
    col = np.ascontiguousarray(column, dtype=np.int32)
    out_col = np.empty_like(col)
    out_valid = np.empty(col.shape, np.bool_)
    _conf_median(col, np.ascontiguousarray(confidence, np.float32), np.ascontiguousarray(eligible, np.bool_),
                 float(t_low), float(t_high), window // 2, int(min_votes), int(tol), out_col, out_valid)
    return out_col, out_valid


@njit(cache=True, parallel=True)
def _outliers(col, valid, radius, tol, out):
    height, width = col.shape
    for yy in prange(height):
        buf = np.empty((2 * radius + 1) ** 2, np.int64)
        for xx in range(width):
            out[yy, xx] = False
            if not valid[yy, xx]:
                continue
            m = 0
            for y2 in range(max(0, yy - radius), min(height, yy + radius + 1)):
                for x2 in range(max(0, xx - radius), min(width, xx + radius + 1)):
                    if valid[y2, x2]:
                        buf[m] = col[y2, x2]
                        m += 1
            med = _median_sorted(buf, m)
            out[yy, xx] = abs(col[yy, xx] - med) > tol


def spatial_outliers(column: np.ndarray, valid: np.ndarray, *, window: int = 7, tol: int = 2) -> np.ndarray:
    """(H, W) bool: valid pixels whose column differs by > tol from the median of the valid
    columns in their window x window neighbourhood (itself included; even counts take the mean
    of the two middle values, rounded down)."""
    col = np.ascontiguousarray(column, dtype=np.int32)
    out = np.empty(col.shape, np.bool_)
    _outliers(col, np.ascontiguousarray(valid, np.bool_), window // 2, int(tol), out)
    return out


@njit(cache=True, parallel=True)
def _support(col, conf, eligible, t_vote, radius, min_votes, tol, out):
    height, width = col.shape
    for yy in prange(height):
        buf = np.empty((2 * radius + 1) ** 2, np.int64)
        for xx in range(width):
            out[yy, xx] = False
            c = col[yy, xx]
            if not eligible[yy, xx] or c < 0:
                continue
            m = 0
            for y2 in range(max(0, yy - radius), min(height, yy + radius + 1)):
                for x2 in range(max(0, xx - radius), min(width, xx + radius + 1)):
                    if (y2 != yy or x2 != xx) and eligible[y2, x2] and conf[y2, x2] >= t_vote and col[y2, x2] >= 0:
                        buf[m] = col[y2, x2]
                        m += 1
            if m >= min_votes:
                out[yy, xx] = abs(c - _median_sorted(buf, m)) <= tol


def spatial_support(
    column: np.ndarray,
    confidence: np.ndarray,
    eligible: np.ndarray,
    *,
    t_vote: float,
    window: int = 5,
    min_votes: int = 3,
    tol: int = 1,
) -> np.ndarray:
    """(H, W) bool: the pixel's column is within `tol` of the median of the columns of the
    high-confidence (>= t_vote) eligible pixels in its window x window neighbourhood (itself
    excluded), with at least `min_votes` voters.  Columns are not changed."""
    col = np.ascontiguousarray(column, dtype=np.int32)
    out = np.empty(col.shape, np.bool_)
    _support(col, np.ascontiguousarray(confidence, np.float32), np.ascontiguousarray(eligible, np.bool_),
             float(t_vote), window // 2, int(min_votes), int(tol), out)
    return out
