#!/usr/bin/env python
"""Benchmark the simulator: median time to capture a code at 640x480 (target <= 0.5 s for 22 frames).

    python tools/bench_sim.py [--repeats 7] [--width 640 --height 480]

Prints the median and min of `capture_code` (n code frames + white + black) for gray-10 and
ecc-22-10 on `flying`, ecc-22-10 on the inter-reflection scene `v-groove` and the `scattering`
scene, and `make_scene` times.  Timing on a shared 2-core machine is noisy.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from edge.codes import get_code
from edge.sim import CameraModel, capture_code, make_scene


def timeit(fn, repeats: int) -> tuple[float, float]:
    fn()  # warm-up (numba compile / cache load)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), min(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=7, help="timed renders; the median is reported (default 7)")
    ap.add_argument("--width", type=int, default=640, help="image width in pixels (default 640)")
    ap.add_argument("--height", type=int, default=480, help="image height in pixels (default 480)")
    args = ap.parse_args()
    w, h = args.width, args.height
    cam = CameraModel(defocus_sigma=0.0)
    rng = np.random.default_rng(0)
    print(f"capture_code at {w}x{h}, median / min of {args.repeats} runs")
    for scene_name in ("flying", "v-groove", "scattering"):
        med, best = timeit(lambda: make_scene(scene_name, w, h, seed=1), max(1, args.repeats // 2))
        print(f"  make_scene {scene_name:12s}            {med:7.3f} s / {best:7.3f} s")
    cases = [("flying", "gray-10", cam), ("flying", "ecc-22-10", cam),
             ("flying", "ecc-22-10", cam.with_(defocus_sigma=1.5)),
             ("v-groove", "ecc-22-10", cam), ("scattering", "ecc-22-10", cam)]
    for scene_name, code_name, camera in cases:
        scene = make_scene(scene_name, w, h, seed=1)
        code = get_code(code_name)
        med, best = timeit(lambda: capture_code(scene, code, camera, rng=rng), args.repeats)
        tag = f"{scene_name}/{code_name}" + (" defocus" if camera.defocus_sigma else "")
        print(f"  capture_code {tag:30s} ({code.n + 2:2d} frames) {med:7.3f} s / {best:7.3f} s"
              + ("   target <= 0.5 s" if code.n == 22 else ""))


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
