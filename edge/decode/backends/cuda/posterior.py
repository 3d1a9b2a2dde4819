"""The "error" validity rule's per-pixel stages on the GPU (`edge.decode.posterior`), float64.

One thread per pixel (`fit_stats`: per pixel of the noise fit's subgrid), each the CPU kernel's
arithmetic in the same order, every product through `cost.mul64` (no fused multiply-add).
The samples of a pixel are its n code frames, then (with inverse frames) its n inverse frames,
then white and black, each ``float64(raw) * scale`` (`posterior._pixel_samples`).

* `normalise`: the search's float32 stack of ``levels="auto"``: ``float32(raw) * float32(scale)``
  of the code (and inverse) frames (`decoder._decode_error_rule`).
* `split_levels`: `posterior._split_levels` (two-means of the m samples by Lloyd's iterations
  -> on / off float32 levels); its residual variance / mean level go to compact arrays that hold exactly the
  pixels `posterior._noise_from` subsamples for its fit (every `step`-th pixel, row-major; NaN
  where a sample is clipped, which the host drops as the CPU does), so only those are
  downloaded.
* `fit_stats`: `posterior._fit_stats` on the `posterior._steps` subgrid (residual variance, mean
  level and the levels (b, c) of the noise fit and the level prior; downloaded whole: at most
  `posterior.FIT_PIXELS` pixels).
* `posterior_kernel`: `posterior._posterior` (the top-3 refit NLLs plus the level prior
  re-ordered, the flat hypothesis' gain ``L_0 - min L_k``, the top three's competitor mass);
  writes candidates, distances, confidence, the gain, the competitor probability and, where the
  tail mass is due, the pixel's far / every / best cost and a due mask.
* `gain_histogram`: the counts of `posterior.not_lit_probability` with atomics (bins of
  `posterior.gain_bins`, the finite gains, those below the null median): the host turns the
  nb + 2 counters into the (nb + 1,) lookup of `posterior.fdr_lookup` (the gain array stays on
  the device).
* `tail_kernel`: `posterior._tail_pass` (the competitor mass of the codewords beyond the top
  three with `_tail_mass`, every tail word refitted, on the due pixels whose P(not lit) from the
  lookup is below 1/2, as on the CPU).
* `error_valid`: P(wrong) ``1 - (1 - P(not lit)) (1 - P(confused))`` (float32), column0 and,
  for methods "soft" / "hard", ``valid = error < max_error``.

Logs and exponentials are the device's (`math.log` / `math.exp`): under the simulator they are
the CPU's, on a GPU they may differ in the last bit, so error / distances agree to float
rounding there (columns, candidates and validity are equal except at exact ties).
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from ...level_prior import C_FLOOR
from ...posterior import FULL_SCALE_SAMPLE, TAIL_BLOCK, TAIL_REFIT_SHARE
from .cost import MAX_N, mul64, pixel_of, sort_small

TPB = 128
#: Most samples per pixel: 2 * MAX_N code + inverse frames, white, black.
MAX_M = 2 * MAX_N + 2
_CLIP = 700.0


@cuda.jit(device=True)
def _sample(frames, inverse, n, yy, xx, i):
    """Raw sample i (0..2n-1 with inverse frames: code frames, then inverse) of pixel (yy, xx)."""
    if i < n:
        return frames[i, yy, xx]
    return inverse[i - n, yy, xx]


@cuda.jit(device=True)
def _load(frames, inverse, ns, n, white, black, scale, yy, xx, buf):
    """buf[0:ns + 2] = the pixel's normalised samples (ns = n or 2n), white, black."""
    for i in range(ns):
        buf[i] = mul64(_sample(frames, inverse, n, yy, xx, i), scale)
    buf[ns] = mul64(white[yy, xx], scale)
    buf[ns + 1] = mul64(black[yy, xx], scale)


@cuda.jit(device=True)
def _clipped(buf, m):
    """`posterior._clipped`: a sample at 0 or at full scale (the pixel stays out of the noise fit)."""
    for i in range(m):
        if buf[i] <= 0.0 or buf[i] >= FULL_SCALE_SAMPLE:
            return True
    return False


@cuda.jit(device=True)
def _above(buf, m, t):
    """`posterior._above`: (sum, count) of the first m samples of buf above t."""
    sh = 0.0
    kh = 0
    for i in range(m):
        if buf[i] > t:
            sh += buf[i]
            kh += 1
    return sh, kh


