"""The "scalar" path: per-pixel exact top-3 by branch-and-bound (any binary code; the reference
the fast paths are tested against).

With y, h, w of `edge.decode.kernels.cost`, for any codeword c ``cost(c) = sum_{i in c xor h} w_i``
and the distance is ``dmin + cost / q_scale``.  So the ML codeword is the one whose disagreement
set with h has the least reliability, and `soft_binary` searches that exactly:

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

Costs are summed with 64-entry subset-sum tables over 6-bit position groups.  Tables:
`edge.decode.tables.ScalarTables`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .cost import _U0, _U1, _pixel_llr
from .top3 import IDX_BITS, NO_KEY, _insert, _pixel_start, _write, _write_none, sort_small


_U63 = np.uint64(63)
_U255 = np.uint64(255)


@njit(cache=True)
def _pack(m, comp, nbytes):
    out = np.int64(0)
    for g in range(nbytes):
        out |= comp[g, np.int64((m >> np.uint64(8 * g)) & _U255)]
    return out


@njit(cache=True)
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


@njit(cache=True)
def _cost_of(diff, tab, ngroups):
    s = tab[0, np.int64(diff & _U63)]
    for g in range(1, ngroups):
        s += tab[g, np.int64((diff >> np.uint64(6 * g)) & _U63)]
    return s


@njit(cache=True, parallel=True)
def soft_binary(frames, inverse, has_inv, white, black, scale, model, tables, band, brute_max,
                out_col, out_dist, out_conf, out_stats):
    """Exact top-3 soft decoding of a binary code for every pixel.

    frames, inverse: (n, H, W); white, black: (H, W); outputs: out_col (H, W, 3) int32,
    out_dist (H, W, 3) float32, out_conf (H, W) float32; out_stats (H, 2) int64 counts per row
    of [pixels that took the brute-force path, codewords whose cost was evaluated].
    model: `CostModel` (ltab unused); tables: `edge.decode.tables.ScalarTables`; band: `Band`.
    linear=False or a band of at most brute_max columns: brute force over the candidates
    (still exact); otherwise the pruned enumeration of the module docstring.
    """
    metric, sr2, ss2, q_scale = model.metric, model.sr2, model.ss2, model.q_scale
    masks, comp_info, col_of_info, comp_syn = tables.masks, tables.comp_info, tables.col_of_info, tables.comp_syn
    leader, has_leader, linear = tables.leader, tables.has_leader, tables.linear
    diff_masks, diff_info, class_start = tables.diff_masks, tables.diff_info, tables.class_start
    sub_start, sub_p0, class_sub = tables.sub_start, tables.sub_p0, tables.class_sub
    ncols, use_band, min_d, max_d, stripe = band.ncols, band.use_band, band.min_d, band.max_d, band.stripe
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
            a, b, lo, hi, ok = _pixel_start(white, black, yy, xx, scale, use_band, min_d, max_d, stripe, ncols)
            if not ok:
                _write_none(out_col, out_dist, out_conf, yy, xx)
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
                sort_small(sv, n)
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
                sort_small(sv, n_out)
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
