"""Exactness of the EDC loop's fused and sparse kernels (`edge.edc._kernels`) against naive
references written here (plain python, none of the package's word / table helpers):

* `round1_words` (round 1 of `AdaptiveScan` in one pass) against a per-pixel CRC check: binarise
  each sample against the midpoint of the pixel's levels, recompute the CRC-5 of the ten data
  bits by polynomial long division (frame 0 = highest power, x^5 + x^4 + x^2 + 1), the column by
  the base code's rows, the contrast floor of the docstring, and the guess (given, the column,
  or the nearest codeword by brute force, lowest row on ties), with rows beyond ``n_columns``
  and unmeasurable rows refused; self-calibrated and calibrated, 1 x 1 and 7 x 19 images
  (not a multiple of any lane count), samples exactly at the midpoint;
* `support_full` / `support_at` against the neighbour-support rule of `_supported`'s docstring;
* `nearest_codewords_distance` with ties (lowest index);
* `grow_guesses` against the fixed point of "a candidate next to a reported pixel with a close
  column is reported".

Every output is an integer or a flag and is compared exactly; the floor's float32 arithmetic is
written out in the same precision the docstring's kernel uses (float32 levels, the square root
of the float64 variance rounded to float32).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from edge.codes import get_code
from edge.edc import _kernels as K
from edge.edc.lookup import membership_table, packed_codewords

CODE = "xor02-10+crc5"
POLY_FULL = 0b110101  # x^5 + x^4 + x^2 + 1 (CRC-5-ITU, the code's default)


def _crc5(data_bits):
    """CRC of the data bits (bit 0 = coefficient of the highest power) by long division."""
    reg = 0
    for b in list(data_bits) + [0] * 5:
        reg = (reg << 1) | int(b)
        if reg >> 5:
            reg ^= POLY_FULL
    return [(reg >> (4 - i)) & 1 for i in range(5)]


def _round1_reference(frames, n, white, black, self_cal, fs, min_contrast, sigmas, sr2, ss2, q, base_rows,
                      given, n_columns, unmeasurable, codebook):
    _, h, w = frames.shape
    cand = np.full((h, w), -1, np.int32)
    pend = np.zeros((h, w), bool)
    guess = np.full((h, w), -1, np.int32)
    f32 = np.float32
    for y in range(h):
        for x in range(w):
            s = [f32(frames[i, y, x]) for i in range(n)]
            hi, lo = (max(s), min(s)) if self_cal else (f32(white[y, x]), f32(black[y, x]))
            t = (hi + lo) * f32(0.5)
            bits = [int(v > t) for v in s]
            hn = f32(hi / f32(fs))
            contrast = f32(hn - f32(lo / f32(fs)))
            if self_cal:
                ok = contrast > f32(sigmas) * f32(math.sqrt(sr2 + ss2 * float(max(hn, f32(0))) + q))
            else:
                ok = float(contrast) > min_contrast
            if not ok:
                continue
            pend[y, x] = True
            c = base_rows.get(tuple(bits[:10]), -1) if _crc5(bits[:10]) == bits[10:] else -1
            if c >= n_columns or (c >= 0 and unmeasurable[c]):
                c = -1
            cand[y, x] = c
            if given is not None:
                g = int(given[y, x])
            elif c >= 0:
                g = c
            else:
                dists = [sum(a != b for a, b in zip(bits, row)) for row in codebook]
                g = dists.index(min(dists))                 # lowest row on ties
            if 0 <= g < n_columns and not unmeasurable[g]:
                guess[y, x] = g
    return cand, pend, guess


def _frames(code, h, w, rng):
    """Codeword samples at random levels (some flipped bits, some samples at the midpoint exactly,
    some pixels without contrast), with white and black frames after the n code frames."""
    n = code.n
    rows = rng.integers(0, len(code.codebook), (h, w))
    bits = code.codebook[rows].transpose(2, 0, 1).astype(np.int64)        # (n, h, w)
    flip = rng.random((n, h, w)) < 0.03
    bits = bits ^ flip
    lo = rng.integers(0, 60, (h, w))
    hi = lo + rng.choice([0, 2, 6, 40, 120], (h, w))
    frames = lo + bits * (hi - lo) + rng.integers(-2, 3, (n, h, w)) * (rng.random((n, h, w)) < 0.3)
    mid = rng.random((n, h, w)) < 0.03
    frames = np.where(mid & ((hi - lo) % 2 == 0), (hi + lo) // 2, frames)   # exactly at the midpoint
    out = np.concatenate([frames, hi[None], lo[None]]).clip(0, 255).astype(np.uint8)
    return out


@pytest.mark.parametrize("shape", [(1, 1), (7, 19), (3, 33)])
@pytest.mark.parametrize("self_cal", [True, False])
@pytest.mark.parametrize("with_given", [False, True])
def test_round1_words_match_a_naive_crc_check(shape, self_cal, with_given):
    code = get_code(CODE)
    base = get_code("xor02-10")
    base_rows = {tuple(int(v) for v in r): i for i, r in enumerate(base.codebook)}
    codebook = [list(map(int, r)) for r in code.codebook]
    rng = np.random.default_rng([*shape, self_cal, with_given])
    n_columns = 900
    unmeasurable = rng.random(n_columns) < 0.05
    fs, sigmas, sr2, ss2 = 255.0, 3.0, 1e-4, 4e-4
    q = 1.0 / (12.0 * fs ** 2)
    for _ in range(3):
        f = _frames(code, *shape, rng)
        n = code.n
        white, black = (f[0], f[0]) if self_cal else (f[n], f[n + 1])
        given = rng.integers(-1, 1100, shape).astype(np.int32) if with_given else None
        args = (f, n, np.ascontiguousarray(white), np.ascontiguousarray(black), self_cal, fs, 0.03, sigmas, sr2, ss2,
                q)
        got = K.round1_words(*args, membership_table(code), packed_codewords(code),
                             given if with_given else np.zeros((1, 1), np.int32), with_given, n_columns, unmeasurable)
        want = _round1_reference(*args, base_rows, given, n_columns, unmeasurable, codebook)
        for g, r, name in zip(got, want, ("candidate", "open", "guess")):
            assert np.array_equal(g, r), name


# ----------------------------------------------------------------------- neighbour support

def _supported_reference(ref, y, x, c, tol):
    h, w = ref.shape
    side = [int(ref[yy, xx]) for yy in (y - 1, y, y + 1) for xx in (x - 1, x + 1) if 0 <= yy < h and 0 <= xx < w]
    side = [r for r in side if r >= 0]
    if side:
        return any(abs(r - c) <= tol for r in side)
    vert = [int(ref[yy, x]) for yy in (y - 1, y + 1) if 0 <= yy < h]
    return any(r >= 0 and abs(r - c) <= tol for r in vert)


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (9, 1), (6, 17)])
@pytest.mark.parametrize("tol", [0, 1, 3])
def test_support_matches_the_naive_rule(shape, tol):
    rng = np.random.default_rng([*shape, tol])
    col = np.where(rng.random(shape) < 0.6, np.arange(shape[1])[None, :] + rng.integers(-4, 5, shape), -1)
    col = col.astype(np.int32)
    want = np.array([[col[y, x] >= 0 and _supported_reference(col, y, x, int(col[y, x]), tol)
                      for x in range(shape[1])] for y in range(shape[0])], bool).reshape(shape)
    assert np.array_equal(K.support_full(col, tol), want)
    ys, xs = np.nonzero(np.ones(shape, bool))
    cols = rng.integers(-1, shape[1] + 3, ys.size).astype(np.int32)
    want_at = [c >= 0 and _supported_reference(col, y, x, int(c), tol) for y, x, c in zip(ys, xs, cols)]
    assert K.support_at(ys, xs, cols, col, tol).tolist() == want_at


def test_nearest_codewords_distance_takes_the_lowest_index_on_ties():
    rng = np.random.default_rng(5)
    book = rng.integers(0, 1 << 12, 40).astype(np.int64)
    book[7] = book[3]                                          # duplicates: always a tie
    words = np.r_[rng.integers(0, 1 << 12, 500), book[3], book[3] ^ 1].astype(np.int64)
    idx, dist = K.nearest_codewords_distance(words, book)
    for p, wd in enumerate(words):
        d = [bin(int(wd) ^ int(b)).count("1") for b in book]
        assert (idx[p], dist[p]) == (d.index(min(d)), min(d))
    assert np.array_equal(K.nearest_codewords(words, book), idx)


# ----------------------------------------------------------------------- region growing

def _grow_reference(verified, guess, cand_mask, tol):
    h, w = verified.shape
    out = verified.copy()
    changed = True
    while changed:
        changed = False
        for y in range(h):
            for x in range(w):
                if not cand_mask[y, x] or out[y, x] >= 0 or guess[y, x] < 0:
                    continue
                g = int(guess[y, x])
                if any(out[yy, xx] >= 0 and abs(int(out[yy, xx]) - g) <= tol
                       for yy in range(max(0, y - 1), min(h, y + 2)) for xx in range(max(0, x - 1), min(w, x + 2))):
                    out[y, x] = g
                    changed = True
    return out


@pytest.mark.parametrize("shape, seed", [((1, 1), 0), ((1, 12), 1), ((8, 13), 2), ((12, 5), 3)])
@pytest.mark.parametrize("tol", [0, 1, 2])
def test_grow_guesses_is_the_reachability_fixed_point(shape, seed, tol):
    rng = np.random.default_rng([seed, tol])
    truth = (np.arange(shape[1])[None, :] + np.arange(shape[0])[:, None]).astype(np.int32)
    verified = np.where(rng.random(shape) < 0.1, truth, -1).astype(np.int32)
    guess = np.where(rng.random(shape) < 0.8, truth, truth + rng.integers(3, 30, shape))
    guess = np.where(rng.random(shape) < 0.1, -1, guess).astype(np.int32)
    cand_mask = (verified < 0) & (rng.random(shape) < 0.85)
    cand_mask[0, 0] |= verified[0, 0] >= 0                      # a candidate that is verified already
    cy, cx = np.nonzero(cand_mask)
    got = K.grow_guesses(verified, guess, cy, cx, tol)
    assert np.array_equal(got, _grow_reference(verified, guess, cand_mask, tol))
