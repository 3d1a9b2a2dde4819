"""Benchmark of the decoders (issue 4): median frames/s against a brute-force numpy baseline.

    python tools/bench_decode.py [--repeats 5] [--height 600 --width 700] [--cold-compile]
    python tools/bench_decode.py --backend cuda [--small]     (GPU; see bench_cuda)

Inputs: (1) a synthetic capture (edge.decode.synthetic) of ecc-22-10 at 600 x 700 with random true
columns inside a 128-column disparity band, albedo uniform in [0.1, 0.8], ambient 0.05,
sigma_r = 0.01, sigma_s = 0.03 (normalised units), uint8 frames.  Baseline: numpy float32
chunked matmul of the per-sample cost differences against all 1024 codewords + argmin (top-1
only).  (2) The hard regime (`make_hard_input`): edge.sim's flying scene at fixed total
exposure, ambient = projector, 12-bit, where gray-10 errs on about 15 %; its baseline also runs
restricted to the same disparity band as the band rows.  Everything runs in one process.

Rows: "search" rows time the exact top-3 search alone (`edge.decode.backends.cpu.search`, or the
syndrome kernel for hard decoding): what issue 4 section 4 targets; the row "within the skip
margin" is the search `decode()`'s soft method runs (the best exact, the second and third only
located within `posterior.SKIP_MARGIN` of it, which is all its posterior rescores), on the same
calibration levels (inside decode() it searches the split levels); the band is searched with
the folded Walsh-Hadamard kernel (path "band") and, for comparison, the plain band scan
("band-scan"; both must agree exactly).  "decode()" rows time the public call, which adds the
valid mask and, by default, the spatial support check (`edge.decode.spatial.spatial_support`,
also timed alone); "(default)" marks the default options.  Each row: median wall time over --repeats calls, the
median process CPU time of the same calls (CPU / wall near 2 means both cores were ours; near 1
means the machine was busy), frames/s, the ratio to the baseline and the 1-minute load average
after the row.  The first call of each
kernel (numba compile, or loading the on-disk cache) is timed separately ("first"); with
--cold-compile a subprocess with an empty NUMBA_CACHE_DIR reports the true compile times.
Peak memory: tracemalloc peak of one decode() call (numpy allocations) and ru_maxrss of the
process (includes numba / LLVM).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from edge.codes import get_code  # noqa: E402
from edge.decode import DEFAULTS, decode  # noqa: E402
from edge.decode.backends import cpu as cpu_backend  # noqa: E402
from edge.decode.inputs import validate  # noqa: E402
from edge.decode.kernels import METRIC_ML  # noqa: E402
from edge.decode.posterior import SKIP_MARGIN  # noqa: E402
from edge.decode.synthetic import make_capture  # noqa: E402


def baseline_numpy(frames, white, black, code, sigma_r=0.01, sigma_s=0.03, chunk=65536, scale=1 / 255):
    """Brute force: per-sample ML cost differences (float32) @ codebook, argmin per pixel."""
    n, h, w = frames.shape
    a = white.reshape(-1).astype(np.float32) * np.float32(scale)
    b = black.reshape(-1).astype(np.float32) * np.float32(scale)
    va = sigma_r**2 + sigma_s**2 * a
    vb = sigma_r**2 + sigma_s**2 * b
    cb = code.codebook.astype(np.float32)  # (M, n)
    out = np.empty(h * w, np.int64)
    fr = frames.reshape(n, -1)
    for s in range(0, h * w, chunk):
        r = fr[:, s:s + chunk].astype(np.float32) * np.float32(scale)
        e1 = (r - a[s:s + chunk]) ** 2 / va[s:s + chunk] + np.log(va[s:s + chunk])
        e0 = (r - b[s:s + chunk]) ** 2 / vb[s:s + chunk] + np.log(vb[s:s + chunk])
        delta = (e1 - e0).T  # (chunk, n): cost of a 1 minus cost of a 0
        out[s:s + chunk] = np.argmin(delta @ cb.T, axis=1)
    return out.reshape(h, w)


def baseline_numpy_band(frames, white, black, code, min_d, max_d, sigma_r=0.01, sigma_s=0.03, scale=1 / 255):
    """The baseline given the same band: for each camera column x only the codebook rows in
    [x - max_d, x - min_d] (one matmul per column); argmin per pixel, -1 where the band is empty."""
    n, h, w = frames.shape
    a = white.astype(np.float32) * np.float32(scale)
    b = black.astype(np.float32) * np.float32(scale)
    va = sigma_r**2 + sigma_s**2 * a
    vb = sigma_r**2 + sigma_s**2 * b
    r = frames.astype(np.float32) * np.float32(scale)
    delta = ((r - a) ** 2 / va + np.log(va)) - ((r - b) ** 2 / vb + np.log(vb))  # (n, h, w)
    cb = code.codebook.astype(np.float32)
    out = np.full((h, w), -1, np.int64)
    for x in range(w):
        lo, hi = max(0, x - max_d), min(code.size - 1, x - min_d)
        if lo > hi:
            continue
        costs = delta[:, :, x].T @ cb[lo:hi + 1].T  # (h, rows)
        out[:, x] = lo + np.argmin(costs, axis=1)
    return out


def make_hard_input(h, w, seed):
    """The hard regime: edge.sim's flying scene, ecc-22-10 at fixed total exposure (every frame,
    white and black included, at T/22), ambient = projector on a white surface, shot-noise
    dominated (sigma_s 0.04), 12-bit uint16 (gray-10 errs on about 15 % here with defaults,
    tools/eval_posterior.py).  Returns (code, true rows (-1 unlit), capture, band)."""
    from edge.sim import CameraModel, capture_code
    from edge.sim.metrics import truth
    from edge.sim.scenes import make_scene

    code = get_code("ecc-22-10")
    scene = make_scene("flying", w, h, seed=seed)
    cam = CameraModel(bits=12, sigma_r=0.002, sigma_s=0.04, ambient=0.4, projector=0.4)
    cap = capture_code(scene, code, cam, rng=np.random.default_rng([seed, 7]))
    col, lit = truth(scene)
    return code, np.where(lit, col, -1), cap, scene.disparity_band(margin=4)


def timed(fn, repeats):
    """(result, first-call seconds, median wall seconds, median CPU seconds)."""
    t0 = time.perf_counter()
    result = fn()
    first = time.perf_counter() - t0
    wall, cpu = [], []
    for _ in range(repeats):
        c0 = time.process_time()
        t0 = time.perf_counter()
        result = fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return result, first, statistics.median(wall), statistics.median(cpu)


def make_input(h, w, band, seed):
    code = get_code("ecc-22-10")
    rng = np.random.default_rng(seed)
    x = np.arange(w)[None, :]
    cols = np.clip(x - rng.integers(0, band, (h, w)), 0, code.size - 1)
    cap = make_capture(code, cols, rng=rng, albedo=rng.uniform(0.1, 0.8, (h, w)), ambient=0.05,
                       sigma_r=0.01, sigma_s=0.03, dtype=np.uint8)
    return code, cols, cap


def cold_compile() -> int:
    """Child process: first-call times with an empty numba cache (= compile times)."""
    code, _, cap = make_input(8, 40, 16, 0)
    fr, wh, bl = cap.frames, cap.white, cap.black
    for name, kw in [("soft (lane search)", {}), ("soft band (folded WHT)", {"min_disparity": 0, "max_disparity": 15}),
                     ("hard (syndrome)", {"method": "hard"})]:
        t0 = time.perf_counter()
        decode(fr, wh, bl, code, spatial_check=False, **kw)
        print(f"    compile {name:<24} {time.perf_counter() - t0:6.1f} s", flush=True)
    t0 = time.perf_counter()
    decode(fr, wh, bl, code)
    print(f"    compile {'spatial support':<24} {time.perf_counter() - t0:6.1f} s", flush=True)
    return 0


def bench_cuda(args) -> int:
    """--backend cuda: the CUDA backend against a plain GPU baseline (GEMM + top-3), one process.

    Rows: kernel only (inputs already on the device; synchronised; median over --repeats) for
    the soft top-3 over all 1024 codewords, the 128-column band and hard decoding, and the
    baseline's three kernels; end to end from host uint8 frames to host column / confidence /
    valid, the runtime's reduced download (`HOST_OUTPUTS`: candidates and distances stay on the
    device): the whole stack uploaded at once (`Staging`: pinned uploads on a stream, decode
    with the valid mask on the device, one download), and staged as the service stages it
    (`FrameStager`: the first n + 1 frames uploaded before the clock starts, as during capture;
    timed: the last frame's upload, the decode and the download, i.e. the latency the GPU adds
    after the last frame arrives), with the default settings.  Every CUDA row is compared with
    the CPU backend on the same input (identical arrays required).  --small: a 2 x 16 image,
    for the simulator."""
    from numba import cuda

    from edge.decode.backends import cuda as gpu
    from edge.decode.backends.cuda.device import search_device, hard_device, upload
    from edge.decode.backends.cuda.pipeline import HOST_OUTPUTS
    from edge.decode.backends.cuda.staging import FrameStager, Staging
    from edge.sensors.base import Frame
    from edge.decode.settings import DEFAULT_SETTINGS
    from tools.bench_cuda_baseline import Baseline

    if not gpu.is_available():
        print("backend cuda: no CUDA device here (and NUMBA_ENABLE_CUDASIM is not set)", file=sys.stderr)
        return 2
    h, w = (2, 16) if args.small else (args.height, args.width)
    code, cols, cap = make_input(h, w, min(args.band, w), args.seed)
    fr, wh, bl = cap.frames, cap.white, cap.black
    sim = gpu.SIM
    print(f"ecc-22-10, {h} x {w} uint8, {args.repeats} repeats, device: "
          f"{'numba-cuda SIMULATOR (timings meaningless)' if sim else cuda.get_current_device().name}", flush=True)
    st = validate(fr, wh, bl, code)
    ds = upload(st)
    kw = dict(metric=METRIC_ML, sigma_r=DEFAULTS["sigma_r"], sigma_s=DEFAULTS["sigma_s"], columns=code.size, stripe=1)
    band = (True, 0, min(args.band, w) - 1)

    def gpu_timed(fn):
        out = fn()
        cuda.synchronize()
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            out = fn()
            cuda.synchronize()
            times.append(time.perf_counter() - t0)
        return out, statistics.median(times)

    def row(name, med, base=None, exact=None):
        ratio = f"{base / med:6.2f}x" if base else "  1.00x"
        ex = "" if exact is None else f"  identical to CPU: {exact}"
        print(f"{name:<52} median {med * 1e3:8.3f} ms  {1.0 / med:9.1f} frames/s {ratio}{ex}", flush=True)

    bl_run = Baseline(code.n, h, w, code.codebook, DEFAULTS["sigma_r"], DEFAULTS["sigma_s"])
    bcand, bmed = gpu_timed(lambda: bl_run.run(ds.frames, ds.white, ds.black))
    row("baseline: GEMM + top-3 (float32, numba-cuda)", bmed)
    ok = True
    bufs: dict = {}  # output arrays reused between calls, as Staging does
    for name, fn, ref in [
        ("kernel: soft exact top-3, all 1024 codewords",
         lambda: search_device(ds, code, band=(False, 0, 0), buffers=bufs, **kw),
         lambda: cpu_backend.search(st, code, band=(False, 0, 0), **kw)),
        (f"kernel: soft exact top-3, {band[2] + 1}-column band",
         lambda: search_device(ds, code, band=band, buffers=bufs, **kw),
         lambda: cpu_backend.search(st, code, band=band, **kw)),
        ("kernel: hard (syndrome)",
         lambda: hard_device(ds, code, columns=code.size, band=(False, 0, 0), stripe=1, buffers=bufs),
         lambda: cpu_backend.hard(st, code, columns=code.size, band=(False, 0, 0), stripe=1)),
    ]:
        out, med = gpu_timed(fn)
        r = ref()
        same = all(np.array_equal(a.copy_to_host(), b) for a, b in zip(out[:3], r[:3]))
        ok &= same
        row(name, med, bmed, same)
    s = DEFAULT_SETTINGS.replace(backend="cuda")
    stage = Staging(code.n, (h, w), np.uint8)
    images = np.concatenate([fr, wh[None], bl[None]])
    stager = FrameStager(code.n + 2, sets=2)

    def staged(**opts):
        frames = [Frame(image=images[i], sequence=i, timestamp_ns=0, exposure_us=0.0, projector_frame=i, stack=0)
                  for i in range(len(images))]
        for i, f in enumerate(frames[:-1]):  # uploaded during capture, before the last frame
            stager.put(i, f)
        cuda.synchronize()
        t0 = time.perf_counter()
        stager.put(len(frames) - 1, frames[-1])
        d = stager.decode_frames(frames, code, s, outputs=HOST_OUTPUTS, **opts)
        return d, time.perf_counter() - t0

    for name, opts in [("end to end: host uint8 -> column/confidence/valid", {}),
                       (f"end to end: same, {band[2] + 1}-column band", dict(min_disparity=band[1], max_disparity=band[2]))]:
        d, med = gpu_timed(lambda: stage.decode_stack(fr, wh, bl, code, s, outputs=HOST_OUTPUTS, **opts))
        ref = decode(fr, wh, bl, code, **opts)
        same = all(np.array_equal(getattr(d, f), getattr(ref, f)) for f in ("column", "confidence", "valid"))
        ok &= same
        row(name, med, bmed, same)
        stage_times(d)
        runs = [staged(**opts) for _ in range(args.repeats + 1)]
        same = all(np.array_equal(getattr(runs[-1][0], f), getattr(ref, f)) for f in ("column", "confidence", "valid"))
        ok &= same and stager.counters["stacks_not_staged"] == 0
        row("  staged during capture: last frame -> host outputs", statistics.median(t for _, t in runs[1:]), bmed,
            same)
    ok &= cuda_hard_regime(args, gpu_timed, row, bmed)
    print(f"all CUDA rows identical to the CPU backend: {ok}", flush=True)
    return 0 if ok else 1


def stage_times(d) -> None:
    """The last call's error-rule stages on the device (`pipeline.StageClock`, ms), one line."""
    ms = d.stats.get("stage_ms")
    if ms:
        print("    stages ms: " + ", ".join(f"{k} {v:.2f}" for k, v in ms.items()), flush=True)