@cuda.jit
def normalise(frames, inverse, has_inv, scale, out_f, out_inv):
    """out_f (n, H, W) float32 = float32(frames) * scale (float32); out_inv the same for inverse."""
    n = frames.shape[0]
    yy, xx, inside = pixel_of(cuda.grid(1), frames.shape[1], frames.shape[2])
    if not inside:
        return
    for i in range(n):
        out_f[i, yy, xx] = np.float32(np.float32(frames[i, yy, xx]) * scale)
        if has_inv:
            out_inv[i, yy, xx] = np.float32(np.float32(inverse[i, yy, xx]) * scale)


@cuda.jit
def split_levels(frames, inverse, has_inv, white, black, scale, iterations, step, out_hi, out_lo, out_s2, out_mu):
    """`posterior._split_levels` (at most `iterations` Lloyd steps, `posterior.SPLIT_ITERATIONS`);
    s2 / mu of pixel p go to out_*[p // step] where p % step == 0."""
    buf = cuda.local.array(MAX_M, np.float64)
    n = frames.shape[0]
    height = frames.shape[1]
    width = frames.shape[2]
    p = cuda.grid(1)
    yy, xx, inside = pixel_of(p, height, width)
    if not inside:
        return
    ns = 2 * n if has_inv else n
    m = ns + 2
    _load(frames, inverse, ns, n, white, black, scale, yy, xx, buf)
    # two-means by Lloyd's iterations from the calibration midpoint, as on the CPU
    top = buf[0]
    bottom = buf[0]
    total = 0.0
    for i in range(m):
        v = buf[i]
        total += v
        top = max(top, v)
        bottom = min(bottom, v)
    t = mul64(0.5, buf[ns] + buf[ns + 1]) if buf[ns] > buf[ns + 1] else mul64(0.5, top + bottom)
    hi = top
    lo = bottom
    count_hi = -1
    for _ in range(iterations):
        sh, kh = _above(buf, m, t)
        if kh == 0 or kh == m:  # one class: split at the mid-range instead
            t = mul64(0.5, top + bottom)
            sh, kh = _above(buf, m, t)
            if kh == 0 or kh == m:
                break
        hi = sh / kh
        lo = (total - sh) / (m - kh)
        t = mul64(0.5, hi + lo)
        if kh == count_hi:
            break
        count_hi = kh
    ssr = 0.0
    for i in range(m):
        e = buf[i] - (hi if buf[i] > t else lo)
        ssr += mul64(e, e)
    if p % step == 0:
        out_s2[p // step] = ssr / (m - 2) if not _clipped(buf, m) else np.nan
        out_mu[p // step] = total / m
    if hi - lo < 1e-6:
        hi = lo + 1e-6
    out_hi[yy, xx] = np.float32(hi)
    out_lo[yy, xx] = np.float32(lo)


@cuda.jit(device=True)
def _fit(buf, xs, row, ns, xtab):
    """`posterior._fit`: least-squares (b, c >= 0) of r = b + c x for codebook row `row`."""
    m = ns + 2
    sx = 1.0
    sxx = 1.0
    sr = 0.0
    sxr = buf[ns]
    for i in range(ns):
        x = xtab[row, i]
        xs[i] = x
        sx += x
        sxx += mul64(x, x)
        sxr += mul64(x, buf[i])
    xs[ns] = 1.0
    xs[ns + 1] = 0.0
    for i in range(m):
        sr += buf[i]
    den = mul64(np.float64(m), sxx) - mul64(sx, sx)
    c = (mul64(np.float64(m), sxr) - mul64(sx, sr)) / den if den > 0 else 0.0
    if c < 0.0:
        c = 0.0
    b = (sr - mul64(c, sx)) / m
    return b, c


@cuda.jit
def fit_stats(frames, inverse, has_inv, white, black, scale, xtab, best, step_y, step_x, out_s2, out_mu, out_b, out_c):
    """`posterior._fit_stats`: out_* (rows, cols) float64 of the subgrid pixel (ry * step_y, rx * step_x)."""
    buf = cuda.local.array(MAX_M, np.float64)
    xs = cuda.local.array(MAX_M, np.float64)
    rows = out_s2.shape[0]
    cols = out_s2.shape[1]
    ry, rx, inside = pixel_of(cuda.grid(1), rows, cols)
    if not inside:
        return
    n = frames.shape[0]
    ns = 2 * n if has_inv else n
    m = ns + 2
    yy = ry * step_y
    xx = rx * step_x
    row = best[yy, xx, 0]
    if row < 0:
        out_s2[ry, rx] = np.nan
        out_mu[ry, rx] = np.nan
        out_b[ry, rx] = np.nan
        out_c[ry, rx] = np.nan
        return
    _load(frames, inverse, ns, n, white, black, scale, yy, xx, buf)
    b, c = _fit(buf, xs, row, ns, xtab)
    out_b[ry, rx] = b
    out_c[ry, rx] = c
    ssr = 0.0
    mu = 0.0
    for i in range(m):
        mi = b + mul64(c, xs[i])
        e = buf[i] - mi
        ssr += mul64(e, e)
        mu += mi
    out_s2[ry, rx] = ssr / (m - 2) if not _clipped(buf, m) else np.nan
    out_mu[ry, rx] = mu / m


@cuda.jit(device=True)
def _nll(buf, xs, row, ns, xtab, a, beta, use_row):
    """`posterior._nll`: (L, Mahalanobis part, contrast, off level) of row `row` (use_row) or one flat level."""
    m = ns + 2
    if use_row:
        b, c = _fit(buf, xs, row, ns, xtab)
    else:
        b = 0.0
        for i in range(m):
            b += buf[i]
        b /= m
        c = 0.0
        for i in range(m):
            xs[i] = 0.0
    m1 = b + c
    v0 = a + mul64(beta, b if b > 0.0 else 0.0)
    v1 = a + mul64(beta, m1 if m1 > 0.0 else 0.0)
    l0 = math.log(v0)
    l1 = math.log(v1)
    r0 = 1.0 / v0
    r1 = 1.0 / v1
    total = 0.0
    maha = 0.0
    for i in range(m):
        x = xs[i]
        if x == 0.0:
            e = buf[i] - b
            q = mul64(mul64(e, e), r0)
            total += q + l0
        elif x == 1.0:
            e = buf[i] - m1
            q = mul64(mul64(e, e), r1)
            total += q + l1
        else:
            mi = b + mul64(c, x)
            v = a + mul64(beta, mi if mi > 0.0 else 0.0)
            e = buf[i] - mi
            q = mul64(e, e) / v
            total += q + math.log(v)
        maha += q
    return total, maha, c, b


@cuda.jit(device=True)
def _prior_cost(ptab, pu0, pdu, pw0, pdw, pout, b, c):
    """`level_prior.cost_at`: -2 log p of levels (b, c) under the capture's level prior."""
    bp = b if b > 0.0 else 0.0
    cp = c if c > C_FLOOR else C_FLOOR
    xu = (math.log10(cp) - pu0) / pdu
    xw = (bp / (bp + cp) - pw0) / pdw
    # floor(x) is in 0..n-1 exactly where 0 <= x < n; tested before the floor, which makes an
    # integer here: NaN (b = inf) and inf are off the grid, as in level_prior.cost_at
    if not (xu >= 0.0 and xu < ptab.shape[0] and xw >= 0.0 and xw < ptab.shape[1]):
        return pout
    return ptab[int(math.floor(xu)), int(math.floor(xw))]


@cuda.jit(device=True)
def _clipped_exp(d):
    """exp(-0.5 * clip(d, -_CLIP, _CLIP))."""
    return math.exp(mul64(-0.5, min(max(d, -_CLIP), _CLIP)))


@cuda.jit(device=True)
def _word_cost(m, n1, tot, s1, sq, q1, a, beta, ptab, pu0, pdu, pw0, pdw, pout, use_prior):
    """`posterior._word_cost` (see there)."""
    den = mul64(np.float64(m), n1) - mul64(n1, n1)
    c = (mul64(np.float64(m), s1) - mul64(n1, tot)) / den if den > 0 else 0.0
    if c < 0.0:
        c = 0.0
    b = (tot - mul64(c, n1)) / m
    m1 = b + c
    n0 = m - n1
    v0 = a + mul64(beta, b if b > 0.0 else 0.0)
    v1 = a + mul64(beta, m1 if m1 > 0.0 else 0.0)
    ss0 = (sq - q1) - mul64(mul64(2.0, b), tot - s1) + mul64(mul64(n0, b), b)
    ss1 = q1 - mul64(mul64(2.0, m1), s1) + mul64(mul64(n1, m1), m1)
    cost = ((ss0 if ss0 > 0.0 else 0.0) / v0 + mul64(n0, math.log(v0)) + (ss1 if ss1 > 0.0 else 0.0) / v1
            + mul64(n1, math.log(v1)))
    if use_prior:
        cost += _prior_cost(ptab, pu0, pdu, pw0, pdw, pout, b, c)
    return cost


@cuda.jit(device=True)
def _tail_mass(buf, xs, rk, lbest, count, ns, nbits, xtab, a, beta, packed, flips, flip_bits, flip_w, weight, wlo, whi,
               floor, ptab, pu0, pdu, pw0, pdw, pout, use_prior, pmin, enough, dn, ds, dq, delta, sorted_d):
    """`posterior._tail_mass` (see there; every word summed, not only those within the skip, and
    the sum stopped after the same blocks of `TAIL_BLOCK` words)."""
    m = ns + 2
    b, c = _fit(buf, xs, rk[0], ns, xtab)
    for i in range(ns):
        mo = b + mul64(c, xs[i])
        mf = b + mul64(c, 1.0 - xs[i])
        vo = a + mul64(beta, mo if mo > 0.0 else 0.0)
        vf = a + mul64(beta, mf if mf > 0.0 else 0.0)
        eo = buf[i] - mo
        ef = buf[i] - mf
        delta[i] = (mul64(ef, ef) / vf + math.log(vf)) - (mul64(eo, eo) / vo + math.log(vo))
    for i in range(nbits):
        if ns > nbits:
            delta[i] += delta[i + nbits]
        sorted_d[i] = delta[i]
    sort_small(sorted_d, nbits)
    lowest = 0.0
    for i in range(wlo):
        lowest += sorted_d[i]
    bound = mul64(TAIL_REFIT_SHARE, lowest)
    if use_prior:
        bound += pmin - _prior_cost(ptab, pu0, pdu, pw0, pdw, pout, b, c)
    if mul64(mul64(np.float64(flips.shape[0]), weight), _clipped_exp(bound)) < floor:
        return 0.0
    n1 = 0.0
    tot = 0.0
    sq = 0.0
    s1 = 0.0
    q1 = 0.0
    for i in range(m):
        r = buf[i]
        tot += r
        sq += mul64(r, r)
        if xs[i] != 0.0:
            n1 += 1.0
            s1 += r
            q1 += mul64(r, r)
    for i in range(nbits):
        dn[i] = 0.0
        ds[i] = 0.0
        dq[i] = 0.0
        j = i
        while j < ns:
            r = buf[j]
            if xs[j] != 0.0:
                dn[i] -= 1.0
                ds[i] -= r
                dq[i] -= mul64(r, r)
            else:
                dn[i] += 1.0
                ds[i] += r
                dq[i] += mul64(r, r)
            j += nbits
    own = packed[rk[0]]
    own1 = 0.0  # the scored candidates' terms (not tail)
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
        if wlo <= bits and bits <= whi:
            e = _clipped_exp(_word_cost(m, wn, tot, ws, sq, wq, a, beta, ptab, pu0, pdu, pw0, pdw, pout, use_prior)
                             - lbest)
            if k == 1:
                own1 = e
            else:
                own2 = e
    stop = (enough + own1 + own2) / weight
    total = 0.0
    for j in range(flips.shape[0]):
        wn = n1
        ws = s1
        wq = q1
        for t in range(flip_w[j]):
            bit = flip_bits[j, t]
            wn += dn[bit]
            ws += ds[bit]
            wq += dq[bit]
        total += _clipped_exp(_word_cost(m, wn, tot, ws, sq, wq, a, beta, ptab, pu0, pdu, pw0, pdw, pout, use_prior)
                              - lbest)
        if (j + 1) % TAIL_BLOCK == 0 and total >= stop:
            break
    total = mul64(total, weight) - own1 - own2
    return total if total > 0.0 else 0.0


@cuda.jit
def posterior_kernel(frames, inverse, has_inv, white, black, scale, xtab, cand, searched, skip_margin, a, beta,
                     nflips, tail_weight, floor, ptab, pu0, pdu, pw0, pdw, pout, use_prior,
                     out_cand, out_dist, out_comp, out_gain, out_conf, out_far, out_every, out_lbest, out_due,
                     out_misfit):
    """`posterior._posterior` (without the contrast output, which the decoder does not use):
    searched (H, W, 3) float32 the search's distances; candidates more than `skip_margin` behind
    the best are not rescored (kept after the scored ones with distance inf).  out_comp: the top
    three's P(confused) = far / (1 + every); out_due (H, W) uint8: 1 where the tail mass is due
    (`tail_kernel` adds it; nflips words of weight tail_weight, the gate of `_posterior`), with
    the pixel's far, every and best -2 log-posterior in out_far / out_every / out_lbest; out_misfit
    (H, W) float32 the best candidate's goodness-of-fit statistic (`posterior.Posterior.misfit`)."""
    buf = cuda.local.array(MAX_M, np.float64)
    xs = cuda.local.array(MAX_M, np.float64)
    lk = cuda.local.array(3, np.float64)
    mk = cuda.local.array(3, np.float64)
    rk = cuda.local.array(3, np.int32)
    rest = cuda.local.array(3, np.int32)
    n = frames.shape[0]
    yy, xx, inside = pixel_of(cuda.grid(1), frames.shape[1], frames.shape[2])
    if not inside:
        return
    ns = 2 * n if has_inv else n
    _load(frames, inverse, ns, n, white, black, scale, yy, xx, buf)
    count = 0
    unscored = 0
    plain = np.inf  # the least L_k without the prior (the not-lit gain's)
    for k in range(3):
        row = cand[yy, xx, k]
        if row < 0:
            continue
        if k > 0 and searched[yy, xx, k] - searched[yy, xx, 0] > skip_margin:  # float32 difference, as on the CPU
            rest[unscored] = row
            unscored += 1
            continue
        lr, maha, c, b = _nll(buf, xs, row, ns, xtab, a, beta, True)
        plain = min(plain, lr)
        total = lr + _prior_cost(ptab, pu0, pdu, pw0, pdw, pout, b, c) if use_prior else lr + 0.0
        j = count
        while j > 0 and lk[j - 1] > total:  # insertion by posterior (ties keep the search's order)
            lk[j] = lk[j - 1]
            mk[j] = mk[j - 1]
            rk[j] = rk[j - 1]
            j -= 1
        lk[j] = total
        mk[j] = maha
        rk[j] = row
        count += 1
    for k in range(3):
        if k < count:
            out_cand[yy, xx, k] = rk[k]
            out_dist[yy, xx, k] = np.float32(lk[k])
        elif k < count + unscored:
            out_cand[yy, xx, k] = rest[k - count]
            out_dist[yy, xx, k] = np.float32(np.inf)
        else:
            out_cand[yy, xx, k] = -1
            out_dist[yy, xx, k] = np.float32(np.inf)
    if count == 0:
        out_comp[yy, xx] = 0.0
        out_gain[yy, xx] = np.nan
        out_conf[yy, xx] = np.float32(0.0)
        out_misfit[yy, xx] = np.float32(np.nan)
        return
    top = buf[0]
    for i in range(ns + 2):
        top = max(top, buf[i])
    out_misfit[yy, xx] = np.float32(mk[0]) if top < FULL_SCALE_SAMPLE else np.float32(np.nan)
    l0, _m0, _c0, _b0 = _nll(buf, xs, 0, ns, xtab, a, beta, False)
    out_gain[yy, xx] = l0 - plain
    far = 0.0
    every = 0.0
    ek = 0.0
    for k in range(1, count):
        ek = math.exp(-min(mul64(lk[k] - lk[0], 0.5), _CLIP))
        every += ek
        if abs(rk[k] - rk[0]) > 1:
            far += ek
    due = (nflips > 0 and count == 3 and mul64(mul64(np.float64(nflips), tail_weight), ek) > floor
           and far < 1.0 + every - far)
    out_due[yy, xx] = 1 if due else 0
    if due:
        out_far[yy, xx] = far
        out_every[yy, xx] = every
        out_lbest[yy, xx] = lk[0]
    out_comp[yy, xx] = far / (1.0 + every)
    if count > 1:
        out_conf[yy, xx] = np.float32((mk[1] - mk[0]) / mk[1]) if mk[1] > mk[0] else np.float32(0.0)
    elif unscored > 0:  # d2 >= d1 + skip_margin: the ratio's lower bound
        out_conf[yy, xx] = np.float32(skip_margin / (mk[0] + skip_margin))
    else:
        out_conf[yy, xx] = np.float32(0.0)


@cuda.jit(device=True)
def _gain_bin(g, bin_width, nb):
    """The bin of gain g: min(int(sqrt(max(g, 0)) / bin_width), nb) (clamped before the cast)."""
    q = math.sqrt(g if g > 0.0 else 0.0) / bin_width
    if q >= nb:
        return np.int64(nb)
    return np.int64(q)


@cuda.jit(device=True)
def _not_lit(g, lookup, bin_width, nb):
    """P(not lit) of a pixel with gain g: lookup[bin of g] (`posterior.fdr_lookup`), 1 where g is
    not finite (no candidate)."""
    if not math.isfinite(g):
        return 1.0
    return lookup[_gain_bin(g, bin_width, nb)]


@cuda.jit
def gain_histogram(gain, bin_width, nb, median, counts):
    """counts (nb + 2,) int64: [0..nb-1] finite gains per bin (`posterior.gain_bins`; bin nb is not
    counted, as on the CPU), [nb] finite gains, [nb + 1] those with max(gain, 0) below the median."""
    yy, xx, inside = pixel_of(cuda.grid(1), gain.shape[0], gain.shape[1])
    if not inside:
        return
    g = gain[yy, xx]
    if not math.isfinite(g):
        return
    k = _gain_bin(g, bin_width, nb)
    if k < nb:
        cuda.atomic.add(counts, k, 1)
    cuda.atomic.add(counts, nb, 1)
    if (g if g > 0.0 else 0.0) < median:
        cuda.atomic.add(counts, nb + 1, 1)


@cuda.jit
def tail_kernel(frames, inverse, has_inv, white, black, scale, xtab, nbits, cand, due, far, every, lbest, gain, lookup,
                bin_width, nb, a, beta, packed, flips, flip_bits, flip_w, tail_weight, wlo, whi, in_band, floor,
                ptab, pu0, pdu, pw0, pdw, pout, use_prior, pmin, out_comp):
    """`posterior._tail_pass`: where due is 1 and the pixel's P(not lit) = lookup[bin of its gain]
    is below 1/2, `_tail_mass` scaled by in_band is added to its far and every and out_comp =
    far / (1 + every) again; where P(not lit) >= 1/2 (or the gain is not finite) P(wrong) >= 1/2
    whatever the tail adds, and it is left out as on the CPU.  cand: the posterior's candidates."""
    buf = cuda.local.array(MAX_M, np.float64)
    xs = cuda.local.array(MAX_M, np.float64)
    dn = cuda.local.array(MAX_N, np.float64)
    ds = cuda.local.array(MAX_N, np.float64)
    dq = cuda.local.array(MAX_N, np.float64)
    delta = cuda.local.array(MAX_M, np.float64)
    sorted_d = cuda.local.array(MAX_N, np.float64)
    rk = cuda.local.array(3, np.int32)
    n = frames.shape[0]
    yy, xx, inside = pixel_of(cuda.grid(1), frames.shape[1], frames.shape[2])
    if not inside or due[yy, xx] == 0:
        return
    if _not_lit(gain[yy, xx], lookup, bin_width, nb) >= 0.5:
        return
    ns = 2 * n if has_inv else n
    _load(frames, inverse, ns, n, white, black, scale, yy, xx, buf)
    for k in range(3):
        rk[k] = cand[yy, xx, k]
    f = far[yy, xx]
    e = every[yy, xx]
    enough = (1.0 + e - mul64(2.0, f)) / in_band  # P(confused) 1/2 (`posterior._tail_pass`)
    t = mul64(in_band, _tail_mass(buf, xs, rk, lbest[yy, xx], 3, ns, nbits, xtab, a, beta, packed, flips, flip_bits,
                                  flip_w, tail_weight, wlo, whi, floor, ptab, pu0, pdu, pw0, pdw, pout, use_prior,
                                  pmin, enough, dn, ds, dq, delta, sorted_d))
    f += t
    e += t
    out_comp[yy, xx] = f / (1.0 + e)


@cuda.jit
def error_valid(gain, comp, cand, lookup, bin_width, nb, max_error, out_err, out_col0, out_col, out_valid):
    """error (float32) = 1 - (1 - lookup[bin]) (1 - comp) where the gain is finite, else 1;
    column0 = cand[..., 0]; valid = error < max_error (float32) and column0 >= 0; column = column0
    where valid else -1."""
    yy, xx, inside = pixel_of(cuda.grid(1), gain.shape[0], gain.shape[1])
    if not inside:
        return
    e = 1.0 - mul64(1.0 - _not_lit(gain[yy, xx], lookup, bin_width, nb), 1.0 - comp[yy, xx])
    err = np.float32(e)
    c = cand[yy, xx, 0]
    ok = err < max_error and c >= 0
    out_err[yy, xx] = err
    out_col0[yy, xx] = c
    out_valid[yy, xx] = ok
    out_col[yy, xx] = c if ok else np.int32(-1)
