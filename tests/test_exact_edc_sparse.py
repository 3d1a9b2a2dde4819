"""Exactness of the EDC loop's word packers and level gatherers (`edge.edc._kernels`:
`pack_words_at`, `pack_words_full`, `gather_pixels`, `gather_extremes`, `extremes_full`), which
tests/test_edc.py compares only with the package's own `pack_bits`, against references written
here with plain python integers (none of the package's word helpers):

* a pixel's word is ``sum(1 << i for i in range(n) if 2 * frame[start + i] > hi + lo)`` in exact
  arithmetic (bit i = frame start + i, frame 0 the least significant bit; a sample exactly at the
  midpoint is a 0), for levels that are integers (white / black frames, the frames' extremes) or
  quarter-integers (float32 holds them and their sums exactly, so the kernels' float32 midpoint
  is the exact one);
* unpacked again (``(word >> i) & 1``) every kernel word gives back the per-frame decisions, and
  it lies in ``[0, 2**n)``;
* gathered levels are the pixels' values, the extremes the max / min over the first n frames.

uint8 and uint16 frames (10- and 12-bit values above 255), code offsets ``start`` > 0 (the
ensemble's later codes), n from 1 to 62, samples exactly at the midpoint, pixel lists from
`np.nonzero` and contiguous ones, an empty list, 1 x 1 and odd-sized images.  The argument types
are those the loop passes (no new kernel specialisations).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from edge.edc import _kernels as K


def _word(samples, hi, lo):
    t2 = Fraction(hi) + Fraction(lo)
    return sum(1 << i for i, s in enumerate(samples) if 2 * Fraction(int(s)) > t2)


def _unpack(word, n):
    return [(int(word) >> i) & 1 for i in range(n)]


def _frames(rng, m, h, w, dtype):
    top = 255 if dtype == np.uint8 else 4095
    lo = rng.integers(0, top // 2, (h, w))
    hi = lo + rng.integers(0, top // 2, (h, w))
    bits = rng.random((m, h, w)) < 0.5
    f = np.where(bits, hi, lo) + rng.integers(-3, 4, (m, h, w))
    mid = rng.random((m, h, w)) < 0.05
    f = np.where(mid & ((hi + lo) % 2 == 0), (hi + lo) // 2, f)              # exactly at the midpoint
    return np.clip(f, 0, top).astype(dtype), hi.astype(dtype), lo.astype(dtype)


def _check_words(got, frames, start, n, ys, xs, hi, lo):
    assert got.dtype == np.int64 and got.shape == (len(ys),)
    for p, (y, x) in enumerate(zip(ys.tolist(), xs.tolist())):
        samples = frames[start:start + n, y, x].tolist()
        want = _word(samples, hi[p], lo[p])
        assert int(got[p]) == want, (y, x)
        assert 0 <= int(got[p]) < (1 << n)
        t2 = Fraction(hi[p]) + Fraction(lo[p])
        assert _unpack(got[p], n) == [int(2 * Fraction(int(s)) > t2) for s in samples]


@pytest.mark.parametrize("dtype, shape", [(np.uint8, (1, 1)), (np.uint8, (7, 13)), (np.uint16, (7, 13)),
                                          (np.uint16, (3, 17))])
def test_pack_words_at_matches_python_ints(dtype, shape):
    rng = np.random.default_rng([shape[1], dtype == np.uint8])
    m = 64
    frames, white, black = _frames(rng, m, *shape, dtype)
    frames = np.ascontiguousarray(frames)
    ys, xs = np.nonzero(rng.random(shape) < 0.7 if shape != (1, 1) else np.ones(shape, bool))
    hi, lo = K.gather_pixels(white, ys, xs), K.gather_pixels(black, ys, xs)
    assert hi.dtype == np.float32 and hi.tolist() == [int(white[y, x]) for y, x in zip(ys, xs)]
    assert lo.tolist() == [int(black[y, x]) for y, x in zip(ys, xs)]
    for start, n in [(0, 1), (0, 10), (3, 15), (24, 40), (2, 62)]:
        got = K.pack_words_at(frames, start, n, ys, xs, hi, lo)
        _check_words(got, frames, start, n, ys, xs, hi.tolist(), lo.tolist())
    if dtype == np.uint8:
        # contiguous pixel lists, self-calibrated levels (the extremes of the code's frames), an empty list
        yc, xc = np.ascontiguousarray(ys), np.ascontiguousarray(xs)
        for n in (10, 40):
            h2, l2 = K.gather_extremes(frames, yc, xc, n)
            assert h2.tolist() == [max(frames[:n, y, x].tolist()) for y, x in zip(yc, xc)]
            assert l2.tolist() == [min(frames[:n, y, x].tolist()) for y, x in zip(yc, xc)]
            _check_words(K.pack_words_at(frames, 0, n, yc, xc, h2, l2), frames, 0, n, yc, xc, h2.tolist(), l2.tolist())
            h3, l3 = K.gather_extremes(frames, ys, xs, n)
            assert np.array_equal(h3, h2) and np.array_equal(l3, l2)
        # quarter-integer levels: midpoints at .25 / .5 / .75 (exact in float32)
        hq = (hi + rng.integers(0, 4, hi.size) * 0.25).astype(np.float32)
        lq = (lo - rng.integers(0, 4, lo.size) * 0.25).astype(np.float32)
        _check_words(K.pack_words_at(frames, 5, 12, yc, xc, hq, lq), frames, 5, 12, yc, xc, hq.tolist(), lq.tolist())
        empty = np.zeros(0, np.int64)
        assert K.pack_words_at(frames, 0, 10, empty, empty, np.zeros(0, np.float32), np.zeros(0, np.float32)).size == 0


@pytest.mark.parametrize("shape", [(1, 1), (5, 11), (9, 4)])
def test_pack_words_full_matches_python_ints(shape):
    rng = np.random.default_rng(list(shape))
    frames, white, black = _frames(rng, 50, *shape, np.uint8)
    frames = np.ascontiguousarray(frames)
    white, black = np.ascontiguousarray(white), np.ascontiguousarray(black)
    ys, xs = np.nonzero(np.ones(shape, bool))
    for start, n in [(0, 1), (0, 10), (7, 15), (10, 40)]:
        # calibrated: uint8 white / black images
        got = K.pack_words_full(frames, start, n, white, black)
        assert got.shape == shape and got.dtype == np.int64
        _check_words(got[ys, xs], frames, start, n, ys, xs, white[ys, xs].tolist(), black[ys, xs].tolist())
        # self-calibrated: float32 extremes over the frames (from frame 0, as the loop's round 1)
        hi, lo = K.extremes_full(frames, start + n)
        assert hi.dtype == np.float32
        assert hi.tolist() == frames[:start + n].max(axis=0).tolist()
        assert lo.tolist() == frames[:start + n].min(axis=0).tolist()
        got = K.pack_words_full(frames, start, n, hi, lo)
        _check_words(got[ys, xs], frames, start, n, ys, xs, hi[ys, xs].tolist(), lo[ys, xs].tolist())
        # quarter-integer float32 levels
        hq = (white + rng.integers(0, 4, shape) * 0.25).astype(np.float32)
        lq = (black - rng.integers(0, 4, shape) * 0.25).astype(np.float32)
        got = K.pack_words_full(frames, start, n, hq, lq)
        _check_words(got[ys, xs], frames, start, n, ys, xs, hq[ys, xs].tolist(), lq[ys, xs].tolist())
