"""Benchmark the depth service end to end: `edge run` in one process, a zenoh subscriber in this one.

    python tools/bench_service.py [--profile sim-dlp] [--seconds 60] [--warmup 10] [--poses 8] [--edc-rounds 3]

The service runs the simulated sensor at the profile's camera rate (default sim-dlp: 640x480 @
120 fps, ecc-22-10, soft decoding; 24 frames per depth map = 5 stacks/s offered), with
``--poses`` pre-rendered poses of the moving scene so the simulator's own rendering does not load
the CPU during the measurement, records MCAP, and publishes on zenoh (loopback).  Printed:

* stacks dropped per minute (stale + incomplete, from the service's final status);
* depth maps per second received by the subscriber;
* p50 / p99 latency from the last camera frame of a stack to the depth sample arriving here
  (another process), after ``--warmup`` seconds;
* CPU use of the service process (user + system time / wall time; 1.0 = one core);
* recording throughput (MB/s written) and frames lost by the recorder (must be 0);
* with ``--edc-rounds R``: the profile's ``edc.rounds`` set to R (a copy of the profile in a
  temporary folder), the EDC rounds run per stack, the decode time of each round and the masked
  frames' capture time, and the camera frames per depth map (from the service's status).

Timings depend on the machine and on whatever else runs on it; quote the command with the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from _ports import free_port  # noqa: E402


def cpu_seconds(pid: int) -> float:
    """user + system CPU seconds of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def edc_profile(name: str, rounds: int, folder: Path):
    """(path, profile): a copy of profile ``name`` with ``[edc] rounds = rounds``, written to ``folder``."""
    import re

    from edge.profiles import load_profile
    from edge.profiles.files import find_profile

    text = find_profile(name).read_text()
    new, count = re.subn(r"(\[edc\][^\[]*?\brounds\s*=\s*)\d+", lambda m: m.group(1) + str(int(rounds)), text)
    if count != 1:
        new = text + f"\n[edc]\nrounds = {int(rounds)}\n" if "[edc]" not in text else None
    if new is None:
        raise SystemExit(f"bench_service: cannot set edc.rounds in profile {name!r}")
    path = folder / f"{Path(str(name)).stem}-edc{int(rounds)}.toml"
    path.write_text(new)
    return path, load_profile(path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--profile", default="sim-dlp", help="firmware profile name or TOML path (default sim-dlp)")
    ap.add_argument("--seconds", type=float, default=60.0, help="measured run time after warm-up (default %(default)g)")
    ap.add_argument("--warmup", type=float, default=10.0, help="seconds ignored at the start: numba load, poses (default %(default)g)")
    ap.add_argument("--poses", type=int, default=8, help="pre-rendered poses of the moving scene (default 8)")
    ap.add_argument("--no-record", action="store_true", help="run without the MCAP recording")
    ap.add_argument("--edc-rounds", type=int, default=None, metavar="R",
                    help="run with the profile's edc.rounds set to R (adaptive EDC re-projection rounds)")
    args = ap.parse_args()

    from edge.io.zenoh import DepthSubscriber
    from edge.profiles import load_profile

    profile = load_profile(args.profile)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    tmp = tempfile.TemporaryDirectory()
    profile_arg = args.profile
    if args.edc_rounds is not None:
        profile_arg, profile = edc_profile(args.profile, args.edc_rounds, Path(tmp.name))
    out = Path(tmp.name) / "bench.mcap"
    total = args.warmup + args.seconds
    cmd = [sys.executable, "-m", "edge.cli", "run", "--profile", str(profile_arg), "--seconds", f"{total:.1f}",
           "--poses", str(args.poses), "--listen", endpoint, "--quiet"]
    if not args.no_record:
        cmd += ["--record", str(out)]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, cwd=ROOT)
    latencies, received, t_first = [], 0, None
    with DepthSubscriber(profile.zenoh.device, connect=[endpoint], max_queue=64) as sub:
        start = time.monotonic()
        cpu0 = wall0 = status0 = None
        while proc.poll() is None:
            s = sub.receive(timeout=0.5, confidence_wait=0.0)
            now = time.monotonic()
            if cpu0 is None and now - start >= args.warmup:
                cpu0, wall0, status0 = cpu_seconds(proc.pid), now, dict(sub.status or {})
            if s is None or cpu0 is None:
                continue
            received += 1
            latencies.append(s.latency_ms)
            t_first = t_first or now
            if now - wall0 >= args.seconds - 0.5:
                cpu1, wall1 = cpu_seconds(proc.pid), now
                break
        else:
            cpu1 = wall1 = None
        final_wait = time.monotonic() + 30
        while proc.poll() is None and time.monotonic() < final_wait:
            time.sleep(0.2)
        final = dict(sub.status or {})
    text, _ = proc.communicate(timeout=120)
    if cpu0 is None or cpu1 is None or not latencies:
        print(text)
        print("bench_service: the service produced no measurable window", file=sys.stderr)
        return 1
    duration = wall1 - wall0
    lat = np.array(latencies)
    dropped = final.get("stacks_dropped", 0) - status0.get("stacks_dropped", 0)
    rec = final.get("recorder") or {}
    size = out.stat().st_size if out.exists() else 0
    print(f"profile {profile.name}: {profile.camera.width}x{profile.camera.height} @ {profile.camera.rate_hz:g} fps, "
          f"{profile.code.name}, {profile.decoder.method} decoding; measured {duration:.1f} s after {args.warmup:g} s warm-up")
    from edge.device import stack_layout

    n, L = stack_layout(profile)
    offered = profile.camera.rate_hz / ((n + 2) * L)
    print(f"depth maps/s at subscriber : {received / duration:.2f}  (offered by the camera: {offered:.2f})")
    print(f"stacks dropped per minute  : {60.0 * dropped / duration:.1f}  (stale {final.get('stacks_dropped_stale')}, "
          f"incomplete {final.get('stacks_dropped_incomplete')} over the whole run)")
    print(f"latency last frame -> subscriber: p50 {np.percentile(lat, 50):.1f} ms, p99 {np.percentile(lat, 99):.1f} ms, "
          f"max {lat.max():.1f} ms ({lat.size} samples)")
    print(f"decode time p50 (service)  : {final.get('decode_ms_p50')} ms")
    print(f"service CPU use            : {(cpu1 - cpu0) / duration:.2f} cores (of {os.cpu_count()})")
    if not args.no_record:
        print(f"recording                  : {size / 1e6:.1f} MB in {total:.0f} s = {size / 1e6 / total:.2f} MB/s; "
              f"frames written {rec.get('frames_written')}, frames lost {rec.get('frames_lost')}")
    if profile.edc.rounds:
        print(f"EDC (edc.rounds = {profile.edc.rounds}): rounds run {final.get('edc_rounds')} (last stack), "
              f"decode ms per round {final.get('edc_round_ms')}, masked capture ms {final.get('edc_capture_ms')}, "
              f"frames per depth map {final.get('frames_per_depth_map')}")
    print("final status: " + json.dumps({k: final.get(k) for k in ("fps", "stacks_complete", "stacks_decoded",
                                                                  "stacks_dropped", "errors")}))
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
