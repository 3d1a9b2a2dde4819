"""Self-calibration and the error probability of a decoded column (the "error" validity rule).

Three pure steps over numpy arrays (numba kernels, one pass over the pixels each):

1. `split_levels` (before the search): each pixel's on / off levels from its own m = n + 2
   samples (the n code frames, white, black; all at the same per-frame exposure; with inverse
   frames m = 2n + 2).  Two-means clustering by Lloyd's iterations: the threshold starts at
   ``(white + black) / 2`` (at the samples' mid-range where white <= black, or where one side
   would be empty), the levels are the means of the samples above / at-or-below it, the
   threshold moves to their midpoint, at most `SPLIT_ITERATIONS` times or until the split stops
   changing.  Each level is the mean of about m / 2 samples instead of one calibration frame at
   exposure T / n, so the search is not thrown off by the calibration frames' own noise, and
   there is no first full decode; the all-zero codeword still works (white alone is "on").  The
   residuals of the samples about their level give a first noise model (the binned fit of step
   2), which the search uses, so its costs depend neither on the settings' sigmas nor on the
   frames' stated bit depth.

2. `fit_noise` (after the search): per pixel, the least-squares levels of the best candidate c1,
   ``r_i = b + c * x_i(c1)`` over the m samples (x = symbol / (q - 1), white x = 1, black x = 0),
   give the residual variance ``s2 = SSR / (m - 2)`` at the pixel's mean level ``mu`` (pixels
   with a sample at 0 or at full scale are left out: clipping censors their residuals).  The noise
   model ``var(I) = a + beta * I`` (read + shot noise) is fitted to the per-bin medians of
   ``s2`` over 16 quantile bins of ``mu`` (medians, so wrongly decoded pixels do not inflate it;
   each divided by the median of chi2_(m-2) / (m-2)), by least squares weighted by sqrt(pixels)
   / variance (a median's standard error is proportional to the variance), with ``a`` floored at
   the quantisation variance ``(scale**2) / 12`` of integer frames.  Pixels the pattern does not
   reach are then left out and the model fitted again (`lit_noise`): their best candidate fits
   their noise, so their residual variance is biased low.  The settings' sigma_r / sigma_s are the prior:
   they are used where fewer than `MIN_FIT_PIXELS` pixels are decoded.  The same pixels' levels
   (b, c) give the capture's level prior (`edge.decode.level_prior`), in ``Noise.levels``.

3. `posterior` (the validity stage's input): for each of the three candidates k, the levels are
   refitted to that candidate (``c >= 0``) and scored by the Gaussian negative log-likelihood
   ``L_k = sum_i (r_i - mu_i)**2 / v(mu_i) + log v(mu_i)``; the "no pattern" model (one level,
   ``mu_i = mean(r)``) gets ``L_0``.  The error probability of the decoded (best) column c1 is

       P(wrong) = 1 - (1 - P(not lit)) * (1 - P(confused))

   * ``P(confused)``: with a uniform prior over the columns and the capture's level prior p
     over each candidate's levels, candidate k scores ``P_k = L_k - 2 log p(b_k, c_k)`` (its
     -2 log-posterior up to a constant; the candidates are ordered by it, c1 the best) and
     competitor k has posterior odds ``e_k = exp(-(P_k - P_1) / 2)``; ``P(confused) = sum over
     far competitors e_k / (1 + sum over all e_k)``, where a competitor is *far* when its row
     differs from c1's by more than one codebook row (a one-row miss is the pattern's own
     quantisation, not an outlier).  Beyond the top three, for binary linear codes, the
     codewords ``c1 xor h`` with h of weight d_min .. d_min + `TAIL_WEIGHTS` are added
     (`_tail_mass`: each word with its own refitted levels, in closed form from per-bit sums, and
     the prior), scaled by the share of the codebook a disparity band allows; not where the
     search found fewer than three or the third is already negligible, and not where the top
     three already give P(confused) >= 1/2, and not where P(not lit) (below) is >= 1/2, since
     P(wrong) is >= 1/2 there whatever the tail adds; the sum over the tail's words stops once it
     takes P(confused) to 1/2 (from 1/2 up the published value may be a lower bound: such a pixel
     is invalid under any target).  Without the prior a
     far competitor's flat-prior odds overstate it where the scene has no pixels at its levels;
     without the refit the tail words, scored under c1's levels, lose about 3/4 of their mass.
   * ``P(not lit)`` (shadow, outside the projector): a local false-discovery rate on the gain
     ``L_0 - min_k L_k`` (likelihoods, no prior), whose law for unlit pixels is known (`_null`);
     the share of unlit pixels and the density of the gain come from the capture
     (`not_lit_probability`).

   Candidates come back re-ordered by P_k.

Units: intensities normalised (1 = full scale of the frame dtype), variances in normalised
units squared.  Shapes: frames (n, H, W), white / black / outputs (H, W), candidates (H, W, 3).

Implementation (results do not depend on it): `_split_levels` and `_posterior` take `LANES`
consecutive pixels of a row at a time with branch-free loops over the lanes; each pixel's sums
still run over its samples in the order above with the same operations, so every value is the
one-pixel-at-a-time value bit for bit; the level prior's cell of a binary code's candidates is
counted from its exact edges (`level_prior.costs_at`: `cost_at`'s cost, with no log).  A binary
code's levels take two values, so the tail's
flip costs take two logs per pixel.  The tail's words (`_tail_words`) are scored in branch-free
passes over blocks of `TAIL_BLOCK` of a pixel's words at once (vectorised), with each word's two log-variances by a
series about c1's (to 2e-11) and its prior cell by counting cell edges, and words whose odds are
below exp(-skip / 2) are left out of the sum (together less than `TAIL_ACCURACY`; the CUDA backend
sums every word exactly, and the two agree to that).  The tail is a second pass
(`_tail_pass`) after P(not lit)'s binning, over the pixels where it is due and P(not lit) < 1/2
(in the hard regime of `tools/bench_decode.py` about two in five of the due pixels are shadow
pixels, `tools/profile_decode.py`);
each of them gets the one-pass arithmetic bit for bit.  P(wrong) is one combining pass;
`_posterior` and `_tail_pass` interleave the rows over the threads (the tail mass makes hard
regions far costlier).  The search's input under the split levels is `normalised32` (float32 frames, one pass).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import get_num_threads, njit, prange

from ..codes import Code
from ..codes.words import pack_words
from .kernels import BEYOND, sort_small
from .level_prior import C_FLOOR, LevelPrior, contrast_edges, cost_at, costs_at, kernel_args, level_prior

#: Smallest on - off contrast (normalised units) the split levels keep, so that the search
#: kernels, which need white > black, decode every pixel.
MIN_CONTRAST = 1e-6
#: A normalised sample at or above this is at full scale.  Not 1.0: the error rule's scale is
#: float32(1 / full scale), which takes full scale to within 6e-8 of 1 from either side (below 1
#: for 10, 14 and 16 bits); the raw value under full scale is at least 1.5e-5 lower.
FULL_SCALE_SAMPLE = 1.0 - 1e-6
#: Fewer decoded pixels than this: the noise model is the settings' prior, not a fit.
MIN_FIT_PIXELS = 500
#: Competitors the search puts this far (in -2 log-likelihood) behind the best are not rescored:
#: their posterior odds, about exp(-SKIP_MARGIN / 2), are far below any error target; they keep
#: their place after the scored candidates with distance inf.  `decode()`'s soft search does not
#: locate them (its margin, `edge.decode.kernels.soft_lanes`): there they come back as row -1.
SKIP_MARGIN = 60.0
#: Lloyd iterations of `split_levels` at most (it stops earlier once the split is stable).
SPLIT_ITERATIONS = 4
#: Pixels the noise fit uses at most (`_steps`: a regular subgrid of larger images).
FIT_PIXELS = 40000
#: Quantile bins of the mean level in `fit_noise`.
NOISE_BINS = 16
#: `fit_noise` keeps the pixels whose contrast gain a pixel the pattern does not light reaches
#: with at most this probability (the not-lit test's null law, `_null`).
FIT_NULL_LEVEL = 1e-3
#: Rounds of that selection at most (each with the model of the round before).
FIT_ROUNDS = 2
#: Largest log-odds exponent evaluated (exp(-x/2) below e**-350 is 0 in float64 anyway).
_CLIP = 700.0
#: Pixels of one row `_posterior` and `_split_levels` process together (consecutive x), a
#: compile-time constant.  64, as the search's `kernels.LANES`: LLVM vectorises loops of 64 over
#: the lanes, where it unrolls loops of 16 into scalar code (`_split_levels` 2.7x and `_posterior`
#: 1.8x slower at 16, stage medians of `tools/profile_decode.py`).  Every lane's sums still run over its samples in
#: order, so the results are those of one pixel at a time, bit for bit, whatever LANES is.
LANES = 64


class Noise(NamedTuple):
    """Fitted model of a capture: noise variance ``a + beta * I`` (normalised units); ``fitted``
    False where the prior was used; ``pixels`` the pixels the fit used; ``levels`` the capture's
    prior over a pixel's levels (`edge.decode.level_prior`), None = the flat prior."""

    a: float
    beta: float
    fitted: bool
    pixels: int
    levels: LevelPrior | None = None


class Posterior(NamedTuple):
    """Output of `posterior` (all (H, W) unless stated).

    candidates: (H, W, 3) int32 rows re-ordered by likelihood (-1 where absent);
    distances: (H, W, 3) float32 ``P_k``: negative log-likelihoods ``L_k`` plus the level prior's
        ``-2 log p(b_k, c_k)`` (the -2 log-posterior up to a constant; inf where absent);
    error: float32 P(wrong) of candidates[..., 0] (1 where no candidate; from 1/2 up it may be a lower
        bound, `TAIL_FLOOR`);
    confidence: float32 ``(d2 - d1) / d2`` of the Mahalanobis parts ``d_k = sum (r - mu)**2 / v``
        (the paper's ratio on the refitted candidates; its lower bound ``SKIP_MARGIN / (d1 +
        SKIP_MARGIN)`` where the second was not rescored; 0 where there is no second);
    contrast: float32 on - off level of the best candidate's fit (normalised units).
    noise: the `Noise` used.
    misfit: float32 the goodness-of-fit statistic of candidates[..., 0]
        (`edge.decode.misfit.misfit_statistic`'s values, bit for bit: its ``d_1``), NaN where
        there is no candidate or a sample is at full scale.
    """

    candidates: np.ndarray
    distances: np.ndarray
    error: np.ndarray
    confidence: np.ndarray
    contrast: np.ndarray
    noise: Noise
    misfit: np.ndarray


