"""Soak test of the depth service: memory over a long run with a subscriber that comes and goes.

    python tools/soak_service.py [--profile sim-dlp] [--seconds 600] [--cycle 20]

Runs `edge run` (simulated sensor, real time, zenoh on loopback, no recording) in a child process.
This process subscribes for ``--cycle`` seconds, closes its session for ``--cycle`` seconds, and
repeats, so the service sees a peer that disappears and comes back.  Every 5 s it samples the
service's resident memory (VmRSS).  It prints the RSS samples' start, end, peak and the growth
slope (MB per minute, least squares over the second half of the run, after warm-up), how many
depth maps each subscription received, and fails (exit 1) if a subscription got nothing after the
first or the slope exceeds ``--max-growth`` MB/min.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from _ports import free_port  # noqa: E402


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--profile", default="sim-dlp", help="firmware profile name or TOML path (default sim-dlp)")
    ap.add_argument("--seconds", type=float, default=600.0, help="run length in seconds (default 600)")
    ap.add_argument("--cycle", type=float, default=20.0, help="seconds subscribed, then seconds away (default %(default)g)")
    ap.add_argument("--poses", type=int, default=8, help="pre-rendered poses of the moving scene (default 8)")
    ap.add_argument("--max-growth", type=float, default=2.0, help="allowed RSS slope, MB per minute (default %(default)g)")
    args = ap.parse_args()

    from edge.io.zenoh import DepthSubscriber
    from edge.profiles import load_profile

    profile = load_profile(args.profile)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cmd = [sys.executable, "-m", "edge.cli", "run", "--profile", args.profile, "--seconds", f"{args.seconds:.0f}",
           "--poses", str(args.poses), "--listen", endpoint, "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"}, cwd=ROOT)
    t0 = time.monotonic()
    samples: list[tuple[float, float]] = []
    per_subscription: list[int] = []
    next_sample = t0
    subscribed = True
    sub = None
    phase_end = t0 + args.cycle
    try:
        while proc.poll() is None:
            now = time.monotonic()
            if now >= next_sample:
                samples.append((now - t0, rss_mb(proc.pid)))
                next_sample += 5.0
            if subscribed and sub is None:
                sub = DepthSubscriber(profile.zenoh.device, connect=[endpoint])
                per_subscription.append(0)
            if now >= phase_end:
                subscribed = not subscribed
                phase_end = now + args.cycle
                if not subscribed and sub is not None:
                    sub.close()
                    sub = None
            if sub is not None:
                if sub.receive(timeout=0.2, confidence_wait=0.0) is not None:
                    per_subscription[-1] += 1
            else:
                time.sleep(0.2)
    finally:
        if sub is not None:
            sub.close()
    text, _ = proc.communicate(timeout=120)
    if len(samples) < 4:
        print(text)
        print("soak_service: run too short to measure", file=sys.stderr)
        return 1
    t = np.array([s[0] for s in samples])
    m = np.array([s[1] for s in samples])
    half = t >= t[-1] / 2
    slope = float(np.polyfit(t[half] / 60.0, m[half], 1)[0]) if half.sum() >= 2 else float("nan")
    print(f"soak {args.profile}: {t[-1]:.0f} s, subscriber cycling every {args.cycle:g} s")
    print(f"service RSS: start {m[0]:.1f} MB, end {m[-1]:.1f} MB, peak {m.max():.1f} MB, "
          f"growth over the second half {slope:+.2f} MB/min")
    print(f"depth maps per subscription: {per_subscription}")
    print(text.strip().splitlines()[-3:] and "\n".join(text.strip().splitlines()[-3:]))
    ok = all(n > 0 for n in per_subscription[1:-1]) and slope <= args.max_growth
    print("soak: " + ("OK" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