def cuda_hard_regime(args, gpu_timed, row, bmed) -> bool:
    """--backend cuda, the hard regime (`make_hard_input`: fixed total exposure, ambient =
    projector, 12-bit, shot-noise dominated): decode() with its defaults (self-calibration, the
    error rule and its noise fit, the goodness-of-fit test) on the device, all codewords and the
    scene's disparity band; host 12-bit frames in, the whole `Decoded` out, and the runtime's
    reduced download (`Staging`, `HOST_OUTPUTS`).  Each row is compared with the CPU backend's
    decode() of the same capture: column and valid identical, P(wrong) within the CUDA checks'
    tolerance; the CPU's median on this machine and the agreement with the true rows over lit
    pixels (invalid counts as wrong) are printed with it.  Returns whether every row agreed."""
    from edge.decode.backends.cuda.pipeline import HOST_OUTPUTS
    from edge.decode.backends.cuda.staging import Staging
    from edge.decode.settings import DEFAULT_SETTINGS

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from _cuda_checks import error_agrees  # the CUDA checks' P(wrong) tolerance, device vs CPU

    h, w = (3, 24) if args.small else (args.height, args.width)  # the simulator: a tail pixel takes seconds
    code, truth_cols, cap, (min_d, max_d) = make_hard_input(h, w, args.seed)
    fr, wh, bl = cap.frames, cap.white, cap.black
    lit = truth_cols >= 0
    print(f"\nhard regime: edge.sim flying {h} x {w}, ecc-22-10 at T/22, ambient = projector, 12-bit, "
          f"disparity band [{min_d}, {max_d}]; CPU rows use this machine's {os.cpu_count()} CPUs", flush=True)
    s = DEFAULT_SETTINGS.replace(backend="cuda")
    stage = Staging(code.n, (h, w), fr.dtype)
    ok = True
    for label, opts in (("all 1024 codewords", {}), (f"{max_d - min_d + 1}-column band",
                                                    dict(min_disparity=min_d, max_disparity=max_d))):
        ref, _, cpu_med, _ = timed(lambda: decode(fr, wh, bl, code, bit_depth=12, **opts), max(1, min(3, args.repeats)))
        acc = float(((ref.column == truth_cols) & ref.valid & lit).sum() / lit.sum())
        print(f"{'  CPU decode() defaults, ' + label:<52} median {cpu_med * 1e3:8.3f} ms  {1.0 / cpu_med:9.1f} "
              f"frames/s  correct {acc:.4f}", flush=True)
        for name, fn, whole in (
                (f"decode(backend='cuda') defaults, {label}",
                 lambda: decode(fr, wh, bl, code, bit_depth=12, backend="cuda", **opts), True),
                (f"  end to end, reduced download, {label}",
                 lambda: stage.decode_stack(fr, wh, bl, code, s, outputs=HOST_OUTPUTS, bit_depth=12, **opts), False)):
            d, med = gpu_timed(fn)
            same = np.array_equal(d.column, ref.column) and np.array_equal(d.valid, ref.valid)
            if whole:
                same &= error_agrees(ref.error, d.error)
            ok &= same
            row(name, med, cpu_med, same)
            stage_times(d)
    print("  (hard-regime ratios are against the CPU decode() above, not the GPU baseline)", flush=True)
    return ok


