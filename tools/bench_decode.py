"""Benchmark of the decoders (issue 4): median frames/s against a brute-force numpy baseline.

    python tools/bench_decode.py [--repeats 5] [--height 600 --width 700]

Input: a synthetic capture (edge.decode.synthetic) of ecc-22-10 at 600 x 700 with random true
columns inside a 128-column disparity band, albedo uniform in [0.1, 0.8], ambient 0.05,
sigma_r = 0.01, sigma_s = 0.03 (normalised units), uint8 frames.  Baseline: numpy float32
chunked matmul of the per-sample cost differences against all 1024 codewords + argmax (top-1
only).  Everything runs in one process; the first call of each kernel (numba compile or cache
load) is timed separately.  Peak memory: ru_maxrss of the process.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from edge.codes import get_code  # noqa: E402
from edge.decode import decode  # noqa: E402
from edge.decode.synthetic import make_capture  # noqa: E402


def baseline_numpy(frames, white, black, code, sigma_r=0.01, sigma_s=0.03, chunk=65536):
    """Brute force: per-sample ML cost differences (float32) @ codebook, argmin per pixel."""
    n, h, w = frames.shape
    a = white.reshape(-1).astype(np.float32) / 255
    b = black.reshape(-1).astype(np.float32) / 255
    va = sigma_r**2 + sigma_s**2 * a
    vb = sigma_r**2 + sigma_s**2 * b
    cb = code.codebook.astype(np.float32)  # (M, n)
    out = np.empty(h * w, np.int64)
    fr = frames.reshape(n, -1)
    for s in range(0, h * w, chunk):
        r = fr[:, s:s + chunk].astype(np.float32) / 255
        e1 = (r - a[s:s + chunk]) ** 2 / va[s:s + chunk] + np.log(va[s:s + chunk])
        e0 = (r - b[s:s + chunk]) ** 2 / vb[s:s + chunk] + np.log(vb[s:s + chunk])
        delta = (e1 - e0).T  # (chunk, n): cost of a 1 minus cost of a 0
        out[s:s + chunk] = np.argmin(delta @ cb.T, axis=1)
    return out.reshape(h, w)


def timed(fn, repeats):
    t0 = time.perf_counter()
    result = fn()
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return result, first, statistics.median(times)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--height", type=int, default=600)
    p.add_argument("--width", type=int, default=700)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--band", type=int, default=128)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    code = get_code("ecc-22-10")
    rng = np.random.default_rng(args.seed)
    h, w = args.height, args.width
    x = np.arange(w)[None, :]
    min_d = 0
    max_d = args.band - 1
    cols = np.clip(x - rng.integers(min_d, max_d + 1, (h, w)), 0, code.size - 1)
    cap = make_capture(code, cols, rng=rng, albedo=rng.uniform(0.1, 0.8, (h, w)), ambient=0.05,
                       sigma_r=0.01, sigma_s=0.03, dtype=np.uint8)
    fr, wh, bl = cap.frames, cap.white, cap.black
    rows = []

    def report(name, result_cols, first, med, base_med=None):
        acc = float((result_cols == cols).mean())
        fps = 1.0 / med
        ratio = f"{base_med / med:6.1f}x" if base_med else "   1.0x"
        rows.append(name)
        print(f"{name:<38} first {first:7.2f} s   median {med * 1e3:8.1f} ms   {fps:7.1f} frames/s   "
              f"{ratio} vs baseline   correct {acc:.4f}", flush=True)

    base, bfirst, bmed = timed(lambda: baseline_numpy(fr, wh, bl, code), max(1, min(3, args.repeats)))
    report("baseline numpy matmul+argmax (top-1)", base, bfirst, bmed)
    d, first, med = timed(lambda: decode(fr, wh, bl, code, method="soft"), args.repeats)
    report("soft ML exact top-3 + confidence", d.candidates[..., 0], first, med, bmed)
    print(f"    evaluated codewords / pixel: {d.stats['evaluated'] / (h * w):.1f}, "
          f"brute-force pixels: {d.stats['brute_pixels']}", flush=True)
    agree = float((d.candidates[..., 0] == base).mean())
    print(f"    agreement with baseline argmax: {agree:.6f}")
    d, first, med = timed(lambda: decode(fr, wh, bl, code, method="soft", min_disparity=min_d,
                                         max_disparity=max_d), args.repeats)
    report(f"soft ML top-3, {args.band}-column band", d.candidates[..., 0], first, med, bmed)
    d, first, med = timed(lambda: decode(fr, wh, bl, code, method="hard"), args.repeats)
    report("hard (syndrome table)", d.candidates[..., 0], first, med, bmed)
    d, first, med = timed(lambda: decode(fr, wh, bl, code, method="list+median"), args.repeats)
    report("soft + order prior + median", d.column, first, med, bmed)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory (ru_maxrss): {peak:.0f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
