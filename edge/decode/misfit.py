"""Goodness of fit of the decoded column: pixels that none of the searched codewords explains.

The error probability (`edge.decode.posterior`) weighs the searched codewords against each other;
it cannot see that none of them is right.  That happens where the truth is outside the search: a
surface nearer or farther than the disparity band, projector columns beyond ``columns``, or a
capture the model does not hold for (motion within the stack).  There the best searched codeword
leaves residuals far larger than the noise, and the posterior still calls it certain.  So the
"error" rule also tests the fit of each pixel's best candidate:

* statistic: ``D = sum_i (r_i - mu_i)**2 / v(mu_i)`` over the pixel's m samples (code frames,
  inverse frames, white, black), ``mu_i = b + c x_i`` with the candidate's least-squares levels
  (``c >= 0``, as `posterior._fit`) and ``v`` the fitted noise model ``a + beta * mu``; where the
  candidate is right, D follows chi2 with m - 2 degrees of freedom;
* its scale on this capture: ``s = median(D) / median(chi2_(m - 2))`` over the pixels the
  posterior alone would publish (P(wrong) < max_error: about 1 where the noise model is right;
  larger where the capture is noisier than modelled, so that a global misfit such as projector
  blur does not reject every pixel), at most `MAX_SCALE`;
* pixels with a sample at full scale are not tested (saturation bends a q-ary code's levels off
  the line; a saturated binary pixel fits anyway);
* a pixel *misfits* where ``D > s * q``, q the chi2_(m - 2) quantile at 1 - `MISFIT_LEVEL`
  (Wilson-Hilferty): a right pixel does that with probability about 1e-6, a pixel whose best
  candidate differs from the truth in a few well-lit bits does it almost surely.

`check_fit` applies it: the spatial methods see a misfitting best candidate's P(wrong) as 1,
and a published column that misfits is not published.  D of the best candidate is the
Mahalanobis part of its likelihood, so both backends' posterior kernels return it on the way
(`edge.decode.posterior.Posterior.misfit`); the test itself runs on the host
(`edge.decode.decoder.publish_error_rule`), and a column a spatial method chose instead is
scored here (`misfit_statistic`, the same arithmetic).

The "confidence" rule has the same blind spot: its ``(d2 - d1) / d2`` compares the searched
codewords with each other, so where the truth is outside the search the best two are both
wrong and the ratio can still be high.  `fit_published` tests its published columns with the
same statistic, level and scale rule; there is no posterior, so the scale is taken over the
published pixels themselves, and the noise model is `edge.decode.posterior.fit_noise` of the
search's best candidates (`edge.decode.decoder.confidence_fit`).

Units: samples normalised (1 = full scale).  Shapes: frames (n, H, W), white / black / best /
outputs (H, W).
"""

from __future__ import annotations

from statistics import NormalDist

import numpy as np
from numba import njit, prange

from ..capture import CodedCapture
from ..codes import Code
from .posterior import FULL_SCALE_SAMPLE, _ls_levels, _samples, _words, _xtab

#: A right pixel misfits with about this probability (the chi2 tail of the test).
MISFIT_LEVEL = 1e-6
#: Largest scale of the statistic over its chi2 law: a capture whose published pixels fit several
#: times worse than its own noise model is mostly misfit, not a noisier camera.
MAX_SCALE = 4.0
#: Pixels the scale's median is taken over at most (a regular subsample of the published ones).
SCALE_PIXELS = 40000


@njit(cache=True)
def _row_sums(frames, white, yy, scale):
    """Row yy's running sums of the least-squares fit before its code samples, (width,) float64
    each: (sx, sxx, sxr, sr, top) with white's sample (x = 1) in sx, sxx and sxr, sr = 0 (white
    and black join it last, `_row_levels`) and top the first frame's sample."""
    width = white.shape[1]
    sx = np.ones(width, np.float64)
    sxx = np.ones(width, np.float64)
    sr = np.zeros(width, np.float64)
    sxr = np.empty(width, np.float64)
    top = np.empty(width, np.float64)
    for xx in range(width):
        sxr[xx] = white[yy, xx] * scale
        top[xx] = frames[0, yy, xx] * scale
    return sx, sxx, sxr, sr, top


@njit(cache=True)
def _add_sample(xx, r, x, sx, sxx, sxr, sr, top):
    """Pixel xx's running sums of the fit gain one code sample r of symbol x (and ``top`` its max)."""
    sx[xx] += x
    sxx[xx] += x * x
    sxr[xx] += x * r
    sr[xx] += r
    top[xx] = max(top[xx], r)


