"""Plain GPU baseline for tools/bench_decode.py --backend cuda: GEMM + top-3 in numba-cuda.

No cupy / torch: three kernels a newcomer would write first.  (1) per pixel the float32 ML cost
differences ``delta_i = e1_i - e0_i`` (n, P); (2) a shared-memory tiled float32 GEMM
``costs = delta^T @ codebook^T`` (P, K) written to global memory; (3) per pixel a scan of its
row for the three smallest costs.  Float32 and unquantised, so it may differ from the exact
decoders at near ties; it is the speed reference, not a correctness reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

TILE = 16


@cuda.jit
def _deltas(frames, white, black, sr2, ss2, out):
    n = frames.shape[0]
    width = frames.shape[2]
    p = cuda.grid(1)
    if p >= out.shape[1]:
        return
    yy = p // width
    xx = p - yy * width
    a = np.float32(white[yy, xx]) / np.float32(255.0)
    b = np.float32(black[yy, xx]) / np.float32(255.0)
    va = sr2 + ss2 * a
    vb = sr2 + ss2 * b
    la = math.log(va)
    lb = math.log(vb)
    for i in range(n):
        r = np.float32(frames[i, yy, xx]) / np.float32(255.0)
        out[i, p] = (r - a) * (r - a) / va + la - ((r - b) * (r - b) / vb + lb)


@cuda.jit
def _gemm(delta, cb_t, out):
    """out (P, K) = delta^T (P, n) @ cb_t (n, K), 16 x 16 shared-memory tiles."""
    sa = cuda.shared.array((TILE, TILE), np.float32)
    sb = cuda.shared.array((TILE, TILE), np.float32)
    tx = cuda.threadIdx.x
    ty = cuda.threadIdx.y
    row = cuda.blockIdx.y * TILE + ty  # pixel
    col = cuda.blockIdx.x * TILE + tx  # codeword
    n = delta.shape[0]
    npx = delta.shape[1]
    k = cb_t.shape[1]
    acc = np.float32(0.0)
    for t in range(0, n, TILE):
        sa[ty, tx] = delta[t + tx, row] if (row < npx and t + tx < n) else np.float32(0.0)
        sb[ty, tx] = cb_t[t + ty, col] if (col < k and t + ty < n) else np.float32(0.0)
        cuda.syncthreads()
        for j in range(TILE):
            acc += sa[ty, j] * sb[j, tx]
        cuda.syncthreads()
    if row < npx and col < k:
        out[row, col] = acc


@cuda.jit
def _top3(costs, out_col):
    p = cuda.grid(1)
    if p >= costs.shape[0]:
        return
    b1 = np.inf
    b2 = np.inf
    b3 = np.inf
    c1 = -1
    c2 = -1
    c3 = -1
    for c in range(costs.shape[1]):
        v = costs[p, c]
        if v < b3:
            if v < b2:
                b3, c3 = b2, c2
                if v < b1:
                    b2, c2 = b1, c1
                    b1, c1 = v, c
                else:
                    b2, c2 = v, c
            else:
                b3, c3 = v, c
    out_col[p, 0] = c1
    out_col[p, 1] = c2
    out_col[p, 2] = c3


class Baseline:
    """Device buffers for one (n, H, W) uint8 input and a codebook; `run` launches the three
    kernels (frames already on the device) and returns the (P, 3) device candidates."""

    def __init__(self, n: int, h: int, w: int, codebook: np.ndarray, sigma_r: float, sigma_s: float) -> None:
        self.p = h * w
        self.k = codebook.shape[0]
        self.delta = cuda.device_array((n, self.p), np.float32)
        self.cb_t = cuda.to_device(np.ascontiguousarray(codebook.T.astype(np.float32)))
        self.costs = cuda.device_array((self.p, self.k), np.float32)
        self.cand = cuda.device_array((self.p, 3), np.int32)
        self.sr2, self.ss2 = np.float32(sigma_r**2), np.float32(sigma_s**2)

    def run(self, frames, white, black):
        tpb = 128
        _deltas[(self.p + tpb - 1) // tpb, tpb](frames, white, black, self.sr2, self.ss2, self.delta)
        grid = ((self.k + TILE - 1) // TILE, (self.p + TILE - 1) // TILE)
        _gemm[grid, (TILE, TILE)](self.delta, self.cb_t, self.costs)
        _top3[(self.p + tpb - 1) // tpb, tpb](self.costs, self.cand)
        return self.cand