def margin_line(r, exact, pixels: int) -> None:
    """One line on a search with the skip margin (`cpu_backend.search(..., margin=SKIP_MARGIN)`,
    what `decode()`'s soft method runs): pixels it finished (and of those, the ones finished
    alone after D = 0 in a block that did not skip), lane blocks that skipped their lightest
    weight class, codewords evaluated, and whether its best candidates and every
    candidate it located equal the exact top-3 search's."""
    s = r[3]
    located = r[0] >= 0
    same = (np.array_equal(r[0][..., 0], exact[0][..., 0]) and np.array_equal(r[0][located], exact[0][located])
            and np.array_equal(r[1][located], exact[1][located]))
    print(f"    finished by the margin {s['margin_pixels'] / pixels:.2%} of pixels ({s['margin_lanes'] / pixels:.2%} "
          f"alone, in blocks that did not skip); blocks that skipped the lightest class "
          f"{s['margin_blocks'] / max(s['blocks'], 1):.2%}; codewords evaluated / pixel "
          f"{s['evaluated'] / pixels:.1f}; best and located candidates equal the exact search's: {same}", flush=True)


def hard_regime(args, report_row) -> None:
    """The rows of the hard regime (`make_hard_input`): the baseline over all codewords and over
    the band, the search, and decode() with its defaults (self-calibration and the error rule
    included), full and with the band; accuracy = the decoded column's agreement with the truth
    over lit pixels (decode rows: invalid counts as wrong)."""
    code, truth_cols, cap, (min_d, max_d) = make_hard_input(args.height, args.width, args.seed)
    fr, wh, bl = cap.frames, cap.white, cap.black
    scale = 1 / 4095
    lit = truth_cols >= 0
    print(f"\nhard regime: edge.sim flying {args.height} x {args.width}, ecc-22-10 at T/22, ambient = projector, "
          f"12-bit, disparity band [{min_d}, {max_d}] ({max_d - min_d + 1} columns)", flush=True)

    def row(name, result, first, med, cpu, base_med=None):
        acc = f"{float(((result == truth_cols) & lit).sum() / lit.sum()):.4f}"
        ratio = f"{base_med / med:6.1f}x" if base_med else "   1.0x"
        print(f"{name:<48} first {first:6.2f} s  median {med * 1e3:7.1f} ms  cpu {cpu * 1e3:7.1f} ms  "
              f"{1.0 / med:7.1f} frames/s {ratio}  correct {acc}  load {os.getloadavg()[0]:.2f}", flush=True)

    reps = max(1, min(3, args.repeats))
    base, f0, bmed, c0 = timed(lambda: baseline_numpy(fr, wh, bl, code, sigma_s=0.04, scale=scale), reps)
    row("baseline numpy matmul+argmin (top-1)", base, f0, bmed, c0)
    bb, f0, bbmed, c0 = timed(lambda: baseline_numpy_band(fr, wh, bl, code, min_d, max_d, sigma_s=0.04, scale=scale),
                              reps)
    row("baseline numpy, same band", bb, f0, bbmed, c0)
    st = validate(fr, wh, bl, code, bit_depth=12)
    kw = dict(metric=METRIC_ML, sigma_r=0.002, sigma_s=0.04, columns=code.size, stripe=1)
    r, first, med, cpu = timed(lambda: cpu_backend.search(st, code, band=(False, 0, 0), **kw), args.repeats)
    row("search: soft exact top-3 (calibration levels)", r[0][..., 0], first, med, cpu, bmed)
    exact_top3 = r
    r, first, med, cpu = timed(lambda: cpu_backend.search(st, code, band=(False, 0, 0), margin=SKIP_MARGIN, **kw),
                               args.repeats)
    row("search: 2nd/3rd within the skip margin (same)", r[0][..., 0], first, med, cpu, bmed)
    margin_line(r, exact_top3, args.height * args.width)
    for name, opts, base_med in (
            ("decode(): defaults (self-calibrated, error rule)", {}, bmed),
            ("decode(): defaults, band", dict(min_disparity=min_d, max_disparity=max_d), bbmed),
            ("decode(): validity='confidence'", dict(validity="confidence"), bmed),
            ("decode(): method='median' (defaults)", dict(method="median"), bmed)):
        d, first, med, cpu = timed(lambda: decode(fr, wh, bl, code, bit_depth=12, **opts), args.repeats)
        row(name, d.column, first, med, cpu, base_med)
    tracemalloc.start()
    decode(fr, wh, bl, code, bit_depth=12)
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    print(f"peak memory: decode() defaults, hard regime {peak:.0f} MiB (tracemalloc, input "
          f"{(fr.nbytes + wh.nbytes + bl.nbytes) / 2**20:.0f} MiB not included)\n", flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--height", type=int, default=600, help="capture height in pixels (default 600)")
    p.add_argument("--width", type=int, default=700, help="capture width in pixels (default 700)")
    p.add_argument("--repeats", type=int, default=5, help="timed calls per row; the median is reported (default 5)")
    p.add_argument("--band", type=int, default=128,
                   help="disparity band width in columns for the band rows (default 128)")
    p.add_argument("--seed", type=int, default=0, help="seed of the synthetic captures (default 0)")
    p.add_argument("--cold-compile", action="store_true",
                   help="also measure compile times in a subprocess with an empty numba cache")
    p.add_argument("--_child-compile", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--backend", choices=("cpu", "cuda"), default="cpu",
                   help="cuda: the CUDA backend against a plain GPU GEMM + top-3 baseline (bench_cuda) "
                        "(default %(default)s)")
    p.add_argument("--small", action="store_true",
                   help="with --backend cuda: a 2 x 16 image (checks the code path under NUMBA_ENABLE_CUDASIM=1)")
    args = p.parse_args(argv)
    if args._child_compile:
        return cold_compile()
    if args.backend == "cuda":
        return bench_cuda(args)
    h, w = args.height, args.width
    code, cols, cap = make_input(h, w, args.band, args.seed)
    fr, wh, bl = cap.frames, cap.white, cap.black
    min_d, max_d = 0, args.band - 1
    print(f"ecc-22-10, {h} x {w} uint8, {args.repeats} repeats, load average at start "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}, {os.cpu_count()} CPUs", flush=True)

    def report(name, result_cols, first, med, cpu, base_med=None):
        acc = f"{float((result_cols == cols).mean()):.4f}" if result_cols is not None else "     -"
        ratio = f"{base_med / med:6.1f}x" if base_med else "   1.0x"
        print(f"{name:<48} first {first:6.2f} s  median {med * 1e3:7.1f} ms  cpu {cpu * 1e3:7.1f} ms  "
              f"{1.0 / med:7.1f} frames/s {ratio}  correct {acc}  load {os.getloadavg()[0]:.2f}", flush=True)

    base, bfirst, bmed, bcpu = timed(lambda: baseline_numpy(fr, wh, bl, code), max(1, min(3, args.repeats)))
    report("baseline numpy matmul+argmin (top-1)", base, bfirst, bmed, bcpu)

    st = validate(fr, wh, bl, code)
    kw = dict(metric=METRIC_ML, sigma_r=DEFAULTS["sigma_r"], sigma_s=DEFAULTS["sigma_s"],
              columns=code.size, stripe=1)
    r, first, med, cpu = timed(lambda: cpu_backend.search(st, code, band=(False, 0, 0), **kw), args.repeats)
    report("search: soft exact top-3 + confidence", r[0][..., 0], first, med, cpu, bmed)
    s = r[3]
    print(f"    path {s['path']}: codewords evaluated / pixel {s['evaluated'] / (h * w):.1f}; pixels needing "
          f"the 2nd weight class {s['second_class_pixels'] / (h * w):.4%}; lane blocks with such a pixel "
          f"{s['second_class_blocks'] / max(s['blocks'], 1):.4%} of {s['blocks']}", flush=True)
    print(f"    agreement with baseline argmin: {float((r[0][..., 0] == base).mean()):.6f}", flush=True)
    exact_top3 = r
    r, first, med, cpu = timed(lambda: cpu_backend.search(st, code, band=(False, 0, 0), margin=SKIP_MARGIN, **kw),
                               args.repeats)
    report("search: soft top-1 + 2nd/3rd within the skip margin", r[0][..., 0], first, med, cpu, bmed)
    margin_line(r, exact_top3, h * w)
    band = (True, min_d, max_d)
    r, first, med, cpu = timed(lambda: cpu_backend.search(st, code, band=band, **kw), args.repeats)
    report(f"search: soft top-3, {args.band}-column band", r[0][..., 0], first, med, cpu, bmed)
    print(f"    path {r[3]['path']}: candidates / pixel {r[3]['evaluated'] / (h * w):.1f}; pixels redone with "
          f"64-bit keys {r[3].get('wide_key_pixels', 0)}", flush=True)
    r2, first, med, cpu = timed(lambda: cpu_backend.search(st, code, band=band, path="band-scan", **kw), args.repeats)
    report(f"search: soft top-3, {args.band}-col band, plain scan", r2[0][..., 0], first, med, cpu, bmed)
    same = all(np.array_equal(a, b) for a, b in zip(r[:3], r2[:3]))
    print(f"    band (folded WHT) == band-scan on every output: {same}", flush=True)
    r, first, med, cpu = timed(lambda: cpu_backend.hard(st, code, columns=code.size, band=(False, 0, 0), stripe=1), args.repeats)
    report("search: hard (syndrome table)", r[0][..., 0], first, med, cpu, bmed)

    from edge.decode.spatial import spatial_support

    d0 = decode(fr, wh, bl, code, spatial_check=False)
    elig = d0.candidates[..., 0] >= 0
    _, first, med, cpu = timed(lambda: spatial_support(d0.column, d0.confidence, elig,
                                                       t_vote=DEFAULTS["t_high"]), args.repeats)
    report("spatial_support (default valid mask's check)", None, first, med, cpu, bmed)

    bopts = dict(min_disparity=min_d, max_disparity=max_d)
    runs = [
        ("decode(): soft (default)", dict(method="soft")),
        ("decode(): soft, spatial_check=False", dict(method="soft", spatial_check=False)),
        ("decode(): soft, band (default)", dict(method="soft", **bopts)),
        ("decode(): soft, band, spatial_check=False", dict(method="soft", spatial_check=False, **bopts)),
        ("decode(): hard (default)", dict(method="hard")),
        ("decode(): hard, spatial_check=False", dict(method="hard", spatial_check=False)),
        ("decode(): list+median", dict(method="list+median")),
        ("decode(): sgm", dict(method="sgm")),
        ("decode(): soft, levels='refit'", dict(method="soft", levels="refit")),
    ]
    for name, opts in runs:
        d, first, med, cpu = timed(lambda: decode(fr, wh, bl, code, **opts), args.repeats)
        report(name, d.candidates[..., 0] if opts["method"] not in ("list+median", "sgm") else d.column, first, med,
               cpu, bmed)

    hard_regime(args, report)

    tracemalloc.start()
    decode(fr, wh, bl, code, method="soft")
    peak_soft = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.reset_peak()
    decode(fr, wh, bl, code, method="soft", min_disparity=min_d, max_disparity=max_d)
    peak_band = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory: decode() soft {peak_soft:.0f} MiB, band {peak_band:.0f} MiB (tracemalloc, input "
          f"{(fr.nbytes + wh.nbytes + bl.nbytes) / 2**20:.0f} MiB not included); process ru_maxrss {rss:.0f} MiB")
    print(f"load average at end {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if args.cold_compile:
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
            print("first-call compile times (empty numba cache, subprocess):", flush=True)
            subprocess.run([sys.executable, __file__, "--_child-compile"], env=env, check=True)
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
