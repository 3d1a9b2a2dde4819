"""Soft exact top-3 of a binary code on the GPU: over all codewords, or over a disparity band.

One thread per pixel (consecutive pixels of a row in consecutive threads: coalesced frame
loads).  Each thread quantises its n samples with the shared cost model (`cost.pixel_llr`) and
builds 4-bit subset-sum tables of its cost differences in shared memory, laid out
``tab[g * 16 + nibble, thread]`` so that the lookups of a warp never conflict (thread t always
reads bank t mod 32).  The cost of codeword c is ``C0 - sum_g tab[g, nibble_g(c)]`` (C0 = cost
of the all-zero word: the identity of `kernels.soft_band`), so ``ceil(n / 4)`` lookups per
codeword; the top-3 keys (cost << 16 | column) stay in registers.

* `full_kernel`: every codeword (optionally restricted to each pixel's band): the codebook is
  streamed through shared memory in tiles of `TILE` packed codewords that the whole block
  reads (broadcast).
* `band_kernel`: each thread scans only its own band [lo, hi] (neighbouring threads read
  neighbouring codewords: cached global loads).

Both are exact, with the CPU's keys and tie rule; tests compare them with the CPU backend.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import cuda

from .cost import MAX_N, band_of, insert, mul64, pixel_llr, pixel_logs_of, pixel_of, write_none, write_top3
from ...kernels import IDX_BITS, NO_KEY

#: Packed codewords per shared-memory tile of `full_kernel`.
TILE = 256
_NO_KEY = int(NO_KEY)
_IDX_BITS = IDX_BITS


def threads_per_block(ngroups: int) -> int:
    """Threads (pixels) per block: 64, or 32 for long codes (shared tables <= 32 KiB)."""
    return 64 if ngroups <= 8 else 32


@cuda.jit(device=True)
def _build_tables(y, n, tab, tid, ngroups):
    """tab[g * 16 + p, tid] = sum of y over the bits of p at positions 4g.. (0 beyond n)."""
    for g in range(ngroups):
        base = g * 16
        tab[base, tid] = 0
        for bit in range(4):
            pos = 4 * g + bit
            val = y[pos] if pos < n else np.int32(0)
            half = 1 << bit
            for p in range(half):
                tab[base + (half | p), tid] = tab[base + p, tid] + val


@cuda.jit(device=True)
def _masked_sum(m, tab, tid, ngroups):
    s = np.int32(0)
    for g in range(ngroups):
        s += tab[g * 16 + np.int64((m >> np.int64(4 * g)) & np.int64(15)), tid]
    return s


@lru_cache(maxsize=None)
def full_kernel(ngroups: int):
    """The all-codeword kernel for codes of ``ceil(n / 4) == ngroups`` (compiled per size)."""
    tpb = threads_per_block(ngroups)
    nt = ngroups * 16

    @cuda.jit
    def soft_full(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale,
                  lmode, ltab, plog, masks, ncols, use_band, min_d, max_d, stripe,
                  out_col, out_dist, out_conf):
        tab = cuda.shared.array((nt, tpb), np.int32)
        tile = cuda.shared.array(TILE, np.int64)
        y = cuda.local.array(MAX_N, np.int32)
        n = frames.shape[0]
        height = frames.shape[1]
        width = frames.shape[2]
        tid = cuda.threadIdx.x
        p = cuda.blockIdx.x * tpb + tid
        act = p < height * width
        yy = p // width if act else 0
        xx = p - yy * width if act else 0
        lo = 0
        hi = -1
        dmin = 0.0
        c0 = np.int32(0)
        if act:
            a = mul64(white[yy, xx], scale)
            b = mul64(black[yy, xx], scale)
            lo, hi = band_of(xx, use_band, min_d, max_d, stripe, ncols)
            if not (a > b) or lo > hi:
                write_none(out_col, out_dist, out_conf, yy, xx)
                act = False
            else:
                log_a, log_b = pixel_logs_of(white, black, lmode, ltab, plog, yy, xx)
                dmin, c0 = pixel_llr(frames, inverse, has_inv, yy, xx, n, scale, a, b, metric,
                                     sr2, ss2, q_scale, log_a, log_b, y)
                _build_tables(y, n, tab, tid, ngroups)
        k1 = _NO_KEY
        k2 = _NO_KEY
        k3 = _NO_KEY
        for t0 in range(0, ncols, TILE):
            cuda.syncthreads()
            for j in range(tid, TILE, tpb):
                if t0 + j < ncols:
                    tile[j] = masks[t0 + j]
            cuda.syncthreads()
            if act:
                jmax = min(TILE, ncols - t0)
                for j in range(jmax):
                    col = t0 + j
                    if col < lo or col > hi:
                        continue
                    cost = c0 - _masked_sum(tile[j], tab, tid, ngroups)
                    key = (np.int64(cost) << _IDX_BITS) | np.int64(col)
                    if key < k3:
                        k1, k2, k3 = insert(key, k1, k2, k3)
        if act:
            write_top3(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale)

    return soft_full, tpb


@lru_cache(maxsize=None)
def band_kernel(ngroups: int):
    """The band-scan kernel for codes of ``ceil(n / 4) == ngroups``."""
    tpb = threads_per_block(ngroups)
    nt = ngroups * 16

    @cuda.jit
    def soft_band(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2, q_scale,
                  lmode, ltab, plog, masks, ncols, min_d, max_d, stripe,
                  out_col, out_dist, out_conf):
        tab = cuda.shared.array((nt, tpb), np.int32)
        y = cuda.local.array(MAX_N, np.int32)
        n = frames.shape[0]
        height = frames.shape[1]
        width = frames.shape[2]
        tid = cuda.threadIdx.x
        yy, xx, inside = pixel_of(cuda.blockIdx.x * tpb + tid, height, width)
        if not inside:
            return
        a = mul64(white[yy, xx], scale)
        b = mul64(black[yy, xx], scale)
        lo, hi = band_of(xx, True, min_d, max_d, stripe, ncols)
        if not (a > b) or lo > hi:
            write_none(out_col, out_dist, out_conf, yy, xx)
            return
        log_a, log_b = pixel_logs_of(white, black, lmode, ltab, plog, yy, xx)
        dmin, c0 = pixel_llr(frames, inverse, has_inv, yy, xx, n, scale, a, b, metric,
                             sr2, ss2, q_scale, log_a, log_b, y)
        _build_tables(y, n, tab, tid, ngroups)
        k1 = _NO_KEY
        k2 = _NO_KEY
        k3 = _NO_KEY
        for col in range(lo, hi + 1):
            cost = c0 - _masked_sum(masks[col], tab, tid, ngroups)
            key = (np.int64(cost) << _IDX_BITS) | np.int64(col)
            if key < k3:
                k1, k2, k3 = insert(key, k1, k2, k3)
        write_top3(out_col, out_dist, out_conf, yy, xx, k1, k2, k3, dmin, q_scale)

    return soft_band, tpb
