#!/usr/bin/env python
"""Speed-up of `edge replay DIR --workers N` (Ray, local) over the serial replay loop, same run.

    python tools/bench_replay_fleet.py [--files 6] [--stacks 4] [--workers 2] [--repeats 3]
                                       [--profile sim-dlp] [--dir DIR]

Records ``--files`` recordings of ``--stacks`` stacks each with ``edge sim record``'s
`record_simulation` (into ``--dir``, reused when the files are already there; default a temporary
directory), then times, ``--repeats`` times and interleaved, (a) `replay_serial`, the loop that
`edge replay DIR` runs in one process, and (b) `replay_on_ray` with N workers on a local Ray
instance started once (``ray.init(num_cpus=N)``; its start-up time is printed apart and not in
the ratio).  Same advantages for both: the numba kernels are compiled and cached before timing,
the driver has loaded them (one replay first) and every Ray worker has too (warm-up round of N
concurrent tasks, twice).  The serial loop keeps numba's default threads (the decoder kernels
are parallel), the Ray workers get ``cores // N`` threads each.  Prints medians, the ratio, and
checks that both found every file bit-identical.  Needs ray (``pip install 'edge[fleet]'``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", type=int, default=6, help="recordings (default %(default)s)")
    ap.add_argument("--stacks", type=int, default=4, help="stacks per recording (default %(default)s)")
    ap.add_argument("--workers", type=int, default=2, help="Ray workers (default %(default)s)")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats of each (default %(default)s)")
    ap.add_argument("--profile", default="sim-dlp", help="profile to record with (default %(default)s)")
    ap.add_argument("--dir", default=None, help="where the recordings go / are reused (default: a temp dir)")
    args = ap.parse_args()
    for name in ("files", "stacks", "workers", "repeats"):  # --files 0 failed with an IndexError
        if getattr(args, name) < 1:
            raise ValueError(f"--{name} must be >= 1, got {getattr(args, name)}")

    from edge.commands.sim import record_simulation
    from edge.profiles import load_profile
    from edge.io.fleet import require_ray, worker_env
    from edge.io.fleet import replay_on_ray
    from edge.io.replay_many import replay_one, replay_serial

    ray = require_ray("the benchmark")
    tmp = None
    folder = args.dir
    if folder is None:
        tmp = tempfile.TemporaryDirectory(prefix="bench_replay_fleet_")
        folder = tmp.name
    os.makedirs(folder, exist_ok=True)
    profile = load_profile(args.profile)
    paths = [os.path.join(folder, f"{profile.name}-{i}.mcap") for i in range(args.files)]
    t = time.perf_counter()
    made = 0
    for i, p in enumerate(paths):
        if not os.path.exists(p):
            record_simulation(p, profile, args.stacks, first_stack=i * args.stacks)
            made += 1
    size = sum(os.path.getsize(p) for p in paths) / 1e6
    print(f"{args.files} recordings of {args.stacks} stacks ({profile.name}, "
          f"{profile.camera.width}x{profile.camera.height}, {size:.0f} MB) in {folder}"
          + (f", {made} recorded in {time.perf_counter() - t:.1f} s" if made else ", reused"))

    warm = replay_one(paths[0])  # driver: kernels loaded
    assert warm.identical, warm
    t = time.perf_counter()
    ray.init(num_cpus=args.workers, include_dashboard=False, logging_level="ERROR", log_to_driver=False,
             object_store_memory=128 * 1024 * 1024,
             runtime_env={"env_vars": worker_env(args.workers, local=True)})
    startup = time.perf_counter() - t
    try:
        t = time.perf_counter()
        for _ in range(2):  # every worker process loads the kernels before timing
            replay_on_ray([paths[0]] * args.workers, workers=args.workers)
        warm_s = time.perf_counter() - t
        print(f"Ray start-up {startup:.1f} s, worker warm-up {warm_s:.1f} s (not timed below)")
        serial_s, fleet_s = [], []
        for r in range(args.repeats):
            t = time.perf_counter()
            a = replay_serial(paths)
            serial_s.append(time.perf_counter() - t)
            t = time.perf_counter()
            b = replay_on_ray(paths, workers=args.workers)
            fleet_s.append(time.perf_counter() - t)
            ok = all(x.identical for x in a) and all(x.identical for x in b)
            print(f"  repeat {r + 1}: serial {serial_s[-1]:.2f} s, ray {args.workers} workers {fleet_s[-1]:.2f} s"
                  f"{'' if ok else '  NOT ALL IDENTICAL'}")
            assert ok, [x.error or x.first_mismatch for x in a + b if not x.identical]
    finally:
        ray.shutdown()
        if tmp is not None:
            tmp.cleanup()
    s, f = statistics.median(serial_s), statistics.median(fleet_s)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"replay of {args.files} recordings ({args.files * args.stacks} stacks), median of {args.repeats}: "
          f"serial loop {s:.2f} s, Ray {args.workers} workers {f:.2f} s -> speed-up {s / f:.2f}x "
          f"on {os.cpu_count()} cores (load average {load:.1f})")


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