class TailTables(NamedTuple):
    """The tail mass's tables of a binary linear code (`_flips`; L sampled words, L = 0 for a code
    without a tail term)."""

    packed: np.ndarray  #: (size,) uint64 every codeword, bit i = symbol i
    flips: np.ndarray  #: (L,) uint64 the sampled words, packed
    flip_bits: np.ndarray  #: (L, w_max) int32 their bit positions (zero-padded)
    flip_w: np.ndarray  #: (L,) int32 their weights
    columns: np.ndarray  #: (n, L) float64 0/1, column j the bits word j flips (`_tail_words`)
    weight: float  #: the words they stand for (weight wlo..whi) / L
    wlo: int  #: the least weight sampled (d_min)
    whi: int  #: the largest weight sampled


@njit(cache=True)
def _clipped(buf, m):
    """Whether any of the m normalised samples sits at 0 or at full scale (`FULL_SCALE_SAMPLE`):
    its residual is censored, so the pixel is left out of the noise fit."""
    for i in range(m):
        if buf[i] <= 0.0 or buf[i] >= FULL_SCALE_SAMPLE:
            return True
    return False


@njit(cache=True)
def _above(buf, m, t):
    """(sum, count) of the first m samples of buf above t."""
    sh = 0.0
    kh = 0
    for i in range(m):
        if buf[i] > t:
            sh += buf[i]
            kh += 1
    return sh, kh


@njit(cache=True)
def _lane_above(R, m, t, sh, kh):
    """`_above` of every lane: sh (LANES,) float64, kh (LANES,) int64 = (sum, count) of lane l's
    m samples above t[l], summed in the samples' order (adding 0.0 for a sample at or below the
    threshold leaves the sum of non-negative samples unchanged: `_above`'s values bit for bit)."""
    L = R.shape[1]
    for l in range(L):
        sh[l] = 0.0
        kh[l] = 0
    for i in range(m):
        for l in range(L):
            v = R[i, l]
            up = v > t[l]
            sh[l] += v if up else 0.0
            kh[l] += 1 if up else 0