@njit(cache=True)
def _row_levels(white, black, yy, scale, m, a, beta, sx, sxx, sxr, sr, top):
    """Row yy's pixels (width = len(sx)) after the code samples' sums: black and white added to
    the plain sum and ``top``; returns (bb, cc, r0, r1), (width,) float64 each: the least-squares
    levels (off, contrast) and the reciprocal variances of the off and on levels."""
    width = sx.size
    bb = np.empty(width, np.float64)
    cc = np.empty(width, np.float64)
    r0 = np.empty(width, np.float64)
    r1 = np.empty(width, np.float64)
    for xx in range(width):
        w_ = white[yy, xx] * scale
        b_ = black[yy, xx] * scale
        sr[xx] += w_
        sr[xx] += b_
        top[xx] = max(top[xx], max(w_, b_))
        b, c = _ls_levels(m, sx[xx], sxx[xx], sxr[xx], sr[xx])
        bb[xx] = b
        cc[xx] = c
        m1 = b + c
        r0[xx] = 1.0 / (a + beta * (b if b > 0.0 else 0.0))
        r1[xx] = 1.0 / (a + beta * (m1 if m1 > 0.0 else 0.0))
    return bb, cc, r0, r1


@njit(cache=True)
def _row_finish(white, black, best, yy, scale, bb, cc, r0, r1, top, acc, out):
    """Row yy's statistics: white's and black's residuals added to the code samples' ``acc``, NaN
    where there is no candidate or a sample is at full scale (the linear model cannot be tested)."""
    for xx in range(bb.size):
        e = white[yy, xx] * scale - (bb[xx] + cc[xx])
        acc[xx] += e * e * r1[xx]
        e = black[yy, xx] * scale - bb[xx]
        acc[xx] += e * e * r0[xx]
        out[yy, xx] = np.nan if best[yy, xx] < 0 or top[xx] >= FULL_SCALE_SAMPLE else acc[xx]


@njit(cache=True, parallel=True)
def _misfit_stat(frames, white, black, scale, xtab, best, a, beta, out):
    """Row by row, each frame's row read contiguously, in the arithmetic and order of the
    posterior's `_nll` / `_lane_nll` Mahalanobis part (so the values are the posterior's
    ``misfit`` bit for bit): the fit's sums over the code samples, white (x = 1) first in the
    cross terms and last with black in the plain sum; the residuals of the code samples, then
    white, then black; a sample of symbol 0 or 1 weighed by its level's reciprocal variance."""
    n, height, width = frames.shape
    m = n + 2
    for yy in prange(height):
        sx, sxx, sxr, sr, top = _row_sums(frames, white, yy, scale)
        rows = np.empty(width, np.int64)
        xs = np.empty(width, np.float64)
        for xx in range(width):
            rows[xx] = max(best[yy, xx], 0)
        for i in range(n):
            src = frames[i, yy]
            for xx in range(width):
                xs[xx] = xtab[rows[xx], i]
            for xx in range(width):
                r = src[xx] * scale
                x = xs[xx]
                _add_sample(xx, r, x, sx, sxx, sxr, sr, top)
        bb, cc, r0, r1 = _row_levels(white, black, yy, scale, m, a, beta, sx, sxx, sxr, sr, top)
        acc = np.zeros(width, np.float64)
        for i in range(n):
            src = frames[i, yy]
            for xx in range(width):
                xs[xx] = xtab[rows[xx], i]
            for xx in range(width):
                x = xs[xx]
                if x == 0.0:
                    e = src[xx] * scale - bb[xx]
                    acc[xx] += e * e * r0[xx]
                elif x == 1.0:
                    e = src[xx] * scale - (bb[xx] + cc[xx])
                    acc[xx] += e * e * r1[xx]
                else:
                    mi = bb[xx] + cc[xx] * x
                    v = a + beta * (mi if mi > 0.0 else 0.0)
                    e = src[xx] * scale - mi
                    acc[xx] += e * e / v
        _row_finish(white, black, best, yy, scale, bb, cc, r0, r1, top, acc, out)


@njit(cache=True, parallel=True)
def _misfit_stat_binary(frames, white, black, scale, packed, best, a, beta, out):
    """`_misfit_stat` of a binary code (every symbol 0 or 1) with at most 64 samples of code per
    pixel, branch-free so that the row loops vectorise: each pixel's symbols are the bits of its
    row's packed word (`posterior.packed_symbols`: ``packed[row] >> i & 1`` for sample i), the sums and
    residuals are taken in `_misfit_stat`'s order with its operations (a symbol-1 sample's mean
    is ``b + c``, a symbol-0 sample's ``b``), so the values are `_misfit_stat`'s bit for bit."""
    n, height, width = frames.shape
    m = n + 2
    for yy in prange(height):
        sx, sxx, sxr, sr, top = _row_sums(frames, white, yy, scale)
        words = np.empty(width, np.uint64)
        for xx in range(width):
            words[xx] = packed[max(best[yy, xx], 0)]
        for i in range(n):
            src = frames[i, yy]
            shift = np.uint64(i)
            for xx in range(width):
                r = src[xx] * scale
                x = 1.0 if ((words[xx] >> shift) & np.uint64(1)) != np.uint64(0) else 0.0
                _add_sample(xx, r, x, sx, sxx, sxr, sr, top)
        bb, cc, r0, r1 = _row_levels(white, black, yy, scale, m, a, beta, sx, sxx, sxr, sr, top)
        acc = np.zeros(width, np.float64)
        for i in range(n):
            src = frames[i, yy]
            shift = np.uint64(i)
            for xx in range(width):
                one = ((words[xx] >> shift) & np.uint64(1)) != np.uint64(0)
                b_ = bb[xx]
                mean = b_ + cc[xx] if one else b_
                e = src[xx] * scale - mean
                acc[xx] += e * e * (r1[xx] if one else r0[xx])
        _row_finish(white, black, best, yy, scale, bb, cc, r0, r1, top, acc, out)


