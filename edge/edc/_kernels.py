"""Numba kernels of the adaptive loop: everything works on the list of OPEN pixels only.

A round of `edge.edc.adaptive.AdaptiveScan` touches only the camera pixels still open (a pixel
list ``ys, xs``), never the full frame: gathering their samples, binarising, packing the word,
the codebook look-up, the nearest codeword of a failing word and the neighbour-support test are
O(open pixels x frames); round 1, where every pixel is open, uses the full-frame forms
(`pack_words_full`, `extremes_full`: rows, then frames, then columns: sequential memory).
The kernels are serial on purpose: each takes a few milliseconds at 640 x 480, and a parallel
kernel on a busy machine waits for its slowest thread (measured 3-10x slower than serial with the
service's other threads and processes competing for 2 cores).  All kernels are exact integer / float32 re-implementations of the numpy
reference functions next to them (`edge.decode.check.lookup_columns`, `edge.edc.adaptive.supported`);
tests compare the two.  Words are packed in the one bit order of `edge.codes.words.pack_words`
(bit i = frame i, frame 0 = least significant bit), so `edge.codes.words.membership_table` and
`packed_codewords` index them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from edge.codes.search import _popcount  # the one njit popcount (Kernighan) of the package below


@njit(cache=True)
def gather_extremes(frames: np.ndarray, ys: np.ndarray, xs: np.ndarray, n: int):
    """(hi, lo) float32 (P,): max and min of frames[:n, ys[p], xs[p]] (self-calibrated levels)."""
    p_count = ys.size
    hi = np.empty(p_count, dtype=np.float32)
    lo = np.empty(p_count, dtype=np.float32)
    for p in range(p_count):
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


@njit(cache=True)
def gather_pixels(image: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """(P,) float32 image[ys, xs]."""
    out = np.empty(ys.size, dtype=np.float32)
    for p in range(ys.size):
        out[p] = np.float32(image[ys[p], xs[p]])
    return out


@njit(cache=True)
def pack_words_at(frames: np.ndarray, start: int, n: int, ys: np.ndarray, xs: np.ndarray,
                  hi: np.ndarray, lo: np.ndarray) -> np.ndarray:
    """(P,) int64 words: bit i (frame start + i; `edge.codes.words.pack_words` order, frame 0 = LSB)
    = sample > (hi + lo) / 2."""
    out = np.empty(ys.size, dtype=np.int64)
    for p in range(ys.size):
        y, x = ys[p], xs[p]
        t = (hi[p] + lo[p]) * np.float32(0.5)
        w = np.int64(0)
        for i in range(n - 1, -1, -1):  # last frame first: frame 0 ends in bit 0
            w = (w << 1) | (1 if np.float32(frames[start + i, y, x]) > t else 0)
        out[p] = w
    return out


@njit(cache=True)
def nearest_codewords(words: np.ndarray, codewords: np.ndarray) -> np.ndarray:
    """(P,) int32 index of the codeword nearest in Hamming distance (lowest index on ties)."""
    return nearest_codewords_distance(words, codewords)[0]


@njit(cache=True)
def nearest_codewords_distance(words: np.ndarray, codewords: np.ndarray):
    """(index int32 (P,), Hamming distance int32 (P,)) of the nearest codeword (lowest index on ties)."""
    out = np.empty(words.size, dtype=np.int32)
    dist = np.empty(words.size, dtype=np.int32)
    for p in range(words.size):
        best, arg = 1 << 30, -1
        w = words[p]
        for c in range(codewords.size):
            d = _popcount(w ^ codewords[c])
            if d < best:
                best, arg = d, c
                if d == 0:
                    break
        out[p] = arg
        dist[p] = best
    return out, dist


@njit(cache=True)
def _supported(ref: np.ndarray, y: int, x: int, c: int, tolerance: int) -> bool:
    """Column ``c`` at pixel (y, x) is supported by the column map ``ref`` (-1 = none): some
    neighbour at dx = +-1 (dy in -1..1) has a column within ``tolerance``, or, when none of those
    six has a column, the pixel above or below does."""
    h, w = ref.shape
    any_h = False
    for yy in range(y - 1 if y > 0 else 0, (y + 1 if y < h - 1 else h - 1) + 1):
        for xx in (x - 1, x + 1):
            if 0 <= xx < w:
                r = ref[yy, xx]
                if r >= 0:
                    any_h = True
                    if r - c <= tolerance and c - r <= tolerance:
                        return True
    if any_h:
        return False
    for yy in (y - 1, y + 1):
        if 0 <= yy < h:
            r = ref[yy, x]
            if r >= 0 and r - c <= tolerance and c - r <= tolerance:
                return True
    return False


@njit(cache=True)
def support_at(ys: np.ndarray, xs: np.ndarray, cols: np.ndarray, ref: np.ndarray, tolerance: int) -> np.ndarray:
    """(P,) bool: pixel (ys[p], xs[p]) with column cols[p] is supported by the column map ``ref``.

    Same rule as `edge.edc.adaptive.supported` (`_supported`).
    """
    out = np.zeros(ys.size, dtype=np.bool_)
    for p in range(ys.size):
        if cols[p] >= 0:
            out[p] = _supported(ref, ys[p], xs[p], cols[p], tolerance)
    return out


@njit(cache=True)
def pack_words_full(frames: np.ndarray, start: int, n: int, hi: np.ndarray, lo: np.ndarray) -> np.ndarray:
    """(H, W) int64 words of every pixel: bit i (frame start + i, frame 0 = LSB) = sample > (hi + lo) / 2.

    The full-frame form of `pack_words_at` (round 1 decodes every pixel): row by row,
    frames then columns inside a row (sequential memory access).
    """
    _, h, w = frames.shape
    out = np.zeros((h, w), dtype=np.int64)
    for y in range(h):
        t = np.empty(w, dtype=np.float32)
        for x in range(w):
            t[x] = (np.float32(hi[y, x]) + np.float32(lo[y, x])) * np.float32(0.5)
        for i in range(n - 1, -1, -1):  # last frame first: frame 0 ends in bit 0
            for x in range(w):
                out[y, x] = (out[y, x] << 1) | (np.float32(frames[start + i, y, x]) > t[x])
    return out


@njit(cache=True)
def extremes_full(frames: np.ndarray, n: int):
    """(hi, lo) float32 (H, W): max and min over frames[:n] (row by row)."""
    _, h, w = frames.shape
    hi = np.empty((h, w), dtype=np.float32)
    lo = np.empty((h, w), dtype=np.float32)
    for y in range(h):
        for x in range(w):
            hi[y, x] = np.float32(frames[0, y, x])
            lo[y, x] = hi[y, x]
        for i in range(1, n):
            for x in range(w):
                v = np.float32(frames[i, y, x])
                if v > hi[y, x]:
                    hi[y, x] = v
                if v < lo[y, x]:
                    lo[y, x] = v
    return hi, lo


@njit(cache=True)
def grow_guesses(verified: np.ndarray, guess: np.ndarray, cy: np.ndarray, cx: np.ndarray, tolerance: int) -> np.ndarray:
    """(H, W) int32: ``verified`` plus the candidate guesses reachable from it by region growing.

    verified: (H, W) int32 columns (-1 = none); guess: (H, W) int32 columns of the candidates
    (cy[p], cx[p]).  A candidate is reported (with its guess) when an 8-neighbour is reported with
    a column within ``tolerance`` codewords, transitively from the verified pixels: a guess is
    kept only when a chain of smoothly varying columns links it to a verified pixel (a surface
    continues; a wrong word jumps).  Cost O(candidates), not O(H x W).
    """
    h, w = verified.shape
    out = verified.copy()
    cand = np.zeros((h, w), dtype=np.bool_)
    for p in range(cy.size):
        if guess[cy[p], cx[p]] >= 0:
            cand[cy[p], cx[p]] = True
    qy = np.empty(cy.size, dtype=np.int64)
    qx = np.empty(cy.size, dtype=np.int64)
    head, tail = 0, 0
    for p in range(cy.size):  # seeds: candidates next to a verified pixel with a close column
        y, x = cy[p], cx[p]
        if not cand[y, x] or out[y, x] >= 0:
            continue
        g = guess[y, x]
        hit = False
        for yy in range(max(0, y - 1), min(h, y + 2)):
            for xx in range(max(0, x - 1), min(w, x + 2)):
                r = verified[yy, xx]
                if r >= 0 and r - g <= tolerance and g - r <= tolerance:
                    hit = True
        if hit:
            out[y, x] = g
            qy[tail] = y
            qx[tail] = x
            tail += 1
    while head < tail:
        y, x = qy[head], qx[head]
        head += 1
        c = out[y, x]
        for yy in range(max(0, y - 1), min(h, y + 2)):
            for xx in range(max(0, x - 1), min(w, x + 2)):
                if cand[yy, xx] and out[yy, xx] < 0:
                    g = guess[yy, xx]
                    if g - c <= tolerance and c - g <= tolerance:
                        out[yy, xx] = g
                        qy[tail] = yy
                        qx[tail] = xx
                        tail += 1
    return out


@njit(cache=True)
def round1_words(frames: np.ndarray, n: int, white: np.ndarray, black: np.ndarray, self_cal: bool,
                 full_scale: float, min_contrast: float, sigmas: float, sr2: float, ss2: float, q: float,
                 table: np.ndarray, codewords: np.ndarray, given: np.ndarray, has_given: bool,
                 n_columns: int, unmeasurable: np.ndarray):
    """Round 1 of an EDC scheme in one pass over the frame (every pixel is open in round 1).

    Per pixel: levels (self: min / max of the n frames; else white / black), the floor (self:
    ``(max - min) / fs > sigmas * sqrt(sr2 + ss2 * max / fs + q)``; else ``(white - black) / fs >
    min_contrast``), the word (bit i = frame i > midpoint, frame 0 = LSB), the membership table,
    and the guess (``given`` if has_given, else the column or the nearest codeword), each checked
    against ``n_columns`` and ``unmeasurable``.  Returns (candidate column (H, W) int32: a
    codeword's column, -1 where the word is none or the pixel under the floor; open (H, W) bool:
    over the floor; guess (H, W) int32).
    """
    _, h, w = frames.shape
    cand = np.full((h, w), -1, dtype=np.int32)
    pend = np.zeros((h, w), dtype=np.bool_)
    guess = np.full((h, w), -1, dtype=np.int32)
    hi = np.empty(w, dtype=np.float32)
    lo = np.empty(w, dtype=np.float32)
    word = np.zeros(w, dtype=np.int64)
    fs = np.float32(full_scale)
    for y in range(h):
        if self_cal:
            for x in range(w):
                hi[x] = np.float32(frames[0, y, x])
                lo[x] = hi[x]
            for i in range(1, n):
                for x in range(w):
                    v = np.float32(frames[i, y, x])
                    if v > hi[x]:
                        hi[x] = v
                    if v < lo[x]:
                        lo[x] = v
        else:
            for x in range(w):
                hi[x] = np.float32(white[y, x])
                lo[x] = np.float32(black[y, x])
        for x in range(w):
            word[x] = 0
        for i in range(n - 1, -1, -1):  # last frame first: frame 0 ends in bit 0
            for x in range(w):
                t = (hi[x] + lo[x]) * np.float32(0.5)
                word[x] = (word[x] << 1) | (np.float32(frames[i, y, x]) > t)
        for x in range(w):
            hn = hi[x] / fs
            contrast = hn - lo[x] / fs
            if self_cal:
                level = hn if hn > 0 else np.float32(0.0)
                ok = contrast > np.float32(sigmas) * np.float32(np.sqrt(sr2 + ss2 * level + q))
            else:
                ok = contrast > min_contrast
            if not ok:
                continue
            pend[y, x] = True
            c = table[word[x]]
            if c >= n_columns or (c >= 0 and unmeasurable[c]):
                c = -1
            cand[y, x] = c
            if has_given:
                g = given[y, x]
            elif c >= 0:
                g = c
            else:
                best, g = 1 << 30, -1
                for k in range(codewords.size):
                    d = _popcount(word[x] ^ codewords[k])
                    if d < best:
                        best, g = d, k
            if g >= 0 and g < n_columns and not unmeasurable[g]:
                guess[y, x] = g
    return cand, pend, guess


@njit(cache=True)
def support_full(cand: np.ndarray, tolerance: int) -> np.ndarray:
    """(H, W) bool: `support_at` for every pixel with cand >= 0, against the map ``cand`` itself."""
    h, w = cand.shape
    out = np.zeros((h, w), dtype=np.bool_)
    for y in range(h):
        for x in range(w):
            if cand[y, x] >= 0:
                out[y, x] = _supported(cand, y, x, cand[y, x], tolerance)
    return out
