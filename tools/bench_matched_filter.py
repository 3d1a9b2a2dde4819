"""Benchmark the source-code matched filters against plain-numpy baselines (same process).

    python tools/bench_matched_filter.py [--repeats 7] [--events 4000000]

Frames: despread of a 640x480 stack of L slots (L = 4 and 8), uint8.  Events: filter_events on a
synthetic 640x480 stream (own coded dots + background), events per second on the cores numba uses
(NUMBA_NUM_THREADS; target >= 10 M events/s on 2 cores).  Prints medians and ratios.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from edge.codes.source import source_code, spread  # noqa: E402
from edge.source.events import make_events  # noqa: E402
from edge.source.matched_filter import despread, despread_numpy, filter_events, filter_events_numpy  # noqa: E402


def median_time(fn, repeats: int) -> float:
    fn()  # warm-up (numba compile / cache load)
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def synthetic_events(n: int, w: int, h: int, code, slot_us: int, rng) -> np.ndarray:
    """A coded dot stream: 8% of pixels are dots; at every code edge each dot fires a burst of 3 events
    (jittered); 10% background events at random pixels and times."""
    tr = code.transitions
    edges = np.flatnonzero(tr)
    period = code.length * slot_us
    dots = np.flatnonzero(rng.random(w * h) < 0.08)
    per_period = dots.size * edges.size * 3
    n_bg = n // 10
    periods = max(1, (n - n_bg) // per_period)
    parts = []
    for k in range(periods):
        for e in edges:
            pix = np.repeat(dots, 3)
            t = k * period + e * slot_us + 50 + np.repeat([0, 20, 40], dots.size).reshape(3, -1).T.ravel()
            t = t + rng.integers(-10, 10, t.size)
            parts.append(make_events(pix % w, pix // w, t, np.full(t.size, tr[e])))
    parts.append(make_events(rng.integers(0, w, n_bg), rng.integers(0, h, n_bg),
                             rng.integers(0, periods * period, n_bg), rng.choice([-1, 1], n_bg)))
    ev = np.concatenate(parts)
    return ev[np.argsort(ev["t"], kind="stable")]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7, help="timed runs; medians are reported (default 7)")
    ap.add_argument("--events", type=int, default=4_000_000, help="events in the synthetic stream (default 4000000)")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    print(f"numba threads: {numba.get_num_threads()}  (cpu count {os.cpu_count()}; timings are noisy on shared machines)")
    print("frames: despread 640x480, uint8")
    for bits in ("1101", "10100010"):
        code = source_code(bits)
        on = rng.random((1, 480, 640)) < 0.5
        slots = np.clip(spread(on.astype(np.float32), code) * 150 + 30 + rng.normal(0, 2, (code.length, 480, 640)), 0, 255).astype(np.uint8)
        t_nb = median_time(lambda: despread(slots, code), args.repeats)
        t_np = median_time(lambda: despread_numpy(slots, code), max(3, args.repeats // 2))
        print(f"  L={code.length}: numba {t_nb * 1e3:7.2f} ms  numpy {t_np * 1e3:7.2f} ms  ratio {t_np / t_nb:5.1f}x  "
              f"({code.length / t_nb:,.0f} slot frames/s)")
    code = source_code("10100010")
    ev = synthetic_events(args.events, 640, 480, code, 1000, rng)
    kw = dict(width=640, height=480, slot_us=1000)
    t_nb = median_time(lambda: filter_events(ev, code, **kw), args.repeats)
    t_np = median_time(lambda: filter_events_numpy(ev, code, **kw), 1)
    keep = filter_events(ev, code, **kw).keep
    same = np.array_equal(keep, filter_events_numpy(ev, code, **kw))
    print(f"events: filter_events 640x480, {ev.size:,} events, code {code.string}, kept {keep.mean():.3f}, numba==numpy: {same}")
    print(f"  numba {t_nb * 1e3:7.1f} ms = {ev.size / t_nb / 1e6:6.1f} M events/s   numpy {t_np * 1e3:7.1f} ms = "
          f"{ev.size / t_np / 1e6:5.2f} M events/s   ratio {t_np / t_nb:5.1f}x   (target >= 10 M events/s)")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