@njit(cache=True, parallel=True, error_model="numpy")
def _split_levels(frames, white, black, scale, step, out_hi, out_lo, out_s2, out_mu):
    """Step 1 per pixel, LANES pixels of a row at a time (every lane runs the same Lloyd steps as
    one pixel alone: the sums in the samples' order, a lane that has converged is left as it is).
    The residual variance and mean level only of the pixels the noise fit takes (`fit_step`):
    pixel p (row-major) with ``p % step == 0`` into out_s2 / out_mu[p // step], its residuals
    summed in the samples' order (NaN where a sample is at 0 or full scale)."""
    n, height, width = frames.shape
    m = n + 2
    L = LANES
    for yy in prange(height):
        R = np.empty((m, L), np.float64)
        total = np.empty(L, np.float64)
        top = np.empty(L, np.float64)
        bottom = np.empty(L, np.float64)
        t = np.empty(L, np.float64)
        t2 = np.empty(L, np.float64)
        hi = np.empty(L, np.float64)
        lo = np.empty(L, np.float64)
        sh = np.empty(L, np.float64)
        sh2 = np.empty(L, np.float64)
        kh = np.empty(L, np.int64)
        kh2 = np.empty(L, np.int64)
        count_hi = np.empty(L, np.int64)
        live = np.empty(L, np.bool_)
        for x0 in range(0, width, L):
            _lane_samples(frames, white, black, scale, yy, x0, R)
            # two-means by Lloyd's iterations from the calibration midpoint (SPLIT_ITERATIONS, or
            # until the split stops changing); from the samples' mid-range where white <= black
            for l in range(L):
                total[l] = 0.0
                top[l] = R[0, l]
                bottom[l] = R[0, l]
            for i in range(m):
                for l in range(L):
                    v = R[i, l]
                    total[l] += v
                    top[l] = max(top[l], v)
                    bottom[l] = min(bottom[l], v)
            for l in range(L):
                w_, b_ = R[n, l], R[n + 1, l]
                t[l] = 0.5 * (w_ + b_) if w_ > b_ else 0.5 * (top[l] + bottom[l])
                hi[l] = top[l]
                lo[l] = bottom[l]
                count_hi[l] = -1
                live[l] = True
            for _ in range(SPLIT_ITERATIONS):
                _lane_above(R, m, t, sh, kh)
                # the lane updates are branch-free (selects), so that they vectorise: a lane that
                # is not live keeps every value, as if skipped
                again = False
                for l in range(L):
                    k1 = kh[l]
                    one_class = live[l] & ((k1 == 0) | (k1 == m))
                    # one class: split at the mid-range instead
                    t[l] = 0.5 * (top[l] + bottom[l]) if one_class else t[l]
                    again |= one_class
                    t2[l] = t[l]
                if again:
                    _lane_above(R, m, t2, sh2, kh2)
                for l in range(L):
                    k1 = kh[l]
                    second = (k1 == 0) | (k1 == m)  # (then sh2 / kh2 were counted for a live lane)
                    s_ = sh2[l] if second else sh[l]
                    k_ = kh2[l] if second else k1
                    moves = live[l] & (k_ != 0) & (k_ != m)
                    h_ = s_ / k_  # (error_model "numpy": where k_ is 0 or m these are not kept)
                    o_ = (total[l] - s_) / (m - k_)
                    hi[l] = h_ if moves else hi[l]
                    lo[l] = o_ if moves else lo[l]
                    t[l] = 0.5 * (h_ + o_) if moves else t[l]
                    changed = moves & (k_ != count_hi[l])
                    count_hi[l] = k_ if changed else count_hi[l]
                    live[l] = changed
                if not live.any():
                    break
            p0 = yy * width + x0
            for l in range((step - p0 % step) % step, min(L, width - x0), step):
                ssr = 0.0
                clip = False
                for i in range(m):
                    v = R[i, l]
                    e = v - (hi[l] if v > t[l] else lo[l])
                    ssr += e * e
                    clip = clip or v <= 0.0 or v >= FULL_SCALE_SAMPLE
                out_s2[(p0 + l) // step] = ssr / (m - 2) if not clip else np.nan
                out_mu[(p0 + l) // step] = total[l] / m
            for l in range(min(L, width - x0)):
                xx = x0 + l
                h_ = hi[l]
                if h_ - lo[l] < 1e-6:
                    h_ = lo[l] + 1e-6
                out_hi[yy, xx] = h_
                out_lo[yy, xx] = lo[l]


@njit(cache=True, parallel=True)
def _normalised32(frames, scale, out):
    n, height, width = frames.shape
    for yy in prange(height):
        for i in range(n):
            src = frames[i, yy]
            dst = out[i, yy]
            for xx in range(width):
                dst[xx] = np.float32(src[xx]) * scale


def normalised32(frames: np.ndarray, scale: float) -> np.ndarray:
    """(n, H, W) float32 normalised frames: ``float32(raw) * float32(scale)``, the values of numpy's
    ``frames.astype(np.float32) * np.float32(scale)`` bit for bit, in one parallel pass (the
    search's input under the split levels).  frames: (n, H, W) uint8 / uint16 / float32 / float64."""
    out = np.empty(frames.shape, np.float32)
    _normalised32(np.ascontiguousarray(frames), np.float32(scale), out)
    return out


def split_levels(frames: np.ndarray, white: np.ndarray, black: np.ndarray, scale: float, *,
                 prior: tuple[float, float] = (0.01, 0.03),
                 inverse: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, Noise]:
    """Step 1 of the module docstring: (on, off) float32 (H, W) levels in normalised units, and
    the noise model fitted (as `fit_noise` does) to the residuals of the samples about their
    split level: the search's noise model, before any decode.

    frames: (n, H, W) raw frames (any real dtype), white / black: (H, W) raw; scale: raw value ->
    normalised intensity; prior: (sigma_r, sigma_s) where too few pixels; inverse: (n, H, W)
    inverse frames (n more samples) or None.  ``on - off >= MIN_CONTRAST`` everywhere.
    """
    frames = _samples(frames, inverse)
    h, w = white.shape
    hi = np.empty((h, w), np.float32)
    lo = np.empty((h, w), np.float32)
    s2 = np.empty(fit_size(h * w), np.float64)  # the noise fit's pixels only (`_fit_sample`'s)
    mu = np.empty_like(s2)
    _split_levels(frames, white, black, np.float64(scale), fit_step(h * w), hi, lo, s2, mu)
    return hi, lo, _noise_from(s2, mu, frames, scale, prior)


@njit(cache=True)
def _ls_levels(m, sx, sxx, sxr, sr):
    """Least-squares (b, c) of r = b + c x from the sums over m samples of x, x**2, x r and r; c
    clamped at 0 (then b is the mean).  The one place of this arithmetic for the CPU kernels
    (`_fit`, `_lane_nll`, `edge.decode.misfit`), so that their levels agree bit for bit."""
    den = m * sxx - sx * sx
    c = (m * sxr - sx * sr) / den if den > 0 else 0.0
    if c < 0.0:
        c = 0.0
    return (sr - c * sx) / m, c


@njit(cache=True)
def _fit(buf, xs, row, n, xtab):
    """Least-squares (b, c) of r = b + c x over the m samples for codebook row `row`."""
    m = n + 2
    sx = 1.0
    sxx = 1.0
    sr = 0.0
    sxr = buf[n]
    for i in range(n):
        x = xtab[row, i]
        xs[i] = x
        sx += x
        sxx += x * x
        sxr += x * buf[i]
    xs[n] = 1.0
    xs[n + 1] = 0.0
    for i in range(m):
        sr += buf[i]
    return _ls_levels(m, sx, sxx, sxr, sr)


@njit(cache=True, parallel=True)
def _fit_stats(frames, white, black, scale, xtab, best, step_y, step_x, out_s2, out_mu, out_b, out_c):
    n = frames.shape[0]
    m = n + 2
    rows, cols = out_s2.shape
    for ry in prange(rows):
        yy = ry * step_y
        buf = np.empty(m, np.float64)
        xs = np.empty(m, np.float64)
        for rx in range(cols):
            xx = rx * step_x
            row = best[yy, xx]
            if row < 0:
                out_s2[ry, rx] = np.nan
                out_mu[ry, rx] = np.nan
                out_b[ry, rx] = np.nan
                out_c[ry, rx] = np.nan
                continue
            _pixel_samples(frames, white, black, scale, yy, xx, buf)
            b, c = _fit(buf, xs, row, n, xtab)
            out_b[ry, rx] = b
            out_c[ry, rx] = c
            ssr = 0.0
            mu = 0.0
            for i in range(m):
                mi = b + c * xs[i]
                e = buf[i] - mi
                ssr += e * e
                mu += mi
            out_s2[ry, rx] = ssr / (m - 2) if not _clipped(buf, m) else np.nan
            out_mu[ry, rx] = mu / m


@njit(cache=True)
def _radix_order(x):
    """`stable_order`'s kernel: each value's order key (the float64 bits made to sort as unsigned
    integers: the sign bit flipped for x >= 0, every bit for x < 0; -0.0 keyed as 0.0, every NaN
    as the largest key), then a least-significant-digit radix sort of the indices by those keys,
    one pass per byte, skipping the bytes all keys share.  Each pass is stable, so equal values
    keep ascending index."""
    n = x.size
    xb = x.view(np.uint64)
    sign = np.uint64(1) << np.uint64(63)
    keys = np.empty(n, np.uint64)
    for i in range(n):
        b = xb[i]
        if x[i] != x[i]:
            keys[i] = ~np.uint64(0)
        else:
            if b == sign:
                b = np.uint64(0)
            keys[i] = ~b if (b & sign) != np.uint64(0) else (b | sign)
    order = np.arange(n)
    spare = np.empty(n, np.int64)
    spare_keys = np.empty(n, np.uint64)
    count = np.empty(257, np.int64)
    for p in range(8):
        shift = np.uint64(8 * p)
        count[:] = 0
        for i in range(n):
            count[((keys[i] >> shift) & np.uint64(255)) + np.uint64(1)] += 1
        if count.max() == n:  # one value of this byte: the pass would leave the order as it is
            continue
        for d in range(256):
            count[d + 1] += count[d]
        for i in range(n):
            d = (keys[i] >> shift) & np.uint64(255)
            j = count[d]
            count[d] = j + 1
            spare[j] = order[i]
            spare_keys[j] = keys[i]
        order, spare = spare, order
        keys, spare_keys = spare_keys, keys
    return order


def stable_order(x: np.ndarray) -> np.ndarray:
    """``np.argsort(x, kind="stable")`` of a 1-d float array: the same int64 indices (ascending,
    -0.0 equal to 0.0, NaN last, equal values in index order), by a radix sort (`_radix_order`:
    linear in the size; numpy's stable sort of the noise fit's 40000 levels took 5x longer)."""
    return _radix_order(np.ascontiguousarray(x, np.float64))


def _chi2_median_ratio(k: int) -> float:
    """Median of chi2_k / k (Wilson-Hilferty)."""
    return float((1.0 - 2.0 / (9.0 * k)) ** 3)


def fit_noise(frames: np.ndarray, white: np.ndarray, black: np.ndarray, scale: float, code: Code,
              best: np.ndarray, *, prior: tuple[float, float], inverse: np.ndarray | None = None) -> Noise:
    """Step 2 of the module docstring: the `Noise` of this capture, with the capture's level
    prior (`edge.decode.level_prior.level_prior` of the same pixels' levels).

    best: (H, W) int codebook rows (-1 = none) of the search; prior: (sigma_r, sigma_s) used where
    fewer than `MIN_FIT_PIXELS` pixels have a row; inverse: (n, H, W) inverse frames or None.
    """
    samples = _samples(frames, inverse)
    h, w = white.shape
    sy, sx = _steps(h, w)
    s2 = np.empty(((h + sy - 1) // sy, (w + sx - 1) // sx), np.float64)
    mu = np.empty_like(s2)
    fb = np.empty_like(s2)
    fc = np.empty_like(s2)
    xtab = _xtab(code, inverse is not None)
    _fit_stats(samples, white, black, np.float64(scale), xtab,
               np.ascontiguousarray(best, np.int32), sy, sx, s2, mu, fb, fc)
    return lit_noise(s2, mu, fb, fc, samples, scale, prior, code, inverse is not None)._replace(
        levels=level_prior(fb, fc))


def lit_noise(s2: np.ndarray, mu: np.ndarray, fb: np.ndarray, fc: np.ndarray, frames: np.ndarray, scale: float,
              prior: tuple[float, float], code: Code, inverse: bool) -> Noise:
    """Step 2's noise model from the fit pixels' residual variances ``s2``, mean levels ``mu``
    and best-candidate levels ``fb`` / ``fc`` (arrays of one shape, NaN = no candidate), fitted
    on the pixels the pattern visibly lights (both backends call this on the host).

    A pixel the pattern does not reach (shadow, outside the projector) still has a best
    candidate, the one that fits its noise best, so its residual variance is biased low, and
    shadows sit at ambient-only levels, where they tilt the line ``a + beta * I`` and push ``a``
    to its floor.  So: the fit of all pixels
    (`_binned_fit`, as `_noise_from`), then, under that model, each pixel's contrast gain ``m (mu - b)(b + c - mu)
    / v(mu)`` (the least-squares fit's ``c**2 S_xx / v``, exact for binary codes, an upper bound
    for q-ary ones), and the fit again on the pixels whose gain an unlit pixel reaches with
    probability at most `FIT_NULL_LEVEL` (the null law of the not-lit test over all codebook
    rows, `_null`), at most `FIT_ROUNDS` times or until the selection repeats.  Too few pixels
    left: the fit of all pixels.  frames: (m - 2, ...) the samples' frames (dtype and count);
    inverse: whether the samples include inverse frames."""
    s2, mu, fb, fc = (np.asarray(v, np.float64) for v in _fit_sample(s2, mu, fb, fc))
    by_level = _level_order(s2, mu)  # sorted once; a selection of it stays sorted
    noise = _binned_fit(mu[by_level], s2[by_level], frames, scale, prior)
    if not noise.fitted:
        return noise
    _sample, xq, slope = _null(code, code.size, inverse)
    threshold = xq + np.log((1.0 - NULL_TAIL_QUANTILE) / FIT_NULL_LEVEL) / slope
    m = frames.shape[0] + 2
    # a finite s2 comes with finite levels (`_fit_stats` writes NaN to all four only where there
    # is no candidate), so every pixel of by_level has a gain
    mu_s, b_s, c_s = mu[by_level], fb[by_level], fc[by_level]
    kept = None
    for _ in range(FIT_ROUNDS):
        v = noise.a + noise.beta * np.maximum(mu_s, 0.0)
        keep = m * (mu_s - b_s) * (b_s + c_s - mu_s) / v > threshold
        if kept is not None and np.array_equal(keep, kept):
            break
        sel = by_level[keep]
        refit = _binned_fit(mu[sel], s2[sel], frames, scale, prior)
        if not refit.fitted:
            break
        noise, kept = refit, keep
    return noise


def _steps(h: int, w: int) -> tuple[int, int]:
    """Row / column steps of the pixel grid the noise fit uses: every pixel up to
    `FIT_PIXELS`, else a regular subgrid of about that many (the fit needs thousands, not
    hundreds of thousands)."""
    sy = sx = 1
    while (h // sy) * (w // sx) > FIT_PIXELS:
        if sy <= sx:
            sy += 1
        else:
            sx += 1
    return sy, sx


def fit_step(pixels: int) -> int:
    """The step of `_fit_sample`'s regular subsample of ``pixels`` pixels: 1 up to `FIT_PIXELS`,
    else ceil(pixels / FIT_PIXELS), so that it keeps at most `FIT_PIXELS` of them."""
    return -(-pixels // FIT_PIXELS) if pixels > FIT_PIXELS else 1


def fit_size(pixels: int) -> int:
    """How many of ``pixels`` pixels that subsample keeps (every `fit_step`-th from the first):
    the length of the split levels' compact residual arrays on both backends."""
    return -(-pixels // fit_step(pixels))


def _fit_sample(*arrays: np.ndarray) -> list[np.ndarray]:
    """The pixels `_noise_from` fits, raveled: every `fit_step`-th pixel (row-major; the split
    levels of both backends compute exactly that subsample, which this then keeps whole)."""
    out = [np.ravel(v) for v in arrays]
    step = fit_step(out[0].size)  # a regular subsample (deterministic), as `_steps`
    return out if step == 1 else [v[::step] for v in out]


def _noise_from(s2: np.ndarray, mu: np.ndarray, frames: np.ndarray, scale: float, prior: tuple[float, float]) -> Noise:
    """The binned-median fit of `fit_noise` from per-pixel residual variances `s2` (NaN = none)
    at mean levels `mu` (`_fit_sample`'s pixels, the finite ones)."""
    s2, mu = _fit_sample(s2, mu)
    by_level = _level_order(s2, mu)
    return _binned_fit(mu[by_level], s2[by_level], frames, scale, prior)


def _level_order(s2: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """int64 indices of the pixels with a finite ``s2`` (1-d arrays), by mean level ``mu``
    ascending, equal levels in pixel order (`stable_order`)."""
    ok = np.flatnonzero(np.isfinite(s2))
    return ok[stable_order(mu[ok])]


@njit(cache=True)
def _bin_medians(muv, s2v, bins, least):
    """(medians of muv, medians of s2v, pixels) (k,) float64 of the bins of ``np.array_split``
    into ``bins`` consecutive slices that hold at least ``least`` pixels.  muv (N,) float64
    ascending: its median is read off the middle; s2v (N,) float64 finite.  A median is the middle
    value, or the mean of the middle two, whatever the selection algorithm: numpy's bit for bit."""
    size = muv.size
    base, extra = size // bins, size % bins
    xs = np.empty(bins, np.float64)
    ys = np.empty(bins, np.float64)
    ws = np.empty(bins, np.float64)
    k = 0
    lo = 0
    for j in range(bins):
        hi = lo + base + (1 if j < extra else 0)
        count = hi - lo
        if count >= least:
            mid = lo + count // 2
            xs[k] = muv[mid] if count % 2 else (muv[mid - 1] + muv[mid]) / 2.0
            ys[k] = np.median(s2v[lo:hi])
            ws[k] = count
            k += 1
        lo = hi
    return xs[:k], ys[:k], ws[:k]


def _binned_fit(muv: np.ndarray, s2v: np.ndarray, frames: np.ndarray, scale: float,
                prior: tuple[float, float]) -> Noise:
    """`_noise_from`'s fit of the finite pixels' mean levels / residual variances, sorted by level
    (stably: equal levels in pixel order)."""
    # variance floor: the quantisation step's (integer frames), else a tiny positive number
    floor = float(scale) ** 2 / 12.0 if np.issubdtype(frames.dtype, np.integer) else 1e-12
    prior_noise = Noise(max(float(prior[0]) ** 2, floor), float(prior[1]) ** 2, False, int(muv.size))
    if muv.size < MIN_FIT_PIXELS:
        return prior_noise
    # NOISE_BINS equal-count bins of the mean level (its quantile bins), medians per slice
    x, y, count = _bin_medians(np.ascontiguousarray(muv, np.float64), np.ascontiguousarray(s2v, np.float64),
                               NOISE_BINS, 20)
    y = y / _chi2_median_ratio(frames.shape[0])
    if x.size < 2:
        return prior_noise
    if np.ptp(x) <= 1e-9:
        return Noise(max(float(np.median(y)), floor), 0.0, True, int(muv.size))
    # weighted least squares: a bin's median has a standard error proportional to the variance
    # itself over sqrt(pixels), so each bin is weighed by sqrt(pixels) / variance (first the
    # measured one, then, once, the fitted line's: where the variance spans decades, an unweighted
    # fit lets the bright bins' 1 % scatter set the read-noise intercept)
    design = np.stack([np.ones_like(x), x], 1)
    scale_y = np.maximum(y, floor)
    for _ in range(2):
        wt = np.sqrt(count) / scale_y
        a, beta = np.linalg.lstsq(design * wt[:, None], y * wt, rcond=None)[0]
        scale_y = np.maximum(a + beta * x, np.maximum(y, floor) * 0.5)
    if beta < 0.0:  # no shot-noise term visible: constant variance
        a, beta = float(np.median(y)), 0.0
    return Noise(max(float(a), floor), float(beta), True, int(muv.size))


@njit(cache=True)
def _nll(buf, xs, row, n, xtab, a, beta, use_row):
    """(L, Mahalanobis part, contrast, off level) of one hypothesis: codebook row `row` (use_row)
    or one flat level (not use_row)."""
    m = n + 2
    if use_row:
        b, c = _fit(buf, xs, row, n, xtab)
    else:
        b = 0.0
        for i in range(m):
            b += buf[i]
        b /= m
        c = 0.0
        for i in range(m):
            xs[i] = 0.0
    # the two levels of a binary code (x = 0 / 1) have one variance each: two logs per hypothesis
    m1 = b + c
    v0 = a + beta * (b if b > 0.0 else 0.0)
    v1 = a + beta * (m1 if m1 > 0.0 else 0.0)
    l0 = np.log(v0)
    l1 = np.log(v1)
    r0 = 1.0 / v0
    r1 = 1.0 / v1
    total = 0.0
    maha = 0.0
    for i in range(m):
        x = xs[i]
        if x == 0.0:
            e = buf[i] - b
            q = e * e * r0
            total += q + l0
        elif x == 1.0:
            e = buf[i] - m1
            q = e * e * r1
            total += q + l1
        else:
            mi = b + c * x
            v = a + beta * (mi if mi > 0.0 else 0.0)
            e = buf[i] - mi
            q = e * e / v
            total += q + np.log(v)
        maha += q
    return total, maha, c, b


@njit(cache=True)
def _pixel_samples(frames, white, black, scale, y, x, buf):
    """buf[:m] = the m normalised samples of pixel (y, x): code frames, white, black (the values
    of `_lane_samples`)."""
    n = frames.shape[0]
    for i in range(n):
        buf[i] = frames[i, y, x] * scale
    buf[n] = white[y, x] * scale
    buf[n + 1] = black[y, x] * scale


@njit(cache=True)
def _lane_samples(frames, white, black, scale, yy, x0, R):
    """R (m, LANES) float64 = the m normalised samples (``float64(raw) * scale``, as `_pixel_samples`)
    of pixels x0 .. x0 + LANES - 1 of row yy; lanes past the row's end repeat its last pixel."""
    n, _, width = frames.shape
    L = R.shape[1]
    if x0 + L <= width:
        for i in range(n):
            row = frames[i, yy, x0:x0 + L]
            for l in range(L):
                R[i, l] = row[l] * scale
        wr = white[yy, x0:x0 + L]
        br = black[yy, x0:x0 + L]
        for l in range(L):
            R[n, l] = wr[l] * scale
            R[n + 1, l] = br[l] * scale
    else:
        for l in range(L):
            xx = min(x0 + l, width - 1)
            for i in range(n):
                R[i, l] = frames[i, yy, xx] * scale
            R[n, l] = white[yy, xx] * scale
            R[n + 1, l] = black[yy, xx] * scale


@njit(cache=True)
def _lane_nll(R, sr, W, rows, k, n, words, a, beta, T, out_l, out_q, out_c, out_b):
    """`_nll` of codebook row ``rows[k, l]`` (>= 0) of every lane of a binary code (symbols 0 /
    1), lane-parallel, into row k of out_l / out_q / out_c / out_b (3, LANES) (L, Mahalanobis
    part, contrast c, off level b).  The symbols are read from the packed words (`_words`: bit i
    of ``words[i // 64, row]`` = symbol i), which vectorises where a gather of `_xtab`'s rows does
    not.  Each lane's sums run over the samples in `_fit` / `_nll`'s order with the same
    operations (``x * x == x`` for a 0 / 1 symbol, so `_fit`'s sum of x**2 is its sum of x), so
    the values are theirs bit for bit.  sr (LANES,): the sum of each lane's m samples (`_fit`'s
    ``sr``); scratch W (2, LANES) uint64, T (8, LANES) float64."""
    m = n + 2
    L = LANES
    for l in range(L):
        r = rows[k, l]
        W[0, l] = words[0, r]
        W[1, l] = words[1, r]
    for l in range(L):
        T[0, l] = 1.0  # sum of x (white: x = 1)
        T[1, l] = R[n, l]  # sum of x r
    for i in range(n):
        wi = i >> 6
        sh = np.uint64(i & 63)
        for l in range(L):
            x = np.float64((W[wi, l] >> sh) & np.uint64(1))
            T[0, l] += x
            T[1, l] += x * R[i, l]
    for l in range(L):
        b, c = _ls_levels(m, T[0, l], T[0, l], T[1, l], sr[l])
        T[2, l] = b
        T[3, l] = b + c
        out_c[k, l] = c
        out_b[k, l] = b
    for l in range(L):
        bb = T[2, l]
        b1 = T[3, l]
        v0 = a + beta * (bb if bb > 0.0 else 0.0)
        v1 = a + beta * (b1 if b1 > 0.0 else 0.0)
        T[4, l] = np.log(v0)
        T[5, l] = np.log(v1)
        T[6, l] = 1.0 / v0
        T[7, l] = 1.0 / v1
        out_l[k, l] = 0.0
        out_q[k, l] = 0.0
    for i in range(n):
        wi = i >> 6
        sh = np.uint64(i & 63)
        for l in range(L):
            # both operands loaded before the select: a branch-free loop that vectorises
            one = ((W[wi, l] >> sh) & np.uint64(1)) != np.uint64(0)
            mu0, mu1, w0, w1, g0, g1 = T[2, l], T[3, l], T[6, l], T[7, l], T[4, l], T[5, l]
            e = R[i, l] - (mu1 if one else mu0)
            q = e * e * (w1 if one else w0)
            out_l[k, l] += q + (g1 if one else g0)
            out_q[k, l] += q
    for l in range(L):  # white (x = 1), then black (x = 0)
        e = R[n, l] - T[3, l]
        q = e * e * T[7, l]
        out_l[k, l] += q + T[5, l]
        out_q[k, l] += q
        e = R[n + 1, l] - T[2, l]
        q = e * e * T[6, l]
        out_l[k, l] += q + T[4, l]
        out_q[k, l] += q


@njit(cache=True)
def _lane_flat(R, sr, n, a, beta, S, out_l):
    """`_nll`'s flat hypothesis (one level, the mean) of every lane, lane-parallel (its values bit
    for bit; sr as in `_lane_nll`; scratch S (9, LANES))."""
    m = n + 2
    L = R.shape[1]
    bb = S[0]
    r0 = S[1]
    l0 = S[2]
    for l in range(L):
        b = sr[l] / m
        bb[l] = b
        v0 = a + beta * (b if b > 0.0 else 0.0)
        l0[l] = np.log(v0)
        r0[l] = 1.0 / v0
        out_l[l] = 0.0
    for i in range(m):
        for l in range(L):
            e = R[i, l] - bb[l]
            out_l[l] += e * e * r0[l] + l0[l]


@njit(cache=True)
def _interleaved(j, chunk, k):
    """Row of iteration j of a parallel loop over ``chunk * k`` iterations on k threads: a
    thread's contiguous share of iterations (about ``chunk``) gets every k-th row, so rows of
    unequal cost (a region of hard pixels) are spread over the threads (>= height: none)."""
    return (j % chunk) * k + j // chunk


@njit(cache=True, parallel=True)
def _posterior(frames, white, black, scale, xtab, words, cand, searched, a, beta, flips, tail_weight, binary,
               threads, ptab, pu0, pdu, pw0, pdw, pout, use_prior, edges, out_cand, out_dist, out_err, out_gain, out_conf,
               out_contrast, out_far, out_every, out_lbest, out_tail, out_misfit):
    """Step 3 per pixel but the tail mass, LANES pixels of a row at a time: the hypotheses' NLLs
    lane-parallel (`_lane_nll`, `_lane_flat`; `_nll` per lane where the code is not binary), then
    each pixel's ordering and odds.  out_err: the top three's P(confused) = far / (1 + every);
    out_tail (H, W) uint8: 1 where the tail mass is due (`_tail_pass` adds it), with the pixel's
    far, every and best -2 log-posterior lk[0] (float64) in out_far / out_every / out_lbest (left
    as they are elsewhere).  out_misfit (H, W) float32: the best candidate's Mahalanobis part
    ``sum (r - mu)**2 / v`` (`edge.decode.misfit`'s statistic), NaN where there is no candidate
    or a sample is at full scale.  Rows interleaved over the `threads` threads (`_interleaved`)."""
    n, height, width = frames.shape
    m = n + 2
    L = LANES
    use_tail = flips.size > 0
    chunk = (height + threads - 1) // threads
    for it in prange(chunk * threads):
        yy = _interleaved(it, chunk, threads)
        if yy >= height:
            continue
        R = np.empty((m, L), np.float64)
        W = np.empty((2, L), np.uint64)
        T = np.empty((8, L), np.float64)
        S = np.empty((9, L), np.float64)
        buf = np.empty(m, np.float64)
        xs = np.empty(m, np.float64)
        sr = np.empty(L, np.float64)
        full = np.empty(L, np.float64)
        rows = np.empty((3, L), np.int32)
        scored = np.empty((3, L), np.bool_)
        need = np.empty(3, np.bool_)
        hl = np.empty((3, L), np.float64)
        hq = np.empty((3, L), np.float64)
        hc = np.empty((3, L), np.float64)
        hp = np.empty((3, L), np.float64)
        hb = np.empty((3, L), np.float64)
        flat = np.empty(L, np.float64)
        pc = np.empty(L, np.float64)
        pi = np.empty(L, np.int64)
        lk = np.empty(3, np.float64)
        mk = np.empty(3, np.float64)
        ck = np.empty(3, np.float64)
        rk = np.empty(3, np.int32)
        rest = np.empty(3, np.int32)
        for x0 in range(0, width, L):
            _lane_samples(frames, white, black, scale, yy, x0, R)
            for l in range(L):
                sr[l] = 0.0
                full[l] = 0.0
            for i in range(m):
                for l in range(L):
                    v = R[i, l]
                    sr[l] += v
                    # a count of the samples at full scale (a select and an add vectorise; a
                    # running max of the samples does not)
                    full[l] += 1.0 if v >= FULL_SCALE_SAMPLE else 0.0
            any_scored = False
            for k in range(3):
                need[k] = False
                for l in range(L):
                    xx = min(x0 + l, width - 1)
                    row = cand[yy, xx, k]
                    ok = row >= 0 and not (k > 0 and searched[yy, xx, k] - searched[yy, xx, 0] > SKIP_MARGIN)
                    scored[k, l] = ok
                    rows[k, l] = row if ok else 0
                    need[k] = need[k] or ok
                any_scored = any_scored or need[k]
            if any_scored:
                for k in range(3):
                    if not need[k]:  # no lane rescores this candidate
                        continue
                    if binary:
                        _lane_nll(R, sr, W, rows, k, n, words, a, beta, T, hl, hq, hc, hb)
                        if use_prior:  # hb / hc: each lane's off level b and contrast c of this candidate
                            costs_at(ptab, pu0, pdu, edges, pw0, pdw, pout, hb[k], hc[k], pc, pi, hp[k])
                        else:
                            hp[k, :] = 0.0
                    else:
                        for l in range(L):
                            if scored[k, l]:
                                for i in range(m):
                                    buf[i] = R[i, l]
                                tl, tq, tc, tb = _nll(buf, xs, rows[k, l], n, xtab, a, beta, True)
                                hl[k, l] = tl
                                hq[k, l] = tq
                                hc[k, l] = tc
                                hp[k, l] = cost_at(ptab, pu0, pdu, pw0, pdw, pout, tb, tc) if use_prior else 0.0
                _lane_flat(R, sr, n, a, beta, S, flat)
            for l in range(min(L, width - x0)):
                xx = x0 + l
                count = 0
                unscored = 0
                plain = np.inf  # the least L_k without the prior: the not-lit test's gain is flat - plain
                for k in range(3):
                    row = cand[yy, xx, k]
                    if row == BEYOND:  # beyond the skip margin and not located: not rescored, as below
                        rest[unscored] = -1
                        unscored += 1
                        continue
                    if row < 0:
                        continue
                    if not scored[k, l]:
                        rest[unscored] = row  # posterior odds far below any target: not rescored
                        unscored += 1
                        continue
                    plain = min(plain, hl[k, l])
                    total = hl[k, l] + hp[k, l]
                    # insertion by posterior: likelihood plus level prior (ties keep the search's order)
                    j = count
                    while j > 0 and lk[j - 1] > total:
                        lk[j] = lk[j - 1]
                        mk[j] = mk[j - 1]
                        ck[j] = ck[j - 1]
                        rk[j] = rk[j - 1]
                        j -= 1
                    lk[j] = total
                    mk[j] = hq[k, l]
                    ck[j] = hc[k, l]
                    rk[j] = row
                    count += 1
                for k in range(3):
                    if k < count:
                        out_cand[yy, xx, k] = rk[k]
                        out_dist[yy, xx, k] = lk[k]
                    elif k < count + unscored:
                        out_cand[yy, xx, k] = rest[k - count]
                        out_dist[yy, xx, k] = np.inf
                    else:
                        out_cand[yy, xx, k] = -1
                        out_dist[yy, xx, k] = np.inf
                if count == 0:
                    out_err[yy, xx] = 1.0
                    out_gain[yy, xx] = np.nan
                    out_conf[yy, xx] = 0.0
                    out_contrast[yy, xx] = 0.0
                    out_misfit[yy, xx] = np.nan
                    out_tail[yy, xx] = 0
                    continue
                out_misfit[yy, xx] = mk[0] if full[l] == 0.0 else np.nan
                out_gain[yy, xx] = flat[l] - plain
                far = 0.0
                every = 0.0
                ek = 0.0
                for k in range(1, count):
                    ek = np.exp(-min((lk[k] - lk[0]) * 0.5, _CLIP))
                    every += ek
                    if abs(rk[k] - rk[0]) > 1:
                        far += ek
                # the codewords beyond the top three (`_tail_pass`): none where the search found fewer
                # (a narrow band holds no more), negligible where even the third is (the search ranks
                # the rest below it), none where the top three already give P(confused) >= 1/2
                due = use_tail and count == 3 and flips.size * tail_weight * ek > TAIL_FLOOR and far < 1.0 + every - far
                out_tail[yy, xx] = 1 if due else 0
                if due:
                    out_far[yy, xx] = far
                    out_every[yy, xx] = every
                    out_lbest[yy, xx] = lk[0]
                out_err[yy, xx] = far / (1.0 + every)
                if count > 1:
                    out_conf[yy, xx] = (mk[1] - mk[0]) / mk[1] if mk[1] > mk[0] else 0.0
                elif unscored > 0:  # d2 >= d1 + SKIP_MARGIN: the ratio's lower bound
                    out_conf[yy, xx] = SKIP_MARGIN / (mk[0] + SKIP_MARGIN)
                else:
                    out_conf[yy, xx] = 0.0
                out_contrast[yy, xx] = ck[0]


@njit(cache=True, parallel=True)
def _tail_pass(frames, white, black, scale, xtab, nbits, cand, tail, far, every, lbest, idx, fdr, a, beta, packed,
               flips, columns, tail_weight, wlo, whi, in_band, threads, ptab, pu0, pdu, pw0, pdw, pout, use_prior,
               pmin, edges, skip, out_err):
    """Step 3's tail mass, after `_posterior` and the not-lit lookup: where ``tail`` is 1 and the
    pixel's P(not lit) = fdr[idx] is below 1/2, `_tail_mass` scaled to the share of the codebook
    the band allows is added to its far and every, and out_err = far / (1 + every) again (the
    arithmetic of one pass, bit for bit).  Where P(not lit) >= 1/2 (or the gain is not finite),
    P(wrong) >= 1/2 whatever the tail adds: it is left out (the published value a lower bound, as
    where the sum stops).  Rows interleaved over the `threads` threads (`_interleaved`)."""
    n, height, width = frames.shape
    m = n + 2
    chunk = (height + threads - 1) // threads
    prior = (ptab, pu0, pdu, pw0, pdw, pout, use_prior, pmin, edges)
    for it in prange(chunk * threads):
        yy = _interleaved(it, chunk, threads)
        if yy >= height:
            continue
        buf = np.empty(m, np.float64)
        xs = np.empty(m, np.float64)
        dn = np.empty(n, np.float64)
        ds = np.empty(n, np.float64)
        dq = np.empty(n, np.float64)
        work = np.empty((8, columns.shape[1]), np.float64)
        delta = np.empty(n, np.float64)
        sorted_d = np.empty(n, np.float64)
        rk = np.empty(3, np.int32)
        for xx in range(width):
            k = idx[yy, xx]
            if tail[yy, xx] == 0 or k < 0 or fdr[k] >= 0.5:
                continue
            _pixel_samples(frames, white, black, scale, yy, xx, buf)  # as `_lane_samples` loads them
            for j in range(3):
                rk[j] = cand[yy, xx, j]
            f = far[yy, xx]
            e = every[yy, xx]
            # P(wrong) = (far + tail) / (1 + every + tail) >= 1/2 once tail >= 1 + every - 2 far: the
            # sum may stop there (invalid under any target; the published value a lower bound)
            enough = (1.0 + e - 2.0 * f) / in_band
            t = in_band * _tail_mass(buf, xs, rk, lbest[yy, xx], 3, n, nbits, xtab, a, beta, packed, flips, columns,
                                     tail_weight, wlo, whi, prior, skip, enough, dn, ds, dq, delta, sorted_d, work)
            f += t
            e += t
            out_err[yy, xx] = f / (1.0 + e)


@njit(cache=True)
def _refit(m, n1, tot, s1, sq, q1, a, beta):
    """A binary codeword's least-squares levels and residuals from its sample sums (see
    `_word_cost`): (b, c, n0, v0, v1, ss0, ss1), b the off level, c >= 0 the contrast, n0 = m -
    n1 the symbol-0 samples, v0 / v1 the variances of the two levels, ss0 / ss1 the sums of
    squared residuals about them (may round below 0).  Branch-free, so that loops over words
    vectorise."""
    den = m * n1 - n1 * n1
    c = (m * s1 - n1 * tot) / den if den > 0 else 0.0
    c = c if c > 0.0 else 0.0
    b = (tot - c * n1) / m
    m1 = b + c
    n0 = m - n1
    v0 = a + beta * (b if b > 0.0 else 0.0)
    v1 = a + beta * (m1 if m1 > 0.0 else 0.0)
    ss0 = (sq - q1) - 2.0 * b * (tot - s1) + n0 * b * b
    ss1 = q1 - 2.0 * m1 * s1 + n1 * m1 * m1
    return b, c, n0, v0, v1, ss0, ss1


@njit(cache=True)
def _word_cost(m, n1, tot, s1, sq, q1, a, beta, ptab, pu0, pdu, pw0, pdw, pout, use_prior):
    """-2 log posterior (up to the constant of `_posterior`'s ``lk``) of a binary codeword from
    its sample sums: n1 samples of symbol 1 (white included) of m, ``tot`` / ``sq`` the sum of
    all samples / their squares, ``s1`` / ``q1`` those of the symbol-1 samples.  The levels are
    `_fit`'s least-squares (b, c >= 0, `_refit`) and L is `_nll`'s, in closed form; plus the level
    prior."""
    b, c, n0, v0, v1, ss0, ss1 = _refit(m, n1, tot, s1, sq, q1, a, beta)
    cost = (ss0 if ss0 > 0.0 else 0.0) / v0 + n0 * np.log(v0) + (ss1 if ss1 > 0.0 else 0.0) / v1 + n1 * np.log(v1)
    if use_prior:
        cost += cost_at(ptab, pu0, pdu, pw0, pdw, pout, b, c)
    return cost


@njit(cache=True)
def _tail_mass(buf, xs, rk, lbest, count, n, nbits, xtab, a, beta, packed, flips, columns, weight, wlo, whi, prior,
               skip, enough, dn, ds, dq, delta, sorted_d, work):
    """Sum of exp(-(P_c - lbest) / 2) over the codewords c = c1 xor h, h a codeword of weight
    wlo..whi of a binary linear code, other than the candidates already scored, where ``P_c``
    is c's -2 log-likelihood with its own refitted levels plus the level prior (`_word_cost`),
    and lbest that of the best candidate c1 = rk[0].  Flipping bit i moves its samples between
    the symbol-1 and symbol-0 sums: dn_i / ds_i / dq_i are the changes of the count, the sum and
    the sum of squares of the symbol-1 samples, so each word costs O(weight).  The sum runs over
    `_flips`' evenly spaced sample of those h, times `weight` (their number / the sample's),
    minus the scored candidates' own terms.

    Skipped (0) where it is negligible for sure: under c1's levels flipping bit i costs
    ``delta_i``, so a weight-w word costs at least the sum of the w smallest; refitting the levels
    lowers a word's cost, without noise by the share d / m of its d flipped samples of m, at most
    1 / 2 (`TAIL_REFIT_SHARE`), and the prior lowers it by at most ``pmin - P(c1's levels)`` (pmin
    the table's least cost).  Where that bound times the number of words is below `TAIL_FLOOR`,
    no word is evaluated.  Else the sampled words are `_tail_words`' (columns: `TailTables.columns`;
    skip: `_skip_cost`), stopped once the sum is at least ``enough`` (then a lower bound; inf:
    never); prior: the kernel form of the level prior with its cell edges, (table, u0, du, w0,
    dw, outside, use, least, edges); work: (8, L) float64 scratch."""
    ptab, pu0, pdu, pw0, pdw, pout, use_prior, pmin, edges = prior
    m = n + 2
    b, c = _fit(buf, xs, rk[0], n, xtab)  # xs: c1's symbols of the m samples
    # the bound: per-bit flip costs under c1's levels (two levels, two variances, two logs)
    m0 = b + c * 0.0
    m1 = b + c * 1.0
    v0 = a + beta * (m0 if m0 > 0.0 else 0.0)
    v1 = a + beta * (m1 if m1 > 0.0 else 0.0)
    g0 = np.log(v0)
    g1 = np.log(v1)
    for i in range(n):  # a flipped bit takes the sample's symbol x to 1 - x
        one = xs[i] != 0.0
        mo = m1 if one else m0
        mf = m0 if one else m1
        vo = v1 if one else v0
        vf = v0 if one else v1
        eo = buf[i] - mo
        ef = buf[i] - mf
        delta[i] = (ef * ef / vf + (g0 if one else g1)) - (eo * eo / vo + (g1 if one else g0))
    for i in range(nbits):  # with inverse frames a bit flips a pattern and an inverse sample
        if n > nbits:
            delta[i] += delta[i + nbits]
        sorted_d[i] = delta[i]
    sort_small(sorted_d, nbits)
    lowest = 0.0
    for i in range(wlo):
        lowest += sorted_d[i]
    bound = TAIL_REFIT_SHARE * lowest
    if use_prior:
        bound += pmin - cost_at(ptab, pu0, pdu, pw0, pdw, pout, b, c)
    if flips.size * weight * np.exp(-0.5 * min(max(bound, -_CLIP), _CLIP)) < TAIL_FLOOR:
        return 0.0
    n1 = 0.0
    tot = 0.0
    sq = 0.0
    s1 = 0.0
    q1 = 0.0
    for i in range(m):
        r = buf[i]
        tot += r
        sq += r * r
        if xs[i] != 0.0:
            n1 += 1.0
            s1 += r
            q1 += r * r
    for i in range(nbits):  # with inverse frames a bit flips a pattern and an inverse sample
        dn[i] = 0.0
        ds[i] = 0.0
        dq[i] = 0.0
        j = i
        while j < n:
            r = buf[j]
            if xs[j] != 0.0:
                dn[i] -= 1.0
                ds[i] -= r
                dq[i] -= r * r
            else:
                dn[i] += 1.0
                ds[i] += r
                dq[i] += r * r
            j += nbits
    # the scored candidates are not tail: what they add to the (estimated) sum is taken out
    own = packed[rk[0]]
    own1 = 0.0  # the second and third candidates' terms
    own2 = 0.0
    for k in range(1, count):
        word = own ^ packed[rk[k]]
        bits = 0
        wn = n1
        ws = s1
        wq = q1
        for i in range(nbits):
            if (word >> np.uint64(i)) & np.uint64(1):
                bits += 1
                wn += dn[i]
                ws += ds[i]
                wq += dq[i]
        if wlo <= bits <= whi:
            d = _word_cost(m, wn, tot, ws, sq, wq, a, beta, ptab, pu0, pdu, pw0, pdw, pout, use_prior) - lbest
            e = np.exp(-0.5 * min(max(d, -_CLIP), _CLIP))
            if k == 1:
                own1 = e
            else:
                own2 = e
    total = _tail_words(m, columns, dn, ds, dq, n1, s1, q1, tot, sq, a, beta, v0, v1, g0, g1, ptab, pu0, pdu, pw0,
                        pdw, pout, use_prior, edges, lbest, skip, (enough + own1 + own2) / weight, work)
    total = total * weight - own1 - own2
    return total if total > 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def _tail_words(m, columns, dn, ds, dq, n1, s1, q1, tot, sq, a, beta, vr0, vr1, g0, g1, ptab, pu0, pdu, pw0, pdw, pout,
                use_prior, edges, lbest, skip, enough, work):
    """`_tail_mass`'s sum over the sampled words, before the weight: the sum of exp(-(P_c -
    lbest) / 2) over the words whose ``P_c - lbest <= skip`` (each of the rest adds less than
    exp(-skip / 2)), taken over blocks of `TAIL_BLOCK` words in order and stopped after the
    first block at whose end the sum is >= ``enough`` (then a lower bound; inf: every word).

    columns (nbits, L) float64 0/1: column j the bits word j flips (`TailTables.columns`); dn / ds /
    dq (>= nbits,): `_tail_mass`'s per-bit changes; n1 / s1 / q1, tot / sq: c1's sums as
    `_word_cost` takes them; vr0 / vr1: the variances of c1's levels, g0 / g1 their logs; edges
    (GRID + 1,): the prior's u-cell edges as contrasts (`level_prior.contrast_edges`).

    Each word's P_c is `_word_cost`'s, with the same operations (`_refit`), except for two things:
    * the logs ``ln(v / vr)`` of its two variances are the series ``2 (z + z**3 / 3 + ... +
      z**19 / 19)`` of ``2 atanh z``, ``z = (v - vr) / (v + vr)``, whose truncation error is
      below 2e-11 where ``|z| <= 1/3`` (the words refit variances near c1's); elsewhere the word
      is `_word_cost` exactly;
    * its u-cell is the count of edges at or below its contrast, less one: `cost_at`'s cell
      exactly (the edges are `contrast_edges`'), found without a log.
    A block's words are scored in branch-free passes over all of them at once (vectorised), then
    one pass adds the prior cells and one sums the exponentials of the words within the skip;
    the sum runs over the words in order, whatever the blocks, so a sum that is not stopped does
    not depend on them.  work: (8, L) float64 scratch (per word: symbol-1 count, sum, sum of
    squares, cost, contrast, w-cell, exact-path flag, u-cell + 1)."""
    wn = work[0]
    ws = work[1]
    wq = work[2]
    cost = work[3]
    cw = work[4]
    fw = work[5]
    exact = work[6]
    fu = work[7]
    words = columns.shape[1]
    third = 1.0 / 3.0
    rows = ptab.shape[0]
    cols = ptab.shape[1]
    table = ptab.ravel()
    total = 0.0
    for j0 in range(0, words, TAIL_BLOCK):
        j1 = min(words, j0 + TAIL_BLOCK)
        # the block's views (1-d contiguous, indexed from 0: the loops vectorise)
        bn = wn[j0:j1]
        bs = ws[j0:j1]
        bq = wq[j0:j1]
        bc = cost[j0:j1]
        bw = cw[j0:j1]
        bf = fw[j0:j1]
        bx = exact[j0:j1]
        bu = fu[j0:j1]
        size = j1 - j0
        for j in range(size):
            bn[j] = n1
            bs[j] = s1
            bq[j] = q1
        for i in range(columns.shape[0]):  # bit by bit in ascending order, as the scalar sums (x + 0 * d is x)
            en = dn[i]
            es = ds[i]
            eq = dq[i]
            row = columns[i][j0:j1]
            for j in range(size):
                f = row[j]
                bn[j] += f * en
                bs[j] += f * es
                bq[j] += f * eq
        for j in range(size):
            tn = bn[j]
            b, c, n0, v0, v1, ss0, ss1 = _refit(m, tn, tot, bs[j], sq, bq[j], a, beta)
            z0 = (v0 - vr0) / (v0 + vr0)
            z1 = (v1 - vr1) / (v1 + vr1)
            bp = b if b > 0.0 else 0.0
            cp = c if c > C_FLOOR else C_FLOOR
            bc[j] = ((ss0 if ss0 > 0.0 else 0.0) / v0 + n0 * (g0 + _atanh2(z0))
                     + (ss1 if ss1 > 0.0 else 0.0) / v1 + tn * (g1 + _atanh2(z1)))
            bx[j] = 0.0 if abs(z0) <= third and abs(z1) <= third else 1.0
            bw[j] = cp
            bf[j] = np.floor((bp / (bp + cp) - pw0) / pdw)
        if use_prior:
            cmin = np.inf
            cmax = 0.0
            for j in range(size):  # (apart from the pass above: a float min / max keeps it from vectorising)
                cmin = min(cmin, bw[j])
                cmax = max(cmax, bw[j])
            # edges at or below every word's contrast: lo; at or below none: from hi on
            lo = 0
            while lo < edges.size and edges[lo] <= cmin:
                lo += 1
            hi = lo
            while hi < edges.size and edges[hi] <= cmax:
                hi += 1
            for j in range(size):
                bu[j] = lo
            for e in range(lo, hi):
                edge = edges[e]
                for j in range(size):
                    bu[j] += 1.0 if bw[j] >= edge else 0.0
            # each word's P_c - lbest (in cost): the prior's cell added
            for j in range(size):
                iu = bu[j] - 1.0
                iw = bf[j]
                inside = iu >= 0.0 and iu < rows and iw >= 0.0 and iw < cols
                cell = table[int(iu if inside else 0.0) * cols + int(iw if inside else 0.0)]
                bc[j] = bc[j] - lbest + (cell if inside else pout)
        else:
            for j in range(size):
                bc[j] = bc[j] - lbest
        for j in range(size):  # the words for the exact path
            if bx[j] != 0.0:
                bc[j] = _word_cost(m, bn[j], tot, bs[j], sq, bq[j], a, beta, ptab, pu0, pdu, pw0, pdw, pout,
                                   use_prior) - lbest
        # the block's words within the skip, in order (branch-free; their indices in bf, done
        # with), then their odds
        kept = 0
        for j in range(size):
            bf[kept] = j
            kept += 1 if bc[j] <= skip else 0
        for t in range(kept):
            d = bc[int(bf[t])]
            total += np.exp(-0.5 * (d if d > -_CLIP else -_CLIP))
        if total >= enough:
            break
    return total


@njit(cache=True)
def _atanh2(z):
    """2 atanh z = ln((1 + z) / (1 - z)) by its series to z**19 (|z| <= 1/3: error below 2e-11)."""
    z2 = z * z
    p = 1.0 / 19.0
    p = 1.0 / 17.0 + z2 * p
    p = 1.0 / 15.0 + z2 * p
    p = 1.0 / 13.0 + z2 * p
    p = 1.0 / 11.0 + z2 * p
    p = 1.0 / 9.0 + z2 * p
    p = 1.0 / 7.0 + z2 * p
    p = 0.2 + z2 * p
    p = 1.0 / 3.0 + z2 * p
    p = 1.0 + z2 * p
    return 2.0 * z * p


#: `_tail_words` scores the words in blocks of this many (and may stop after a block).
TAIL_BLOCK = 64
#: The tail words `_tail_words` leaves out (``P_c - lbest`` above the skip, `_skip_cost`) add
#: less than this together: the error probability is exact to it.
TAIL_ACCURACY = 1e-8


def _skip_cost(words: float) -> float:
    """`_tail_words`' skip: the -2 log odds beyond which a word is left out, so that `words`
    (the number of words the sample stands for) of them add less than `TAIL_ACCURACY`."""
    return 2.0 * float(np.log(max(words, 1.0) / TAIL_ACCURACY))


_XTAB: dict[tuple[int, bool], np.ndarray] = {}
_WORDS: dict[tuple[int, bool], np.ndarray] = {}
_FLIPS: dict[int, TailTables] = {}
#: Codeword weights d_min .. d_min + TAIL_WEIGHTS enter the tail mass (`_flips`).
TAIL_WEIGHTS = 2
#: The tail mass sums an evenly spaced sample of at most this many of the low-weight codewords.
TAIL_WORDS = 1024
#: The tail mass is skipped where its bound (all of them as likely as the third candidate) is
#: below this (an error probability far below any target), and where the top three already
#: give P(confused) >= 1/2 (invalid under any target; the published value is then a lower bound);
#: its sum stops (`_tail_words`, after a block) once it takes P(confused) to 1/2.
TAIL_FLOOR = 1e-4
#: The least share of a flip's cost under c1's levels that is left once the word's own levels are
#: refitted (`_tail_mass`'s skip bound): without noise it is 1 - d / m for d flipped samples of m,
#: and the tail's words have d <= m / 2.
TAIL_REFIT_SHARE = 0.5


def _xtab(code: Code, inverse: bool = False) -> np.ndarray:
    """(size, n) float64 symbol / (q - 1) of every codeword, with inverse frames (size, 2n): the
    pattern's symbols, then the inverse pattern's (1 - x).  Cached per (code object, inverse)."""
    key = (id(code), bool(inverse))
    tab = _XTAB.get(key)
    if tab is None or tab.shape[0] != code.size:
        tab = np.asarray(code.codebook, np.float64) / float(code.q - 1)
        if inverse:
            tab = np.concatenate([tab, 1.0 - tab], axis=1)
        tab = np.ascontiguousarray(tab)
        _XTAB[key] = tab
    return tab


def packed_symbols(xtab: np.ndarray) -> np.ndarray:
    """(rows,) uint64: bit i of row r set where ``xtab[r, i] == 1``, for a table of 0 / 1 symbols
    with at most 64 columns (a binary code's `_xtab`, inverse frames included, or a part of it);
    empty (0,) for any other table (`edge.decode.misfit` then takes its general kernel)."""
    if xtab.shape[1] > 64 or not np.isin(xtab, (0.0, 1.0)).all():
        return np.zeros(0, np.uint64)
    return np.ascontiguousarray(pack_words(xtab == 1.0))


def _words(code: Code, inverse: bool = False) -> np.ndarray:
    """(2, size) uint64 `_xtab`'s rows packed (`packed_symbols` of its columns 0-63 and 64-127):
    bit i of ``[i // 64, row]`` is symbol i of a binary code's row (up to 128 samples: 2n with
    inverse frames, n <= 64).  A code of more than two symbols, which `_lane_nll` does not take,
    gets zeros.  Cached with `_xtab`; row 0 is `edge.decode.misfit`'s packed table where the
    samples are at most 64."""
    key = (id(code), bool(inverse))
    tab = _WORDS.get(key)
    if tab is None or tab.shape[1] != code.size:
        x = _xtab(code, inverse)
        tab = np.zeros((2, x.shape[0]), np.uint64)
        if code.q == 2:
            tab[0] = packed_symbols(x[:, :64])
            if x.shape[1] > 64:
                tab[1] = packed_symbols(x[:, 64:])
        _WORDS[key] = tab
    return tab


def _samples(frames: np.ndarray, inverse: np.ndarray | None) -> np.ndarray:
    """The code samples of a capture: frames (n, H, W), or frames then inverse (2n, H, W), C-contiguous
    (the kernels read rows; one compiled layout per dtype)."""
    return np.ascontiguousarray(frames) if inverse is None else np.concatenate([frames, inverse], axis=0)


def no_tail_tables() -> TailTables:
    """`TailTables` with no sampled word (L = 0): no tail term."""
    return TailTables(np.zeros(1, np.uint64), np.zeros(0, np.uint64), np.zeros((0, 1), np.int32),
                      np.zeros(1, np.int32), np.zeros((1, 0), np.float64), 1.0, 0, 0)


def _flips(code: Code) -> TailTables:
    """The tail mass's tables (`TailTables`) of a binary linear code with n <= 64: its sampled
    words are an evenly spaced sample (at most TAIL_WORDS) of its nonzero codewords of weight
    wlo = d_min .. whi = d_min + TAIL_WEIGHTS.  Other codes: L = 0 (no tail term).  Cached per
    code object."""
    key = id(code)
    hit = _FLIPS.get(key)
    if hit is None:
        hit = no_tail_tables()
        if code.q == 2 and code.is_linear and code.n <= 64:
            packed = pack_words(code.codebook)
            weights = np.asarray(code.codebook, np.int64).sum(axis=1)
            nonzero = weights[weights > 0]
            if nonzero.size:
                dmin = int(nonzero.min())
                every = np.nonzero((weights > 0) & (weights <= dmin + TAIL_WEIGHTS))[0]
                pick = every[np.unique(np.linspace(0, every.size - 1, min(TAIL_WORDS, every.size)).round().astype(int))]
                wmax = int(weights[pick].max())
                bits = np.zeros((pick.size, wmax), np.int32)
                for j, r in enumerate(pick):
                    pos = np.nonzero(code.codebook[r])[0]
                    bits[j, :pos.size] = pos
                columns = np.ascontiguousarray(np.asarray(code.codebook, np.float64)[pick].T)
                hit = TailTables(packed, packed[pick].copy(), bits, weights[pick].astype(np.int32), columns,
                                 every.size / pick.size, dmin, dmin + TAIL_WEIGHTS)
        _FLIPS[key] = hit
    return hit


def posterior(frames: np.ndarray, white: np.ndarray, black: np.ndarray, scale: float, code: Code,
              candidates: np.ndarray, noise: Noise, *, choices: int, inverse: np.ndarray | None = None,
              distances: np.ndarray | None = None) -> Posterior:
    """Step 3 of the module docstring.

    frames (n, H, W), white / black (H, W), inverse (n, H, W) or None: the raw capture (``scale``
    to normalised units; inverse frames are n more samples, of symbol 1 - x); candidates: (H, W,
    3) int32 rows of the search (-1 none; `kernels.BEYOND`: a codeword more than `SKIP_MARGIN`
    behind the best that a search with that margin did not locate, treated as a candidate not
    rescored and returned as -1); noise: `fit_noise`'s model; choices: N, the number of columns a
    pixel could have decoded to (codebook rows in use, or the rows of the disparity band), >= 1;
    distances: (H, W, 3) the search's distances (-2 log-likelihood), or None (every candidate is
    rescored): candidates more than `SKIP_MARGIN` behind the best are not rescored.
    """
    if choices < 1:
        raise ValueError(f"choices: expected >= 1 candidate columns, got {choices}")
    h, w = white.shape
    cand = np.ascontiguousarray(candidates, np.int32)
    out_cand = np.empty((h, w, 3), np.int32)
    out_dist = np.empty((h, w, 3), np.float32)
    competitors = np.empty((h, w), np.float64)
    gain = np.empty((h, w), np.float64)
    conf = np.empty((h, w), np.float32)
    contrast = np.empty((h, w), np.float32)
    tail = _flips(code)
    has_inv = inverse is not None
    xtab = _xtab(code, has_inv)
    searched = (np.zeros(cand.shape, np.float32) if distances is None
                else np.ascontiguousarray(distances, np.float32))
    samples = _samples(frames, inverse)
    args = kernel_args(noise.levels)
    edges = contrast_edges(noise.levels)
    threads = max(1, get_num_threads())
    due = np.empty((h, w), np.uint8)
    far = np.empty((h, w), np.float64)
    every = np.empty((h, w), np.float64)
    lbest = np.empty((h, w), np.float64)
    misfit = np.empty((h, w), np.float32)
    _posterior(samples, white, black, np.float64(scale), xtab, _words(code, has_inv), cand, searched, float(noise.a),
               float(noise.beta), tail.flips, float(tail.weight), bool(np.isin(xtab, (0.0, 1.0)).all()), threads,
               *args[:7], edges, out_cand, out_dist, competitors, gain, conf, contrast, far, every, lbest, due, misfit)
    fdr, idx = _not_lit_lookup(gain, code, choices, has_inv)
    if tail.flips.size:
        _tail_pass(samples, white, black, np.float64(scale), xtab, code.n, out_cand, due, far, every, lbest, idx, fdr,
                   float(noise.a), float(noise.beta), tail.packed, tail.flips, tail.columns, float(tail.weight),
                   int(tail.wlo), int(tail.whi), min(1.0, choices / code.size), threads, *args,
                   edges, _skip_cost(tail.flips.size * tail.weight), competitors)
    err = np.empty((h, w), np.float32)
    _combine(idx, competitors, fdr, err)
    return Posterior(out_cand, out_dist, err, conf, contrast, noise, misfit)


# ----------------------------------------------------------------------------- the "not lit" test

#: Pseudo-pixels of the null sample (`_null`), its seed, and the quantile beyond which its
#: survival function is extrapolated exponentially.
NULL_SAMPLES = 16384
NULL_SEED = 20261201
NULL_TAIL_QUANTILE = 0.99
#: Bin width of the histogram of sqrt(gain) (`not_lit_probability`).
GAIN_BIN = 0.25

_NULL: dict[tuple[int, int, bool], tuple[np.ndarray, float, float]] = {}


def _null(code: Code, rows: int, inverse: bool = False) -> tuple[np.ndarray, float, float]:
    """The gain statistic of pixels the pattern does not reach: (sorted sample (NULL_SAMPLES,),
    x_q = its NULL_TAIL_QUANTILE, tail slope s with S0(x) = (1 - q) exp(-s (x - x_q)) beyond x_q).

    Under "not lit" the m samples are one level plus white Gaussian noise; the gain of the best
    of the first `rows` codewords (white x = 1, black x = 0 included) with contrast >= 0 is
    ``max_c max(0, z . u_c)**2`` with u_c the centred, unit-norm symbol vector.  Monte Carlo with a
    fixed seed (deterministic), cached per (code, rows).
    """
    key = (id(code), int(rows), bool(inverse))
    hit = _NULL.get(key)
    if hit is not None:
        return hit
    rows = max(1, min(int(rows), code.size))
    x = np.concatenate([_xtab(code, inverse)[:rows], np.ones((rows, 1)), np.zeros((rows, 1))], axis=1)
    m = x.shape[1]
    x -= x.mean(axis=1, keepdims=True)
    x /= np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-12)
    z = np.random.default_rng(NULL_SEED).standard_normal((NULL_SAMPLES, m))
    best = np.zeros(NULL_SAMPLES)
    for i in range(0, rows, 256):
        proj = np.maximum(z @ x[i:i + 256].T, 0.0)
        best = np.maximum(best, (proj * proj).max(axis=1))
    sample = np.sort(best)
    xq = float(np.quantile(sample, NULL_TAIL_QUANTILE))
    x999 = float(np.quantile(sample, 1.0 - (1.0 - NULL_TAIL_QUANTILE) / 10.0))
    slope = float(np.log(10.0) / max(x999 - xq, 1e-6))
    _NULL[key] = out = (sample, xq, slope)
    return out


def _null_survival(xs: np.ndarray, null: tuple[np.ndarray, float, float]) -> np.ndarray:
    """S0(x) = P(gain >= x | not lit): empirical up to x_q, exponential tail beyond."""
    sample, xq, slope = null
    emp = 1.0 - np.searchsorted(sample, xs, side="left") / sample.size
    tail = (1.0 - NULL_TAIL_QUANTILE) * np.exp(-slope * (xs - xq))
    return np.where(xs <= xq, emp, np.minimum(tail, 1.0 - NULL_TAIL_QUANTILE))


def not_lit_probability(gain: np.ndarray, code: Code, rows: int, *, inverse: bool = False) -> np.ndarray:
    """(H, W) float64 P(the pixel is not lit by the pattern | its gain), 0..1.

    gain: (H, W) ``L_0 - L_1`` (NaN where no candidate); rows: codebook rows a pixel could decode
    to; inverse: whether the capture had inverse frames (the null law of 2n + 2 samples).
    Two-group model (a local false-discovery rate): the pixels of this capture are a mixture
    of "not lit" pixels, whose gain follows the known null law S0 (`_null`), and lit ones.  With
    ``u = sqrt(max(gain, 0))`` in bins of `GAIN_BIN`, ``P(not lit | u in bin) = pi0 * N * P0(bin) /
    max(count(bin), 1)`` (an empty bin counts one pixel; clipped to 1, then made non-increasing in
    u; the last bin of `gain_bins`, past the null's reach, 0), where N is the number of pixels
    with a finite gain and pi0 the fraction of not-lit pixels, estimated as ``#(gain < null
    median) / (N / 2)`` (Storey's estimator at lambda = 1/2, at most 1).  A gain that is not
    finite: 0.  Nothing is assumed about the scene: the share of shadow pixels comes from the
    capture.
    """
    ok = np.isfinite(gain)
    out = np.zeros(gain.shape, np.float64)
    total = int(ok.sum())
    if total == 0:
        return out
    fdr, idx = _not_lit_lookup(gain, code, rows, inverse)
    _dark(idx, fdr, out)
    return out


@njit(cache=True, parallel=True)
def _gain_index(gain, median, nb, bin_width, out_idx, out_below):
    """out_idx (H, W) int64: the bin ``min(int(sqrt(max(g, 0)) / GAIN_BIN), nb)`` of each finite
    gain (`gain_bins`), -1 where the gain is not finite; out_below (H,) int64 per row: the finite
    gains below the null median.  Branch-free per pixel (vectorises)."""
    height, width = gain.shape
    for yy in prange(height):
        row = gain[yy]
        idx = out_idx[yy]
        below = 0
        for xx in range(width):
            g = row[xx]
            ok = np.isfinite(g)
            g0 = g if g >= 0.0 else 0.0
            u = np.sqrt(g0) / bin_width
            k = nb if not u < nb else np.int64(u)
            idx[xx] = k if ok else -1
            below += 1 if (ok and g0 < median) else 0
        out_below[yy] = below


@njit(cache=True)
def _bin_counts(idx, nb, out):
    """out (nb + 1,) int64: the pixels per bin 0..nb of idx (H, W) (-1: not counted)."""
    out[:] = 0
    for k in idx.ravel():
        if k >= 0:
            out[k] += 1


@njit(cache=True, parallel=True)
def _dark(idx, fdr, out):
    """out (H, W) float64 = fdr[idx] where idx >= 0 (left as it is elsewhere)."""
    height, width = idx.shape
    for yy in prange(height):
        for xx in range(width):
            k = idx[yy, xx]
            if k >= 0:
                out[yy, xx] = fdr[k]


@njit(cache=True, parallel=True)
def _combine(idx, competitors, fdr, out):
    """out (H, W) float32 P(wrong) = ``1 - (1 - P(not lit)) * (1 - P(confused))`` where the gain
    is finite (idx >= 0; P(not lit) = fdr[idx], `not_lit_probability`), else 1."""
    height, width = idx.shape
    for yy in prange(height):
        ir = idx[yy]
        cr = competitors[yy]
        orow = out[yy]
        for xx in range(width):
            k = ir[xx]
            d = fdr[k if k >= 0 else 0]
            e = np.float32(1.0 - (1.0 - d) * (1.0 - cr[xx]))
            orow[xx] = e if k >= 0 else np.float32(1.0)


def _not_lit_lookup(gain: np.ndarray, code: Code, rows: int, inverse: bool) -> tuple[np.ndarray, np.ndarray]:
    """(fdr (nb + 1,) float64 `fdr_lookup` of this capture's gains, idx (H, W) int64 each pixel's
    bin, -1 where the gain is not finite): `not_lit_probability`'s model.  gain: (H, W) float64,
    NaN where no candidate."""
    median, nb = gain_bins(code, rows, inverse)
    idx = np.empty(gain.shape, np.int64)
    below = np.empty(gain.shape[0], np.int64)
    _gain_index(np.ascontiguousarray(gain, np.float64), np.float64(median), np.int64(nb), np.float64(GAIN_BIN),
                idx, below)
    counts = np.empty(nb + 1, np.int64)
    _bin_counts(idx, np.int64(nb), counts)
    total = int(counts.sum())
    if total == 0:
        return np.zeros(nb + 1, np.float64), idx
    return fdr_lookup(counts[:nb], total, int(below.sum()), code, rows, inverse), idx


def gain_bins(code: Code, rows: int, inverse: bool = False) -> tuple[float, int]:
    """(null median, nb) of `not_lit_probability`: a gain g >= 0 falls in bin
    ``min(int(sqrt(g) / GAIN_BIN), nb)`` (bin nb: beyond where the null's survival is negligible);
    pi0 counts the gains below the null median (a seam for device backends that bin on the device)."""
    null = _null(code, rows, inverse)
    x_end = null[1] + np.log(1e12) / null[2]
    return float(null[0][null[0].size // 2]), int(np.ceil(np.sqrt(x_end) / GAIN_BIN)) + 1


def fdr_lookup(counts: np.ndarray, total: int, below: int, code: Code, rows: int, inverse: bool = False) -> np.ndarray:
    """(nb + 1,) float64 P(not lit) per gain bin of `gain_bins` (the last: 0), from the (nb,)
    counts of the finite gains in bins 0..nb-1, their number `total` and the number `below` the
    null median (`not_lit_probability`'s two-group model)."""
    null = _null(code, rows, inverse)
    _, nb = gain_bins(code, rows, inverse)
    pi0 = min(1.0, float(below) / (0.5 * total))
    edges_u = np.arange(nb + 1) * GAIN_BIN
    s0 = _null_survival(edges_u ** 2, null)
    p0 = np.maximum(s0[:-1] - s0[1:], 0.0)
    fdr = np.minimum(1.0, pi0 * total * p0 / np.maximum(np.asarray(counts, np.float64)[:nb], 1.0))
    fdr = np.maximum.accumulate(fdr[::-1])[::-1]  # non-increasing in u (the conservative envelope)
    return np.append(fdr, 0.0)
