"""Numba kernels of the adaptive loop: everything works on the list of OPEN pixels only.

A round of `edge.edc.adaptive.AdaptiveScan` touches only the camera pixels still open (a pixel
list ``ys, xs``), never the full frame: gathering their samples, binarising, packing the word,
the codebook look-up, the nearest codeword of a failing word and the neighbour-support test are
O(open pixels x frames).  All kernels are exact integer / float32 re-implementations of the numpy
reference functions next to them (`edge.edc.lookup.lookup_columns`, `edge.edc.adaptive.supported`);
tests compare the two.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def gather_extremes(frames: np.ndarray, ys: np.ndarray, xs: np.ndarray, n: int):
    """(hi, lo) float32 (P,): max and min of frames[:n, ys[p], xs[p]] (self-calibrated levels)."""
    p_count = ys.size
    hi = np.empty(p_count, dtype=np.float32)
    lo = np.empty(p_count, dtype=np.float32)
    for p in prange(p_count):
        y, x = ys[p], xs[p]
        a = np.float32(frames[0, y, x])
        b = a
        for i in range(1, n):
            v = np.float32(frames[i, y, x])
            if v > a:
                a = v
            if v < b:
                b = v
        hi[p] = a
        lo[p] = b
    return hi, lo


@njit(cache=True, parallel=True)
def gather_pixels(image: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """(P,) float32 image[ys, xs]."""
    out = np.empty(ys.size, dtype=np.float32)
    for p in prange(ys.size):
        out[p] = np.float32(image[ys[p], xs[p]])
    return out


@njit(cache=True, parallel=True)
def pack_words_at(frames: np.ndarray, start: int, n: int, ys: np.ndarray, xs: np.ndarray,
                  hi: np.ndarray, lo: np.ndarray) -> np.ndarray:
    """(P,) int64 words: bit i (frame start + i, MSB first) = sample > (hi + lo) / 2."""
    out = np.empty(ys.size, dtype=np.int64)
    for p in prange(ys.size):
        y, x = ys[p], xs[p]
        t = (hi[p] + lo[p]) * np.float32(0.5)
        w = np.int64(0)
        for i in range(n):
            w = (w << 1) | (1 if np.float32(frames[start + i, y, x]) > t else 0)
        out[p] = w
    return out


@njit(cache=True)
def _popcount(v: np.int64) -> int:
    c = 0
    while v:
        v &= v - 1
        c += 1
    return c


@njit(cache=True, parallel=True)
def nearest_codewords(words: np.ndarray, codewords: np.ndarray) -> np.ndarray:
    """(P,) int32 index of the codeword nearest in Hamming distance (lowest index on ties)."""
    out = np.empty(words.size, dtype=np.int32)
    for p in prange(words.size):
        best, arg = 1 << 30, -1
        w = words[p]
        for c in range(codewords.size):
            d = _popcount(w ^ codewords[c])
            if d < best:
                best, arg = d, c
                if d == 0:
                    break
        out[p] = arg
    return out


@njit(cache=True, parallel=True)
def support_at(ys: np.ndarray, xs: np.ndarray, cols: np.ndarray, ref: np.ndarray, tolerance: int) -> np.ndarray:
    """(P,) bool: pixel (ys[p], xs[p]) with column cols[p] is supported by the column map ``ref``.

    Same rule as `edge.edc.adaptive.supported`: some neighbour at dx = +-1 (dy in -1..1) has a
    column within ``tolerance``, or, when none of those six has a column, the pixel above or below.
    """
    h, w = ref.shape
    out = np.zeros(ys.size, dtype=np.bool_)
    for p in prange(ys.size):
        y, x, c = ys[p], xs[p], cols[p]
        if c < 0:
            continue
        near_h = False
        any_h = False
        for dy in range(-1, 2):
            yy = y + dy
            if yy < 0 or yy >= h:
                continue
            for dx in (-1, 1):
                xx = x + dx
                if xx < 0 or xx >= w:
                    continue
                r = ref[yy, xx]
                if r >= 0:
                    any_h = True
                    if abs(r - c) <= tolerance:
                        near_h = True
        if near_h:
            out[p] = True
        elif not any_h:
            for dy in (-1, 1):
                yy = y + dy
                if 0 <= yy < h:
                    r = ref[yy, x]
                    if r >= 0 and abs(r - c) <= tolerance:
                        out[p] = True
    return out


@njit(cache=True)
def grow_guesses(verified: np.ndarray, guess: np.ndarray, candidate: np.ndarray, tolerance: int) -> np.ndarray:
    """(H, W) int32: ``verified`` plus the candidate guesses reachable from it by region growing.

    verified: (H, W) int32 columns (-1 = none); guess: (H, W) int32 candidate columns; candidate:
    (H, W) bool.  Breadth-first from every verified pixel: an 8-neighbour candidate whose guess is
    within ``tolerance`` codewords of the reported column of the pixel it is reached from is
    reported too and grows further.  A guess is therefore kept only when a chain of smoothly
    varying columns links it to a verified pixel (a surface continues; a wrong word jumps).
    """
    h, w = verified.shape
    out = verified.copy()
    qy = np.empty(h * w, dtype=np.int32)
    qx = np.empty(h * w, dtype=np.int32)
    head, tail = 0, 0
    for y in range(h):
        for x in range(w):
            if verified[y, x] >= 0:
                qy[tail] = y
                qx[tail] = x
                tail += 1
    while head < tail:
        y, x = qy[head], qx[head]
        head += 1
        c = out[y, x]
        for dy in range(-1, 2):
            yy = y + dy
            if yy < 0 or yy >= h:
                continue
            for dx in range(-1, 2):
                xx = x + dx
                if xx < 0 or xx >= w or (dy == 0 and dx == 0):
                    continue
                if candidate[yy, xx] and out[yy, xx] < 0:
                    g = guess[yy, xx]
                    if g >= 0 and abs(g - c) <= tolerance:
                        out[yy, xx] = g
                        qy[tail] = yy
                        qx[tail] = xx
                        tail += 1
    return out