def _packed(code: Code, inverse: bool) -> np.ndarray:
    """`packed_symbols` of ``_xtab(code, inverse)`` (the posterior's cached `_words`, row 0):
    empty for a code of more than two symbols or more than 64 samples."""
    if code.q != 2 or _xtab(code, inverse).shape[1] > 64:
        return np.zeros(0, np.uint64)
    return _words(code, inverse)[0]


def misfit_statistic(frames: np.ndarray, white: np.ndarray, black: np.ndarray, scale: float, code: Code,
                     best: np.ndarray, noise: tuple[float, float], *,
                     inverse: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32 D of the module docstring (NaN where best < 0, and where a sample is at full
    scale, `FULL_SCALE_SAMPLE`: saturation bends the levels of a q-ary code, and the test would
    reject right columns).  frames (n, H, W), white / black (H, W) raw, ``scale`` to normalised
    units; best (H, W) int codebook rows; noise (a, beta) of the variance ``a + beta * I``; inverse
    (n, H, W) or None (n more samples, symbols 1 - x).  With the posterior's scale and noise, and
    best = its candidates[..., 0], the values are `edge.decode.posterior.Posterior.misfit`'s."""
    samples = _samples(frames, inverse)
    out = np.empty(np.shape(white), np.float32)
    xtab = _xtab(code, inverse is not None)
    packed = _packed(code, inverse is not None)
    args = (np.ascontiguousarray(white), np.ascontiguousarray(black), np.float64(scale))
    rest = (np.ascontiguousarray(best, np.int32), float(noise[0]), float(noise[1]), out)
    if packed.size == 0:
        _misfit_stat(samples, *args, xtab, *rest)
    else:
        _misfit_stat_binary(samples, *args, packed, *rest)
    return out


def _chi2_quantile(k: int, p: float) -> float:
    """Wilson-Hilferty quantile of chi2_k at ``p``."""
    z = NormalDist().inv_cdf(p)
    return float(k * (1.0 - 2.0 / (9.0 * k) + z * np.sqrt(2.0 / (9.0 * k))) ** 3)


def misfit_threshold(stat: np.ndarray, m: int) -> float:
    """``s * q`` of the module docstring from the statistics ``stat`` of the pixels the scale is
    taken over (any shape; NaN left out) of m samples per pixel; inf where there are none."""
    finite = np.asarray(stat, np.float64)
    finite = finite[np.isfinite(finite)]
    # a regular subsample: the median needs thousands, not millions
    return _threshold_of(finite[::_thinning(finite.size)], m)


@njit(cache=True)
def _thinning(count):
    """The step of the regular subsample the scale's median is taken over: every pixel up to
    `SCALE_PIXELS`, else every ceil(count / SCALE_PIXELS)-th, from the first (>= 1)."""
    return 1 if count <= SCALE_PIXELS else (count + SCALE_PIXELS - 1) // SCALE_PIXELS


def _threshold_of(sample: np.ndarray, m: int) -> float:
    """`misfit_threshold` of its subsample of finite statistics (float64, 1-d): ``s * q``, inf
    where it is empty."""
    if sample.size == 0:
        return float("inf")
    k = max(1, m - 2)
    s = min(float(np.median(sample)) / _chi2_quantile(k, 0.5), MAX_SCALE)
    return s * _chi2_quantile(k, 1.0 - MISFIT_LEVEL)


@njit(cache=True)
def _published_finite(stat, column0, error, max_error, yy, xx):
    """Pixel (yy, xx) is one the posterior alone would publish and its statistic is finite (the
    three tests joined by ``&``, not ``and``: no branches, so that the counting pass vectorises;
    with ``and`` the pass took 8x as long)."""
    return (column0[yy, xx] >= 0) & (error[yy, xx] < max_error) & np.isfinite(stat[yy, xx])


@njit(cache=True)
def _published_sample(stat, column0, error, max_error):
    """What `misfit_threshold` takes the median of over the pixels the posterior alone would
    publish, without the arrays in between: (k,) float64 the finite ``stat`` where ``column0 >=
    0`` and ``error < max_error``, in row-major order, every step-th of them where there are
    more than `SCALE_PIXELS` (step = ceil(count / SCALE_PIXELS), from the first): the same
    values in the same order as ``stat[published]`` after `misfit_threshold`'s selection.
    stat (H, W) float (float32 from the posteriors), column0 (H, W) int32, error (H, W) float,
    max_error float32; two passes."""
    height, width = stat.shape
    count = 0
    for yy in range(height):
        for xx in range(width):
            count += 1 if _published_finite(stat, column0, error, max_error, yy, xx) else 0
    step = _thinning(count)
    out = np.empty((count + step - 1) // step, np.float64)
    taken = 0
    skip = 0  # the published finite statistics still to pass over before the next one taken
    for yy in range(height):
        for xx in range(width):
            if _published_finite(stat, column0, error, max_error, yy, xx):
                if skip == 0:
                    out[taken] = stat[yy, xx]
                    taken += 1
                    skip = step
                skip -= 1
    return out


def check_fit(stack: CodedCapture, code: Code, noise: tuple[float, float], column0: np.ndarray, error: np.ndarray,
              max_error: float, stat: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """(P(wrong) as the spatial methods see it: `error` with 1 where column0 misfits, threshold).
    stack: the validated `CodedCapture`; column0 (H, W) int the best candidates (-1 = none; the
    CUDA backend's soft path passes its published columns only, which gives the same threshold
    and the same published pixels); error (H, W) float32 P(wrong) of column0; the scale is taken
    over the pixels with ``error < max_error`` (`misfit_threshold`'s, its sample taken in one
    kernel, `_published_sample`).  stat: (H, W) float32 the statistic of the
    posterior's best candidates (`edge.decode.posterior.Posterior.misfit`, which both backends'
    posterior kernels compute on the way), or None to compute it here from column0."""
    if stat is None:
        stat = statistic_of(stack, code, noise, column0)
    error = np.ascontiguousarray(error)  # (its dtype kept: compared with float32(max_error) as numpy does)
    sample = _published_sample(np.ascontiguousarray(stat), np.ascontiguousarray(column0, np.int32),
                               error, np.float32(max_error))
    threshold = _threshold_of(sample, samples_per_pixel(stack))
    with np.errstate(invalid="ignore"):
        bad = stat > threshold
    return np.where(bad, np.float32(1.0), error).astype(np.float32, copy=False), threshold


def fits(stack: CodedCapture, code: Code, noise: tuple[float, float], column: np.ndarray, threshold: float) -> np.ndarray:
    """(H, W) bool: where ``column`` (-1 = none: False) explains the samples (statistic at or below
    ``threshold``, `check_fit`'s)."""
    return _within(column, statistic_of(stack, code, noise, column), threshold)


def fit_published(stack: CodedCapture, code: Code, noise: tuple[float, float],
                  column: np.ndarray) -> tuple[np.ndarray, float]:
    """The test of published columns on their own (the "confidence" rule, which has no P(wrong)):
    (fits (H, W) bool: ``column >= 0`` and its statistic at or below the threshold; threshold:
    `misfit_threshold` over the statistics of the published pixels, ``column >= 0``).  stack: the
    validated `CodedCapture`; column (H, W) int codebook rows, -1 = not published; noise (a,
    beta) of the variance ``a + beta * I`` (normalised units).  Pixels with a sample at full
    scale are not tested (NaN statistic: they fit)."""
    column = np.asarray(column)
    stat = statistic_of(stack, code, noise, column)
    threshold = misfit_threshold(stat[column >= 0], samples_per_pixel(stack))
    return _within(column, stat, threshold), threshold


def _within(column: np.ndarray, stat: np.ndarray, threshold: float) -> np.ndarray:
    """(H, W) bool: a column (>= 0) whose statistic is not above ``threshold`` (NaN: untested, fits)."""
    with np.errstate(invalid="ignore"):
        return (np.asarray(column) >= 0) & ~(stat > threshold)


def statistic_of(stack: CodedCapture, code: Code, noise: tuple[float, float], column: np.ndarray) -> np.ndarray:
    """`misfit_statistic` of a validated `CodedCapture`'s samples for the rows ``column``, at the
    error rule's scale (float32, as `edge.decode.decoder` gives the posterior)."""
    return misfit_statistic(stack.frames, stack.white, stack.black, float(np.float32(stack.scale)), code,
                            np.where(np.asarray(column) >= 0, column, -1), noise, inverse=stack.inverse)


def samples_per_pixel(stack: CodedCapture) -> int:
    """m: code frames (and inverse frames) plus white and black."""
    return stack.frames.shape[0] * (1 if stack.inverse is None else 2) + 2
