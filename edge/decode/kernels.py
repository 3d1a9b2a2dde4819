"""numba kernels of the decoders (compiled once, cached on disk with ``cache=True``).

Per-sample costs.  Each sample gets two non-negative costs ``e0, e1`` (one per bit value, for
N-ary codes one per symbol) such that the distance of a codeword is ``sum_i e_i(c_i)``:

* ``METRIC_ML`` (0): ``-2 log p(r | symbol)`` up to a per-pixel constant under the heteroscedastic
  Gaussian model ``r ~ N(mu_s, sigma_r**2 + sigma_s**2 * mu_s)``, with ``mu_1`` = white and
  ``mu_0`` = black (intensities normalised to [0, 1]); with inverse frames the sample is
  ``r - r_inv ~ N(+-(white - black), v_white + v_black)``.  ``e0 - e1 = 2 * LLR``.
* ``METRIC_NORMALIZED`` (1): the paper's plain normalised distance, ``(x - s)**2`` with
  ``x = (r - black) / (white - black)`` (with inverse: ``x = ((r - r_inv)/(white - black) + 1)/2``).
* ``METRIC_HARD`` (2): Hamming distance to the hard decision (``r > (white + black)/2`` or
  ``r > r_inv``); the distance output is then the exact Hamming distance.

Binary search.  ``y_i = round(Q * (e0 - e1))`` (int64, clipped); ``h`` = bits with ``y > 0``;
``w_i = |y_i|``.  For any codeword c, ``cost(c) = sum_{i in c xor h} w_i`` and the distance is
``dmin + cost / Q`` with ``dmin = sum_i min(e0, e1)``.  So the ML codeword is the one whose
disagreement set with h has the least reliability, and the kernels search that exactly:

1. reference codeword ``c_ref``: nearest codeword of h in Hamming distance (syndrome table) or
   the re-encoded information bits of h;
2. every other codeword is ``c_ref xor D`` with D a nonzero codeword; its cost is
   ``cost(c_ref) + sum_{i in D} v_i`` with ``v_i = +w_i`` where c_ref agrees with h, ``-w_i``
   where it does not;
3. the D are visited by Hamming weight t; any D of weight >= t costs at least
   ``min_{t' >= t} (sum of the t' smallest v)``; inside a weight class, D sharing the pattern p0
   on positions 0..5 cost at least ``T0[p0] + (sum of the t - |p0| smallest v outside 0..5)``.
   A class or sublist whose bound exceeds the current third-best cost is skipped, so the top-3
   (score | column keys, ties to the lower column) is exact.

Costs are summed with 64-entry subset-sum tables over 6-bit position groups.  This per-pixel
search is `soft_binary` (the "scalar" path, any binary code).

Fast paths (same keys, same ties, bit-identical results; tests compare them with `soft_binary`):

* `soft_lanes` (column-linear codes, see `tables`): the same c_ref / V decomposition, but
  LANES (= 64) consecutive pixels of a row are decoded together with V stored (n, LANES), so
  the cost of c_ref ^ D for every lane is |D| contiguous vector adds with positions shared by
  all lanes, the column is col(c_ref) ^ col(D), and the top-3 update is a branch-free min/max
  network per lane.  Whole weight classes are evaluated (D = 0 and the lightest class for the
  whole block); a lane is finished when its third-best cost is below the class bound of the
  heavier classes (sum of the t smallest V, lanes sorted with a vectorised odd-even network);
  the others are moved to a per-row pending block that evaluates the next classes.  On the
  issue-4 benchmark (ecc-22-10: classes 8, 12, 16) about 5e-6 of the pixels need class 12.
* `soft_band` (any binary code, a band of at most a few hundred columns): per pixel
  cost(c) = C0 - sum_i (masks_t[i, c] & y_i) over the contiguous candidate columns, then a
  BAND_NET-wide (16) min/max network.  Brute force over the band, which beats pruning when the band
  holds a small share of the codebook.
* `hard_lean`: hard decisions, syndrome and information bits as XORs of per-position
  contributions over contiguous x, then one coset-leader lookup per pixel.

* `soft_band_fold` (column-linear codes, a band): folded Walsh-Hadamard transforms of 64-column
  blocks for LANES pixels at a time, top-3 on 32-bit keys with an exact 64-bit redo of the rare
  pixels whose costs exceed them.

Integer ranges: |y_i| <= Y_CLIP = 2**24, so costs (<= n * 2**24) fit int32 for
n <= 64 (the binary limit) and keys (cost << IDX_BITS | column) fit int64.

Per-pixel constants: for integer frames under METRIC_ML without inverse frames the two logs of
`_pixel_params` come from a table over the raw levels (`log_levels`, the same log); the
lane-parallel sample loop of `_block_llr` has an unswitched copy for that metric.  Both give the
same values bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

METRIC_ML = 0
METRIC_NORMALIZED = 1
METRIC_HARD = 2

#: Bits of a top-3 key that hold the column; the cost sits above them.
IDX_BITS = 16
IDX_MASK = (1 << IDX_BITS) - 1
NO_KEY = np.int64(1) << np.int64(62)
#: Largest |quantised per-sample cost difference|.
Y_CLIP = 1 << 24

_U6 = np.uint64(6)
_U63 = np.uint64(63)
_U255 = np.uint64(255)
_U1 = np.uint64(1)
_U0 = np.uint64(0)


@njit(cache=True, inline="always")
def _pack(m, comp, nbytes):
    out = np.int64(0)
    for g in range(nbytes):
        out |= comp[g, np.int64((m >> np.uint64(8 * g)) & _U255)]
    return out


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
def _pixel_params(a, b, has_inv, metric, sr2, ss2):
    """Per-pixel constants of `_sample_costs`: (1/v_white, 1/v_black, log terms la, lb,
    1/(v_white + v_black), 1/(white - black)); reciprocals so the per-sample work has no
    division."""
    va = sr2 + ss2 * a
    vb = sr2 + ss2 * b
    la = 0.0
    lb = 0.0
    if metric == METRIC_ML and not has_inv:
        la = np.log(va)
        lb = np.log(vb)
        m = min(la, lb)
        la -= m
        lb -= m
    return 1.0 / va, 1.0 / vb, la, lb, 1.0 / (va + vb), 1.0 / (a - b)


@njit(cache=True, inline="always")
def _pixel_params_tab(a, b, log_va, log_vb, sr2, ss2):
    """`_pixel_params` for METRIC_ML without inverse frames with the two logs given (from
    `log_levels`): the same values, bit for bit."""
    va = sr2 + ss2 * a
    vb = sr2 + ss2 * b
    m = min(log_va, log_vb)
    return 1.0 / va, 1.0 / vb, log_va - m, log_vb - m, 1.0 / (va + vb), 1.0 / (a - b)


@njit(cache=True)
def log_levels(levels, scale, sr2, ss2):
    """(levels,) float64 table of log(sr2 + ss2 * (v * scale)) for raw values v = 0..levels-1:
    the logs `_pixel_params` takes of a pixel's white / black variance (METRIC_ML without
    inverse frames), so integer frames pay 2 logs per raw level instead of per pixel.  Computed
    here (not in numpy) so that it is the same log, bit for bit."""
    out = np.empty(levels, np.float64)
    for v in range(levels):
        out[v] = np.log(sr2 + ss2 * (v * scale))
    return out


@njit(cache=True, inline="always")
def _sample_costs(r, ri, a, b, has_inv, metric, iva, ivb, la, lb, ivs, idiff):
    """(e0, e1) of one binary sample (see module docstring); constants from `_pixel_params`."""
    d = a - b
    if metric == METRIC_ML:
        if has_inv:
            s = r - ri
            e1 = (s - d) * (s - d) * ivs
            e0 = (s + d) * (s + d) * ivs
        else:
            e1 = (r - a) * (r - a) * iva + la
            e0 = (r - b) * (r - b) * ivb + lb
    elif metric == METRIC_NORMALIZED:
        if has_inv:
            x = 0.5 * ((r - ri) * idiff + 1.0)
        else:
            x = (r - b) * idiff
        e1 = (x - 1.0) * (x - 1.0)
        e0 = x * x
    else:
        if has_inv:
            one = r > ri
        else:
            one = r > 0.5 * (a + b)
        e1 = 0.0 if one else 1.0
        e0 = 1.0 if one else 0.0
    return e0, e1


@njit(cache=True, inline="always")
def _quantise(e0, e1, q_scale):
    """round(q_scale * (e0 - e1)) clipped to [-Y_CLIP, Y_CLIP], as int64 (clipped as a float)."""
    t = np.round((e0 - e1) * q_scale)
    t = min(max(t, -float(Y_CLIP)), float(Y_CLIP))
    return np.int64(t)


@njit(cache=True, inline="always")
def _pixel_llr(frames, inverse, has_inv, yy, xx, n, scale, a, b, metric, sr2, ss2, q_scale, y, w):
    """Fill y (quantised e0 - e1) and w = |y| for one pixel; return (hard mask h, dmin)."""
    iva, ivb, la, lb, ivs, idiff = _pixel_params(a, b, has_inv, metric, sr2, ss2)
    h = _U0
    dmin = 0.0
    for i in range(n):
        r = frames[i, yy, xx] * scale
        ri = 0.0
        if has_inv:
            ri = inverse[i, yy, xx] * scale
        e0, e1 = _sample_costs(r, ri, a, b, has_inv, metric, iva, ivb, la, lb, ivs, idiff)
        dmin += min(e0, e1)
        t = _quantise(e0, e1, q_scale)
        y[i] = t
        if t > 0:
            h |= _U1 << np.uint64(i)
            w[i] = t
        else:
            w[i] = -t
    return h, dmin


@njit(cache=True, inline="always")
def _subset_tables(v, n, ngroups, tab):
    """tab[g, p] = sum of v over the bits of p at positions 6g.. (v = 0 beyond n)."""
    for g in range(ngroups):
        tab[g, 0] = 0
        for bit in range(6):
            pos = 6 * g + bit
            val = v[pos] if pos < n else 0
            half = 1 << bit
            for p in range(half):
                tab[g, half | p] = tab[g, p] + val


@njit(cache=True, inline="always")
def _cost_of(diff, tab, ngroups):
    s = tab[0, np.int64(diff & _U63)]
    for g in range(1, ngroups):
        s += tab[g, np.int64((diff >> np.uint64(6 * g)) & _U63)]
    return s


@njit(cache=True, inline="always")
def _sort_small(a, m):
    for i in range(1, m):
        t = a[i]
        j = i - 1
        while j >= 0 and a[j] > t:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = t


@njit(cache=True, inline="always")
def _write(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale):
    keys = (k1, k2, k3)
    for j in range(3):
        kk = keys[j]
        if kk == NO_KEY:
            out_col[yy, xx, j] = -1
            out_dist[yy, xx, j] = np.inf
        else:
            out_col[yy, xx, j] = np.int32(kk & IDX_MASK)
            out_dist[yy, xx, j] = np.float32(dmin + (kk >> IDX_BITS) / q_scale)
    if k2 == NO_KEY:
        out_conf[yy, xx] = 0.0
    else:
        d1 = dmin + (k1 >> IDX_BITS) / q_scale
        d2 = dmin + (k2 >> IDX_BITS) / q_scale
        out_conf[yy, xx] = np.float32((d2 - d1) / d2) if d2 > 0 else np.float32(0.0)


@njit(cache=True, parallel=True)
def soft_binary(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale,
                masks, comp_info, col_of_info, comp_syn, leader, has_leader, linear,
                diff_masks, diff_info, class_start, sub_start, sub_p0, class_sub,
                ncols, use_band, min_d, max_d, stripe, brute_max,
                out_col, out_dist, out_conf, out_stats):
    """Exact top-3 soft decoding of a binary code for every pixel.

    frames, inverse: (n, H, W); white, black: (H, W); outputs: out_col (H, W, 3) int32,
    out_dist (H, W, 3) float32, out_conf (H, W) float32; out_stats (H, 2) int64 counts per row
    of [pixels that took the brute-force path, codewords whose cost was evaluated].
    linear=False or a band of at most brute_max columns: brute force over the candidates
    (still exact); otherwise the pruned enumeration of the module docstring.
    """
    n, height, width = frames.shape
    ngroups = (n + 5) // 6
    nbytes_info = comp_info.shape[0]
    nbytes_syn = comp_syn.shape[0]
    n_out = n - min(n, 6)
    popc = np.zeros(64, np.int64)
    for p in range(64):
        c = 0
        for bit in range(6):
            c += (p >> bit) & 1
        popc[p] = c
    for yy in prange(height):
        y = np.zeros(n, np.int64)
        w = np.zeros(n, np.int64)
        v = np.zeros(max(n, 6 * ngroups), np.int64)
        sv = np.zeros(n, np.int64)
        lbc = np.zeros(n + 2, np.int64)
        rout = np.zeros(n_out + 1, np.int64)
        tab = np.zeros((ngroups, 64), np.int64)
        brute_pixels = 0
        evaluated = 0
        for xx in range(width):
            a = white[yy, xx] * scale
            b = black[yy, xx] * scale
            lo, hi = _band(xx, use_band, min_d, max_d, stripe, ncols)
            if not (a > b) or lo > hi:
                for j in range(3):
                    out_col[yy, xx, j] = -1
                    out_dist[yy, xx, j] = np.inf
                out_conf[yy, xx] = 0.0
                continue
            h, dmin = _pixel_llr(frames, inverse, has_inv, yy, xx, n, scale, a, b, metric,
                                 sr2, ss2, q_scale, y, w)
            # reference codeword
            if linear:
                hinfo = _pack(h, comp_info, nbytes_info)
                enc = masks[col_of_info[hinfo]]
                if has_leader:
                    syn = _pack(h ^ enc, comp_syn, nbytes_syn)
                    cref = h ^ leader[syn]
                else:
                    cref = enc
            else:
                cref = h
            eref = cref ^ h
            cost_ref = np.int64(0)
            for i in range(n):
                if (eref >> np.uint64(i)) & _U1:
                    v[i] = -w[i]
                    cost_ref += w[i]
                else:
                    v[i] = w[i]
            _subset_tables(v, n, ngroups, tab)
            k1 = NO_KEY
            k2 = NO_KEY
            k3 = NO_KEY
            if (not linear) or (use_band and hi - lo + 1 <= brute_max):
                brute_pixels += 1
                evaluated += hi - lo + 1
                for j in range(lo, hi + 1):
                    cost = cost_ref + _cost_of(masks[j] ^ cref, tab, ngroups)
                    if cost <= (k3 >> IDX_BITS):
                        k1, k2, k3 = _insert((cost << IDX_BITS) | j, k1, k2, k3)
            else:
                # bounds: sorted v (all positions) and sorted v outside group 0
                for i in range(n):
                    sv[i] = v[i]
                _sort_small(sv, n)
                acc = np.int64(0)
                lbc[0] = 0
                for t in range(1, n + 1):
                    acc += sv[t - 1]
                    lbc[t] = acc
                lbc[n + 1] = NO_KEY
                for t in range(n - 1, -1, -1):
                    if lbc[t + 1] < lbc[t]:
                        lbc[t] = lbc[t + 1]
                for i in range(n_out):
                    sv[i] = v[6 + i]
                _sort_small(sv, n_out)
                rout[0] = 0
                for j in range(1, n_out + 1):
                    rout[j] = rout[j - 1] + sv[j - 1]
                ref_info = _pack(cref, comp_info, nbytes_info)
                ref_col = col_of_info[ref_info]
                evaluated += 1
                if ref_col >= lo and ref_col <= hi:
                    k1 = (cost_ref << IDX_BITS) | ref_col
                if has_leader and n > 0:
                    # Chase-style seeds: flip the least reliable positions of h and decode,
                    # so the third-best bound is tight before the enumeration starts.
                    p1 = 0
                    for i in range(n):
                        if w[i] < w[p1]:
                            p1 = i
                    p2 = -1
                    for i in range(n):
                        if i != p1 and (p2 < 0 or w[i] < w[p2]):
                            p2 = i
                    p3 = -1
                    for i in range(n):
                        if i != p1 and i != p2 and (p3 < 0 or w[i] < w[p3]):
                            p3 = i
                    for trial in range(1, 8):
                        f = _U0
                        if trial & 1:
                            f |= _U1 << np.uint64(p1)
                        if (trial & 2) and p2 >= 0:
                            f |= _U1 << np.uint64(p2)
                        if (trial & 4) and p3 >= 0:
                            f |= _U1 << np.uint64(p3)
                        hh = h ^ f
                        enc2 = masks[col_of_info[_pack(hh, comp_info, nbytes_info)]]
                        c2 = hh ^ leader[_pack(hh ^ enc2, comp_syn, nbytes_syn)]
                        d2 = c2 ^ cref
                        if d2 == _U0:
                            continue
                        cost = cost_ref + _cost_of(d2, tab, ngroups)
                        evaluated += 1
                        if cost > (k3 >> IDX_BITS):
                            continue
                        col = col_of_info[_pack(c2, comp_info, nbytes_info)]
                        if col < lo or col > hi:
                            continue
                        key = (cost << IDX_BITS) | col
                        if key != k1 and key != k2 and key != k3:
                            k1, k2, k3 = _insert(key, k1, k2, k3)
                for t in range(1, n + 1):
                    if class_start[t] == class_start[t + 1]:
                        continue
                    if k3 != NO_KEY and cost_ref + lbc[t] > (k3 >> IDX_BITS):
                        break
                    for s in range(class_sub[t], class_sub[t + 1]):
                        p0 = sub_p0[s]
                        t0 = tab[0, p0]
                        if k3 != NO_KEY and cost_ref + t0 + rout[t - popc[p0]] > (k3 >> IDX_BITS):
                            continue
                        for e in range(sub_start[s], sub_start[s + 1]):
                            d = diff_masks[e]
                            cost = cost_ref + t0
                            for g in range(1, ngroups):
                                cost += tab[g, np.int64((d >> np.uint64(6 * g)) & _U63)]
                            evaluated += 1
                            if cost > (k3 >> IDX_BITS):
                                continue
                            col = col_of_info[ref_info ^ diff_info[e]]
                            if col < lo or col > hi:
                                continue
                            key = (cost << IDX_BITS) | col
                            if key != k1 and key != k2 and key != k3:
                                k1, k2, k3 = _insert(key, k1, k2, k3)
            _write(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale)
        out_stats[yy, 0] = brute_pixels
        out_stats[yy, 1] = evaluated


@njit(cache=True, parallel=True)
def soft_nary(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, q,
              codebook, ncols, use_band, min_d, max_d, stripe, out_col, out_dist, out_conf):
    """Exact top-3 over the codebook rows in the band for an N-ary code (q levels).

    Symbol s has level mu_s = black + (white - black) * s / (q - 1) (with inverse frames the
    difference r - r_inv has mean (white - black) * (2 s / (q - 1) - 1)); per-sample costs as
    in the module docstring (ML: Gaussian -2 log-likelihood; normalised: (x - s/(q-1))**2;
    hard: 0 for the nearest level, 1 otherwise).  Brute force over the candidate rows.
    """
    n, height, width = frames.shape
    for yy in prange(height):
        e = np.zeros((n, q), np.float64)
        eq = np.zeros((n, q), np.int64)
        for xx in range(width):
            a = white[yy, xx] * scale
            b = black[yy, xx] * scale
            lo, hi = _band(xx, use_band, min_d, max_d, stripe, ncols)
            if not (a > b) or lo > hi:
                for j in range(3):
                    out_col[yy, xx, j] = -1
                    out_dist[yy, xx, j] = np.inf
                out_conf[yy, xx] = 0.0
                continue
            d = a - b
            dmin = 0.0
            for i in range(n):
                r = frames[i, yy, xx] * scale
                ri = inverse[i, yy, xx] * scale if has_inv else 0.0
                best = np.inf
                for s in range(q):
                    frac = s / (q - 1)
                    if has_inv:
                        mu = d * (2.0 * frac - 1.0)
                        obs = r - ri
                        var = 2.0 * sr2 + ss2 * (b + d * frac + b + d * (1.0 - frac))
                    else:
                        mu = b + d * frac
                        obs = r
                        var = sr2 + ss2 * mu
                    if metric == METRIC_ML:
                        val = (obs - mu) * (obs - mu) / var + np.log(var)
                    else:
                        x = (obs - mu) / d
                        val = x * x
                    e[i, s] = val
                    if val < best:
                        best = val
                if metric == METRIC_HARD:
                    arg = 0
                    for s in range(q):
                        if e[i, s] == best:
                            arg = s
                            break
                    for s in range(q):
                        e[i, s] = 0.0 if s == arg else 1.0
                    best = 0.0
                dmin += best
                for s in range(q):
                    t = np.int64(np.round((e[i, s] - best) * q_scale))
                    eq[i, s] = min(t, Y_CLIP)
            k1 = NO_KEY
            k2 = NO_KEY
            k3 = NO_KEY
            for j in range(lo, hi + 1):
                cost = np.int64(0)
                for i in range(n):
                    cost += eq[i, codebook[j, i]]
                if cost <= (k3 >> IDX_BITS):
                    k1, k2, k3 = _insert((cost << IDX_BITS) | j, k1, k2, k3)
            _write(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale)


# ---------------------------------------------------------------------------------------------
# Lane-parallel kernels (the fast paths; see `soft_lanes`, `soft_band`, `hard_lean`).
# ---------------------------------------------------------------------------------------------

#: Pixels decoded together by `soft_lanes` (consecutive x of one row); a compile-time constant
#: so that every loop over lanes has a fixed trip count and vectorises.
LANES = 64
#: Width of the top-3 min/max network of `soft_band` (columns per step).
BAND_NET = 16
#: Larger than any cost bound (an empty weight class).
_NO_BOUND = np.int64(1) << np.int64(62)
#: Band limits of the lanes past the right image edge in `soft_band_fold` (beyond any column).
_FAR_COL = 1 << 30


@njit(cache=True, inline="always")
def _block_llr(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab, yy,
               x0, use_band, min_d, max_d, stripe, ncols, R, RI, PA, Y, dmin, active, lo, hi):
    """Quantised cost differences of the LANES pixels x0.. of row yy, lane-parallel.

    ltab: `log_levels` table (empty: the logs of `_pixel_params` are computed per pixel).

    Fills Y (n, LANES) int32 (= `_pixel_llr`'s y, bit for bit), dmin, active (white > black,
    inside the image, non-empty band [lo, hi]); inactive lanes get finite dummy values.
    Scratch: R, RI (n, LANES) float64, PA (8, LANES) float64.  Returns the active lane count.
    """
    n, height, width = frames.shape
    L = LANES
    nact = 0
    for l in range(L):
        xx = x0 + l
        act = False
        a = 1.0
        b = 0.0
        if xx < width:
            a = white[yy, xx] * scale
            b = black[yy, xx] * scale
            llo, lhi = _band(xx, use_band, min_d, max_d, stripe, ncols)
            lo[l] = llo
            hi[l] = lhi
            act = (a > b) and (llo <= lhi)
        if not act:
            a = 1.0
            b = 0.0
        active[l] = act
        nact += np.int64(act)
        if act and ltab.shape[0] > 0:
            iva, ivb, la, lb, ivs, idiff = _pixel_params_tab(a, b, ltab[np.int64(white[yy, xx])],
                                                             ltab[np.int64(black[yy, xx])], sr2, ss2)
        else:
            iva, ivb, la, lb, ivs, idiff = _pixel_params(a, b, has_inv, metric, sr2, ss2)
        PA[0, l] = a
        PA[1, l] = b
        PA[2, l] = iva
        PA[3, l] = ivb
        PA[4, l] = la
        PA[5, l] = lb
        PA[6, l] = ivs
        PA[7, l] = idiff
        dmin[l] = 0.0
    full = x0 + L <= width
    if full and metric == METRIC_ML and not has_inv:
        # the common case, unswitched: the same arithmetic as `_sample_costs`, bit for bit
        a = PA[0]
        b = PA[1]
        iva = PA[2]
        ivb = PA[3]
        la = PA[4]
        lb = PA[5]
        for i in range(n):
            row = frames[i, yy, x0:x0 + L]
            yr = Y[i]
            for l in range(L):
                r = row[l] * scale
                e1 = (r - a[l]) * (r - a[l]) * iva[l] + la[l]
                e0 = (r - b[l]) * (r - b[l]) * ivb[l] + lb[l]
                dmin[l] += min(e0, e1)
                yr[l] = np.int32(_quantise(e0, e1, q_scale))
        return nact
    if full:
        for i in range(n):
            row = frames[i, yy, x0:x0 + L]
            for l in range(L):
                R[i, l] = row[l] * scale
            if has_inv:
                rowi = inverse[i, yy, x0:x0 + L]
                for l in range(L):
                    RI[i, l] = rowi[l] * scale
    else:
        for i in range(n):
            for l in range(L):
                xx = min(x0 + l, width - 1)
                R[i, l] = frames[i, yy, xx] * scale
                if has_inv:
                    RI[i, l] = inverse[i, yy, xx] * scale
    for i in range(n):
        for l in range(L):
            e0, e1 = _sample_costs(R[i, l], RI[i, l], PA[0, l], PA[1, l], has_inv, metric,
                                   PA[2, l], PA[3, l], PA[4, l], PA[5, l], PA[6, l], PA[7, l])
            dmin[l] += min(e0, e1)
            Y[i, l] = np.int32(_quantise(e0, e1, q_scale))
    return nact


@njit(cache=True, inline="always")
def _eval_class(V, base, colref, lo, hi, k1, k2, k3, acc, dpos, dcol, e_start, e_stop, p_start, t):
    """Top-3 update of LANES lanes with every codeword c_ref ^ D, D in dcol[e_start:e_stop].

    D has weight t and positions dpos[p_start + (e - e_start) * t ...]; its cost in lane l is
    base[l] + sum of V[pos, l]; its column colref[l] ^ dcol[e].  Keys are
    (cost << IDX_BITS) | column; columns outside [lo[l], hi[l]] are skipped (a compare and a
    select per lane: cheaper to always do than to compile a second copy).
    """
    p = p_start
    t4 = t - t % 4
    for e in range(e_start, e_stop):
        # sums of 4 rows per pass: straight-line loop bodies over the lanes vectorise
        if t >= 4:
            r0 = dpos[p]
            r1 = dpos[p + 1]
            r2 = dpos[p + 2]
            r3 = dpos[p + 3]
            for l in range(LANES):
                acc[l] = base[l] + V[r0, l] + V[r1, l] + V[r2, l] + V[r3, l]
        else:
            for l in range(LANES):
                acc[l] = base[l]
        for j in range(4, t4, 4):
            r0 = dpos[p + j]
            r1 = dpos[p + j + 1]
            r2 = dpos[p + j + 2]
            r3 = dpos[p + j + 3]
            for l in range(LANES):
                acc[l] += V[r0, l] + V[r1, l] + V[r2, l] + V[r3, l]
        for j in range(t4, t):
            r0 = dpos[p + j]
            for l in range(LANES):
                acc[l] += V[r0, l]
        p += t
        md = dcol[e]
        for l in range(LANES):
            col = colref[l] ^ md
            key = (np.int64(acc[l]) << IDX_BITS) | np.int64(col)
            ok = (col >= lo[l]) & (col <= hi[l])
            key = key if ok else NO_KEY
            a = k1[l]
            k1[l] = min(a, key)
            key = max(a, key)
            a = k2[l]
            k2[l] = min(a, key)
            key = max(a, key)
            k3[l] = min(k3[l], key)


@njit(cache=True, inline="always")
def _class_bounds(V, SV, run, lb, n, cls_weight, nclass):
    """lb[c, l] = min over classes c' >= c of (sum of the cls_weight[c'] smallest V of
    lane l): a lower bound of cost - base for every codeword c_ref ^ D, |D| >= cls_weight[c].
    lb[nclass, l] = _NO_BOUND.  Sorts each lane (odd-even transposition, lane-wise)."""
    for i in range(n):
        for l in range(LANES):
            SV[i, l] = V[i, l]
    for ps in range(n):
        for i in range(ps & 1, n - 1, 2):
            for l in range(LANES):
                a = SV[i, l]
                b = SV[i + 1, l]
                SV[i, l] = min(a, b)
                SV[i + 1, l] = max(a, b)
    for l in range(LANES):
        run[l] = 0
        lb[nclass, l] = _NO_BOUND
    c = 0
    for t in range(1, n + 1):
        for l in range(LANES):
            run[l] += SV[t - 1, l]
        if c < nclass and cls_weight[c] == t:
            for l in range(LANES):
                lb[c, l] = run[l]
            c += 1
    for c in range(nclass - 1, -1, -1):
        for l in range(LANES):
            lb[c, l] = min(lb[c, l], lb[c + 1, l])


@njit(cache=True, inline="always")
def _write_none(out_col, out_dist, out_conf, yy, xx):
    for j in range(3):
        out_col[yy, xx, j] = -1
        out_dist[yy, xx, j] = np.inf
    out_conf[yy, xx] = 0.0


@njit(cache=True)
def _run_classes(V, lb, base, colref, lo, hi, k1, k2, k3, acc, nlanes, c_first, c_stop, nclass,
                 cls_weight, cls_start, cls_pstart, dpos, dcol):
    """Evaluate classes c_first, c_first + 1, ... (before c_stop) for a whole lane block, until
    the bounds lb prove the top-3 of lanes 0..nlanes-1; return the codeword evaluations per lane.
    (Not inlined: one compiled copy of the class loop serves both stages.)"""
    evaluated = 0
    c = c_first
    while c < c_stop:
        _eval_class(V, base, colref, lo, hi, k1, k2, k3, acc, dpos, dcol, cls_start[c],
                    cls_start[c + 1], cls_pstart[c], cls_weight[c])
        evaluated += cls_start[c + 1] - cls_start[c]
        c += 1
        if c >= c_stop:
            break
        done = True
        for l in range(nlanes):
            if (k3[l] >> IDX_BITS) >= base[l] + lb[c, l]:
                done = False
        if done:
            break
    return evaluated


@njit(cache=True)
def _lanes_row(yy, frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
               masks, syn_col, col_bit, leader, leader_col, has_leader,
               cls_weight, cls_start, cls_pstart, dpos, dcol,
               ncols, use_band, min_d, max_d, stripe, out_col, out_dist, out_conf, out_stats):
    """Row yy of `soft_lanes` (a plain function: keeps the parallel kernel small to compile)."""
    n, height, width = frames.shape
    nclass = cls_weight.shape[0]
    L = LANES
    R = np.zeros((n, L), np.float64)
    RI = np.zeros((n, L), np.float64)
    PA = np.zeros((8, L), np.float64)
    Y = np.zeros((n, L), np.int32)
    SYN = np.zeros(L, np.int64)
    COLH = np.zeros(L, np.int64)
    HM = np.zeros(L, np.int64)
    E = np.zeros(L, np.int64)
    V = np.zeros((n, L), np.int32)
    SV = np.zeros((n, L), np.int32)
    lb = np.zeros((nclass + 1, L), np.int64)
    run = np.zeros(L, np.int64)
    acc = np.zeros(L, np.int32)
    base = np.zeros(L, np.int32)
    colref = np.zeros(L, np.int32)
    lo = np.zeros(L, np.int32)
    hi = np.zeros(L, np.int32)
    k1 = np.empty(L, np.int64)
    k2 = np.empty(L, np.int64)
    k3 = np.empty(L, np.int64)
    dmin = np.zeros(L, np.float64)
    active = np.zeros(L, np.bool_)
    # pending block (lanes that need the heavier classes)
    PV = np.zeros((n, L), np.int32)
    Plb = np.zeros((nclass + 1, L), np.int64)
    Pbase = np.zeros(L, np.int32)
    Pcolref = np.zeros(L, np.int32)
    Plo = np.zeros(L, np.int32)
    Phi = np.zeros(L, np.int32)
    Pk1 = np.empty(L, np.int64)
    Pk2 = np.empty(L, np.int64)
    Pk3 = np.empty(L, np.int64)
    Pdmin = np.zeros(L, np.float64)
    Px = np.zeros(L, np.int64)
    npend = 0
    n_second = 0
    evaluated = 0
    blocks_second = 0
    blocks = 0
    pend_blocks = 0
    for x0 in range(0, width, L):
        blocks += 1
        nact = _block_llr(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2,
                          q_scale, ltab, yy, x0, use_band, min_d, max_d, stripe, ncols, R, RI, PA,
                          Y, dmin, active, lo, hi)
        # hard decision -> syndrome and column of h, lane-parallel
        for l in range(L):
            SYN[l] = 0
            COLH[l] = 0
            HM[l] = 0
        for i in range(n):
            sc = syn_col[i]
            cbit = col_bit[i]
            ibit = np.int64(1) << i
            for l in range(L):
                m = -np.int64(Y[i, l] > 0)
                SYN[l] ^= sc & m
                COLH[l] ^= cbit & m
                HM[l] |= ibit & m
        for l in range(L):
            if has_leader:
                E[l] = np.int64(leader[SYN[l]])
                colref[l] = np.int32(COLH[l] ^ leader_col[SYN[l]])
            else:
                E[l] = HM[l] ^ np.int64(masks[COLH[l]])
                colref[l] = np.int32(COLH[l])
            base[l] = 0
        for i in range(n):
            for l in range(L):
                yv = Y[i, l]
                wv = max(yv, -yv)
                bit = (E[l] >> i) & 1
                V[i, l] = wv - 2 * wv * np.int32(bit)
                base[l] += wv * np.int32(bit)
        if nact == 0:
            for l in range(L):
                if x0 + l < width:
                    _write_none(out_col, out_dist, out_conf, yy, x0 + l)
            continue
        for l in range(L):
            cr = colref[l]
            ok = (cr >= lo[l]) & (cr <= hi[l])
            k1[l] = ((np.int64(base[l]) << IDX_BITS) | np.int64(cr)) if ok else NO_KEY
            k2[l] = NO_KEY
            k3[l] = NO_KEY
        evaluated += nact
        if nclass > 0:
            evaluated += nact * _run_classes(V, lb, base, colref, lo, hi, k1, k2, k3, acc, L, 0,
                                             1, nclass, cls_weight, cls_start, cls_pstart,
                                             dpos, dcol)
            _class_bounds(V, SV, run, lb, n, cls_weight, nclass)
        else:
            for l in range(L):
                lb[0, l] = _NO_BOUND
        any_second = False
        for l in range(L):
            xx = x0 + l
            if xx >= width:
                continue
            if not active[l]:
                _write_none(out_col, out_dist, out_conf, yy, xx)
                continue
            cidx = 1 if nclass > 0 else 0
            if (k3[l] >> IDX_BITS) < base[l] + lb[cidx, l]:
                _write(out_col, out_dist, out_conf, yy, xx, k1[l], k2[l], k3[l], dmin[l], q_scale)
                continue
            # move lane l into the pending block
            any_second = True
            n_second += 1
            p = npend
            for i in range(n):
                PV[i, p] = V[i, l]
            for c in range(nclass + 1):
                Plb[c, p] = lb[c, l]
            Pbase[p] = base[l]
            Pcolref[p] = colref[l]
            Plo[p] = lo[l]
            Phi[p] = hi[l]
            Pk1[p] = k1[l]
            Pk2[p] = k2[l]
            Pk3[p] = k3[l]
            Pdmin[p] = dmin[l]
            Px[p] = xx
            npend += 1
            if npend == L:
                evaluated += npend * _run_classes(PV, Plb, Pbase, Pcolref, Plo, Phi, Pk1, Pk2, Pk3,
                                                  acc, npend, 1, nclass, nclass, cls_weight,
                                                  cls_start, cls_pstart, dpos, dcol)
                for q in range(npend):
                    _write(out_col, out_dist, out_conf, yy, Px[q], Pk1[q], Pk2[q], Pk3[q],
                           Pdmin[q], q_scale)
                npend = 0
                pend_blocks += 1
        if any_second:
            blocks_second += 1
    if npend > 0:
        for p in range(npend, L):
            for i in range(n):
                PV[i, p] = 0
            Pbase[p] = 0
            Pcolref[p] = 0
        evaluated += npend * _run_classes(PV, Plb, Pbase, Pcolref, Plo, Phi, Pk1, Pk2, Pk3, acc,
                                          npend, 1, nclass, nclass, cls_weight, cls_start,
                                          cls_pstart, dpos, dcol)
        for q in range(npend):
            _write(out_col, out_dist, out_conf, yy, Px[q], Pk1[q], Pk2[q], Pk3[q], Pdmin[q],
                   q_scale)
        pend_blocks += 1
    out_stats[yy, 0] = n_second
    out_stats[yy, 1] = evaluated
    out_stats[yy, 2] = blocks_second
    out_stats[yy, 3] = blocks
    out_stats[yy, 4] = pend_blocks


@njit(cache=True, parallel=True)
def soft_lanes(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
               masks, syn_col, col_bit, leader, leader_col, has_leader,
               cls_weight, cls_start, cls_pstart, dpos, dcol,
               ncols, use_band, min_d, max_d, stripe, out_col, out_dist, out_conf, out_stats):
    """Exact top-3 soft decoding of a column-linear binary code, LANES pixels at a time.

    Per pixel: y, h, w as in the module docstring; c_ref = nearest codeword of h (coset
    leader e of the syndrome of h, else the re-encoded information bits), base = cost(c_ref),
    V_i = +w_i where c_ref agrees with h, -w_i where not (stored V[i, lane]).  Every
    other codeword is c_ref ^ D with cost base + sum_{i in D} V_i and column col(c_ref) ^ col(D).
    Stage 1 evaluates D = 0 and the lightest weight class for the whole block; a lane is done
    when its third-best cost is below base + (sum of the t smallest V) for every heavier class
    weight t.  Unfinished lanes are moved into a pending block of the row; full (or, at the end
    of the row, partial) pending blocks evaluate the next classes until every lane is done.
    Ties go to the lower column (keys (cost << IDX_BITS) | column).

    Columns outside a lane's candidates [lo, hi] (band, ncols < size) are dropped; the bounds
    stay valid, so the result is exact within the candidates.
    out_stats (H, 5) int64 per row: pixels that needed the second class, codeword evaluations,
    stage-1 blocks with at least one such pixel, stage-1 blocks, pending blocks.
    """
    height = frames.shape[1]
    for yy in prange(height):
        _lanes_row(yy, frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
                   masks, syn_col, col_bit, leader, leader_col, has_leader,
                   cls_weight, cls_start, cls_pstart, dpos, dcol,
                   ncols, use_band, min_d, max_d, stripe, out_col, out_dist, out_conf, out_stats)


@njit(cache=True)
def _band_row(yy, frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
              masks_t, ncols, min_d, max_d, stripe, out_col, out_dist, out_conf, out_stats):
    """Row yy of `soft_band` (a plain function: keeps the parallel kernel small to compile)."""
    n, height, width = frames.shape
    L = LANES
    R = np.zeros((n, L), np.float64)
    RI = np.zeros((n, L), np.float64)
    PA = np.zeros((8, L), np.float64)
    Y = np.zeros((n, L), np.int32)
    dmin = np.zeros(L, np.float64)
    active = np.zeros(L, np.bool_)
    lo = np.zeros(L, np.int32)
    hi = np.zeros(L, np.int32)
    acc = np.zeros(ncols + BAND_NET, np.int32)
    K1 = np.empty(BAND_NET, np.int64)
    K2 = np.empty(BAND_NET, np.int64)
    K3 = np.empty(BAND_NET, np.int64)
    pixels = 0
    evaluated = 0
    n4 = n - n % 4
    for x0 in range(0, width, L):
        _block_llr(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale,
                   ltab, yy, x0, True, min_d, max_d, stripe, ncols, R, RI, PA, Y, dmin, active,
                   lo, hi)
        for ln in range(L):
            xx = x0 + ln
            if xx >= width:
                break
            if not active[ln]:
                _write_none(out_col, out_dist, out_conf, yy, xx)
                continue
            clo = lo[ln]
            chi = hi[ln]
            c0 = np.int32(0)
            for i in range(n):
                c0 += max(Y[i, ln], 0)
            nb = chi - clo + 1
            pixels += 1
            evaluated += nb
            for c in range(nb):
                acc[c] = c0
            for i in range(0, n4, 4):  # 4 rows per pass: fewer loads / stores of acc
                y0 = Y[i, ln]
                y1 = Y[i + 1, ln]
                y2 = Y[i + 2, ln]
                y3 = Y[i + 3, ln]
                r0 = masks_t[i, clo:chi + 1]
                r1 = masks_t[i + 1, clo:chi + 1]
                r2 = masks_t[i + 2, clo:chi + 1]
                r3 = masks_t[i + 3, clo:chi + 1]
                for c in range(nb):
                    acc[c] -= (r0[c] & y0) + (r1[c] & y1) + (r2[c] & y2) + (r3[c] & y3)
            for i in range(n4, n):
                yi = Y[i, ln]
                row = masks_t[i, clo:chi + 1]
                for c in range(nb):
                    acc[c] -= row[c] & yi
            for l in range(BAND_NET):
                K1[l] = NO_KEY
                K2[l] = NO_KEY
                K3[l] = NO_KEY
            for cb in range(0, nb, BAND_NET):
                for l in range(BAND_NET):
                    c = cb + l
                    key = (np.int64(acc[c]) << IDX_BITS) | np.int64(clo + c)
                    key = key if c < nb else NO_KEY
                    t = K1[l]
                    K1[l] = min(t, key)
                    key = max(t, key)
                    t = K2[l]
                    K2[l] = min(t, key)
                    key = max(t, key)
                    K3[l] = min(K3[l], key)
            k1 = NO_KEY
            k2 = NO_KEY
            k3 = NO_KEY
            for l in range(BAND_NET):
                if K1[l] < k3:
                    k1, k2, k3 = _insert(K1[l], k1, k2, k3)
                    if K2[l] < k3:
                        k1, k2, k3 = _insert(K2[l], k1, k2, k3)
                        if K3[l] < k3:
                            k1, k2, k3 = _insert(K3[l], k1, k2, k3)
            _write(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin[ln], q_scale)
    out_stats[yy, 0] = pixels
    out_stats[yy, 1] = evaluated


@njit(cache=True, parallel=True)
def soft_band(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
              masks_t, ncols, min_d, max_d, stripe, out_col, out_dist, out_conf, out_stats):
    """Exact top-3 soft decoding of any binary code within a disparity band, by scanning the
    band: cost(c) = C0 - sum_i (masks_t[i, c] & y_i) with C0 = sum_i max(y_i, 0) (the cost of
    the all-zero word; masks_t is 0 / -1), a loop over contiguous candidate columns, then a
    lane-wise top-3 network over BAND_NET columns at a time.  out_stats (H, 2): decoded pixels,
    candidate evaluations."""
    height = frames.shape[1]
    for yy in prange(height):
        _band_row(yy, frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
                  masks_t, ncols, min_d, max_d, stripe, out_col, out_dist, out_conf, out_stats)


@njit(cache=True, parallel=True)
def hard_lean(frames, inverse, has_inv, white, black, syn_col, info_bit, leader_info, leader_wt,
              col_of_info, d_min, ncols, use_band, min_d, max_d, stripe, out_cand, out_dist,
              out_conf):
    """Hard decision + coset-leader decoding of a binary linear code, one image row at a time.

    Bits r > (white + black)/2 (or r > r_inv); the syndrome and information bits of the word are
    XORs of per-position contributions (loops over contiguous x); then per pixel the coset
    leader's information bits and weight give the column and the Hamming distance d1.
    Outputs: out_cand (H, W, 3) int32 [column, -1, -1] (-1 where white <= black or the column
    is outside the projector / band), out_dist (H, W, 3) float32 [d1, inf, inf], out_conf (H, W)
    float32 max(0, d_min - 2 d1) / max(1, d_min - d1) (0 where undecoded).
    """
    n, height, width = frames.shape
    for yy in prange(height):
        syn = np.zeros(width, np.int64)
        inf = np.zeros(width, np.int64)
        thr = np.empty(width, np.float64)
        if not has_inv:
            for xx in range(width):
                thr[xx] = 0.5 * (np.float64(white[yy, xx]) + np.float64(black[yy, xx]))
        for i in range(n):
            sc = syn_col[i]
            ib = info_bit[i]
            if has_inv:
                for xx in range(width):
                    m = -np.int64(frames[i, yy, xx] > inverse[i, yy, xx])
                    syn[xx] ^= sc & m
                    inf[xx] ^= ib & m
            else:
                for xx in range(width):
                    m = -np.int64(np.float64(frames[i, yy, xx]) > thr[xx])
                    syn[xx] ^= sc & m
                    inf[xx] ^= ib & m
        for xx in range(width):
            s = syn[xx]
            col = col_of_info[inf[xx] ^ leader_info[s]]
            d1 = leader_wt[s]
            lo, hi = _band(xx, use_band, min_d, max_d, stripe, ncols)
            if white[yy, xx] > black[yy, xx] and col >= lo and col <= hi:
                out_cand[yy, xx, 0] = col
                out_dist[yy, xx, 0] = np.float32(d1)
                out_conf[yy, xx] = np.float32(max(d_min - 2 * d1, 0) / max(d_min - d1, 1))
            else:
                out_cand[yy, xx, 0] = -1
                out_dist[yy, xx, 0] = np.inf
                out_conf[yy, xx] = 0.0
            out_cand[yy, xx, 1] = -1
            out_cand[yy, xx, 2] = -1
            out_dist[yy, xx, 1] = np.inf
            out_dist[yy, xx, 2] = np.inf


#: Empty slot of the 32-bit top-3 keys of `soft_band_fold` (larger than any uncapped key).
NO_KEY32 = np.int32(0x7FFFFFFF)


@njit(cache=True)
def _band_lane_scan(Y, l, n, clo, chi, masks_t):
    """Exact top-3 keys (64-bit, as `_write` takes them) of lane l over columns clo..chi by the
    band-scan formula cost = C0 - sum_i (masks_t[i, c] & y_i) (`soft_band_fold`'s fallback)."""
    c0 = np.int64(0)
    for i in range(n):
        c0 += max(np.int64(Y[i, l]), 0)
    k1 = NO_KEY
    k2 = NO_KEY
    k3 = NO_KEY
    for c in range(clo, chi + 1):
        cost = c0
        for i in range(n):
            cost -= np.int64(masks_t[i, c]) & np.int64(Y[i, l])
        key = (cost << IDX_BITS) | c
        if key < k3:
            k1, k2, k3 = _insert(key, k1, k2, k3)
    return k1, k2, k3


@njit(cache=True)
def _key64(key32, s, cmin):
    """64-bit key (cost << IDX_BITS | column) of a 32-bit key (cost << s | column - cmin)."""
    if key32 == NO_KEY32:
        return NO_KEY
    return ((np.int64(key32) >> s) << IDX_BITS) | (cmin + (np.int64(key32) & ((1 << s) - 1)))


@njit(cache=True, inline="always")
def _key32(zv, wl, zcap, mult, rc):
    """32-bit top-3 key of `soft_band_fold`: min(z, zcap) * mult | rc with z = zv + wl = 2 cost
    (int32 throughout, so the lane loops stay 8 x int32 wide)."""
    return np.int32(np.int32(min(np.int32(zv + wl), zcap) * mult) | rc)


@njit(cache=True)
def _top3_cols(Z, z0off, m, W, k1, k2, k3, lo, hi, cmin, c_first, c_last, zcap, mult, masked):
    """Top-3 update of every lane with columns c_first..c_last: column c, lane l at
    Z[z0off + c * m + l]; masked: lanes l with c outside [lo[l], hi[l]] skip column c."""
    L = LANES
    c = c_first
    if masked:
        while c + 1 <= c_last:
            zo = z0off + c * m
            z0 = Z[zo:zo + L]
            z1 = Z[zo + m:zo + m + L]
            rc = np.int32(c - cmin)
            ci = np.int32(c)
            ci1 = np.int32(c + 1)
            for l in range(L):
                wl = W[l]
                t1 = k1[l]
                t2 = k2[l]
                t3 = k3[l]
                key = _key32(z0[l], wl, zcap, mult, rc)
                key = key if (ci >= lo[l]) & (ci <= hi[l]) else NO_KEY32
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                key = _key32(z1[l], wl, zcap, mult, rc + 1)
                key = key if (ci1 >= lo[l]) & (ci1 <= hi[l]) else NO_KEY32
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                k1[l] = t1
                k2[l] = t2
                k3[l] = t3
            c += 2
    else:
        while c + 3 <= c_last:
            zo = z0off + c * m
            z0 = Z[zo:zo + L]
            z1 = Z[zo + m:zo + m + L]
            z2 = Z[zo + 2 * m:zo + 2 * m + L]
            z3 = Z[zo + 3 * m:zo + 3 * m + L]
            rc = np.int32(c - cmin)
            for l in range(L):
                wl = W[l]
                t1 = k1[l]
                t2 = k2[l]
                t3 = k3[l]
                key = _key32(z0[l], wl, zcap, mult, rc)
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                key = _key32(z1[l], wl, zcap, mult, rc + 1)
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                key = _key32(z2[l], wl, zcap, mult, rc + 2)
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                key = _key32(z3[l], wl, zcap, mult, rc + 3)
                t3 = min(t3, max(t2, key))
                t2 = min(t2, max(t1, key))
                t1 = min(t1, key)
                k1[l] = t1
                k2[l] = t2
                k3[l] = t3
            c += 4
    while c <= c_last:
        zo = z0off + c * m
        z0 = Z[zo:zo + L]
        rc = np.int32(c - cmin)
        ci = np.int32(c)
        for l in range(L):
            key = _key32(z0[l], W[l], zcap, mult, rc)
            key = key if (ci >= lo[l]) & (ci <= hi[l]) else NO_KEY32
            t1 = k1[l]
            t2 = k2[l]
            k3[l] = min(k3[l], max(t2, key))
            k2[l] = min(t2, max(t1, key))
            k1[l] = min(t1, key)
        c += 1



@njit(cache=True)
def _band_fold_row(yy, frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
                   fold_b, fold_v, fold_sgn, fold_row, fold_usign, masks_t, ncols, min_d, max_d,
                   stripe, out_col, out_dist, out_conf, out_stats):
    """Row yy of `soft_band_fold` (a plain function: keeps the parallel kernel small to compile)."""
    n, height, width = frames.shape
    L = LANES
    R = np.zeros((n, L), np.float64)
    RI = np.zeros((n, L), np.float64)
    PA = np.zeros((8, L), np.float64)
    Y = np.zeros((n, L), np.int32)
    YY = np.zeros((2, n, L), np.int32)
    dmin = np.zeros(L, np.float64)
    active = np.zeros(L, np.bool_)
    lo = np.zeros(L, np.int32)
    hi = np.zeros(L, np.int32)
    W = np.zeros(L, np.int32)
    bsz = 1 << fold_b
    nv = 1 << fold_v
    Z = np.zeros(bsz * L + 2 * L, np.int32)
    k1 = np.empty(L, np.int32)
    k2 = np.empty(L, np.int32)
    k3 = np.empty(L, np.int32)
    pixels = 0
    evaluated = 0
    wide = 0
    for x0 in range(0, width, L):
        nact = _block_llr(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale,
                          ltab, yy, x0, True, min_d, max_d, stripe, ncols, R, RI, PA, Y, dmin, active, lo, hi)
        if nact == 0:
            for l in range(L):
                if x0 + l < width:
                    _write_none(out_col, out_dist, out_conf, yy, x0 + l)
            continue
        # union of the active lanes' bands; lanes past the image get an empty band that keeps
        # lo and hi non-decreasing in l (so each column's lanes are one interval)
        cmin = ncols
        cmax = -1
        for l in range(L):
            if active[l]:
                cmin = min(cmin, lo[l])
                cmax = max(cmax, hi[l])
                pixels += 1
                evaluated += hi[l] - lo[l] + 1
            if x0 + l >= width:
                lo[l] = _FAR_COL
                hi[l] = _FAR_COL
        # 32-bit keys (min(cost, cap) << s) | (c - cmin), s = bits of c - cmin; a lane whose
        # top-3 holds a capped cost is redone exactly with 64-bit keys (`_band_lane_scan`)
        s = 2
        while (1 << s) <= cmax - cmin:
            s += 1
        zcap = np.int32((1 << (32 - s)) - 2)  # cap of z = 2 cost: cost <= 2**(31 - s) - 1
        mult = np.int32(1 << (s - 1))  # key = min(z, zcap) * mult | (c - cmin)
        for l in range(L):
            W[l] = 0
            k1[l] = NO_KEY32
            k2[l] = NO_KEY32
            k3[l] = NO_KEY32
        for i in range(n):
            yr = Y[i]
            y0 = YY[0, i]
            y1 = YY[1, i]
            for l in range(L):
                yv = yr[l]
                W[l] += max(yv, -yv)
                y0[l] = yv
                y1[l] = -yv
        for u in range(cmin >> fold_b, (cmax >> fold_b) + 1):
            cb = u << fold_b
            c_first = max(cmin, cb)
            c_last = min(cmax, cb + bsz - 1)
            # lanes whose band meets the block: q8 .. q8 + m - 1 (rounded out to multiples of
            # 8); Z holds just these, column c, lane l at Z[L + (c - cb) * m + l - q8] (the
            # margins of L entries keep the top-3 reads of other lanes in bounds: they are
            # outside the band, masked)
            q = 0
            while hi[q] < c_first:
                q += 1
            p = q
            while p < L and lo[p] <= c_last:
                p += 1
            q8 = q & ~7
            m = min(L, (p + 7) & ~7) - q8
            zb = Z[L:L + bsz * m]
            # fold: Z[(a, v), l] = sum over positions i with row a of +-y_i (sign of <g_i, col>
            # on the v and u bits)
            for j in range(bsz * m):
                zb[j] = 0
            for i in range(n):
                zr = fold_row[i] * nv
                su = fold_usign[u, i]
                for v in range(nv):
                    zo = (zr + v) * m
                    zrow = zb[zo:zo + m]
                    src = YY[fold_sgn[i, v] ^ su, i, q8:q8 + m]
                    for l in range(m):
                        zrow[l] += src[l]
            # Walsh-Hadamard transform over the row bits a: Z[(a, v), l] = corr(column)
            h = nv * m
            while h < bsz * m:
                for r0 in range(0, bsz * m, 2 * h):
                    za = zb[r0:r0 + h]
                    zz = zb[r0 + h:r0 + 2 * h]
                    for j in range(h):
                        a = za[j]
                        b = zz[j]
                        za[j] = a + b
                        zz[j] = a - b
                h *= 2
            # top-3 keys, columns inside every lane's band (lo[L-1] <= c <= hi[0]: lo, hi are
            # non-decreasing) unmasked, the others with the lanes outside their band masked out
            f_lo = max(c_first, lo[L - 1])
            f_hi = min(c_last, hi[0])
            if f_lo > f_hi:
                f_lo = c_last + 1
                f_hi = c_last
            zo = L - q8 - cb * m
            _top3_cols(Z, zo, m, W, k1, k2, k3, lo, hi, cmin, c_first, f_lo - 1, zcap, mult, True)
            _top3_cols(Z, zo, m, W, k1, k2, k3, lo, hi, cmin, f_lo, f_hi, zcap, mult, False)
            _top3_cols(Z, zo, m, W, k1, k2, k3, lo, hi, cmin, f_hi + 1, c_last, zcap, mult, True)
        cost_cap = (1 << (31 - s)) - 1
        for l in range(L):
            xx = x0 + l
            if xx >= width:
                break
            if not active[l]:
                _write_none(out_col, out_dist, out_conf, yy, xx)
                continue
            nb = hi[l] - lo[l] + 1
            last = k3[l] if nb >= 3 else (k2[l] if nb == 2 else k1[l])
            if (last >> s) < cost_cap:
                e1 = _key64(k1[l], s, cmin)
                e2 = _key64(k2[l], s, cmin) if nb >= 2 else NO_KEY
                e3 = _key64(k3[l], s, cmin) if nb >= 3 else NO_KEY
            else:
                wide += 1
                e1, e2, e3 = _band_lane_scan(Y, l, n, lo[l], hi[l], masks_t)
            _write(out_col, out_dist, out_conf, yy, xx, e1, e2, e3, dmin[l], q_scale)
    out_stats[yy, 0] = pixels
    out_stats[yy, 1] = evaluated
    out_stats[yy, 2] = wide


@njit(cache=True, parallel=True)
def soft_band_fold(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
                   fold_b, fold_v, fold_sgn, fold_row, fold_usign, masks_t, ncols, min_d, max_d,
                   stripe, out_col, out_dist, out_conf, out_stats):
    """Exact top-3 soft decoding of a column-linear binary code within a disparity band, LANES
    pixels of a row at a time, by folded Walsh-Hadamard transforms of 2**fold_b-column blocks.

    Column-linear: bit i of codeword `col` is <g_i, col> over GF(2) (g_i: `tables` fold_*), so
    corr(col) = sum_i y_i (-1)**<g_i, col> and cost(col) = (sum_i |y_i| + corr(col)) / 2 (the
    cost of the module docstring, bit for bit: C0 - sum_{c_i = 1} y_i).  Split
    col = (u, a, v) (high bits, fold_b - fold_v row bits, fold_v low bits): within block u,
    corr(u, a, v) = WHT over a of Z[a', v] = sum_{i: row(g_i) = a'} +-y_i, the sign being
    (-1)**(<g_i, u> + <g_i, v>).  Per block and lane: n * 2**fold_v row adds and
    (fold_b - fold_v) * 2**fold_b butterflies instead of 2**fold_b * n masked adds; the blocks
    cover the union of the LANES pixels' bands.  The top-3 update (keys (cost << IDX_BITS) |
    column, ties to the lower column) runs per column over exactly the lanes whose band [lo, hi]
    holds it (lo, hi are non-decreasing in x, so these lanes form an interval).
    Keys are 32-bit: (min(cost, cap) << s) | (column - cmin), s the bits of the block's column
    span, cmin its first column, cap = 2**(31 - s) - 1 (so two int32 min/max per step, twice the
    SIMD width of 64-bit keys); a lane whose top-3 (or fewer, with fewer candidates) holds a
    capped cost is redone with 64-bit keys by the band-scan formula (`_band_lane_scan`) from
    masks_t (`tables` masks_t), so the result is exact and bit-identical in every case.  Per
    column block the transform covers only the lanes whose band meets it (rounded out to 8).
    Same outputs as `soft_band`; out_stats (H, 3): decoded pixels, candidate evaluations,
    pixels redone with 64-bit keys.
    """
    height = frames.shape[1]
    for yy in prange(height):
        _band_fold_row(yy, frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale, ltab,
                       fold_b, fold_v, fold_sgn, fold_row, fold_usign, masks_t, ncols, min_d, max_d,
                       stripe, out_col, out_dist, out_conf, out_stats)
