"""A/B of the CPU search kernels between this checkout and another one (e.g. before a refactor).

    python tools/bench_decode_ab.py --base ../edge-before [--pairs 5] [--repeats 7]

Each run is a fresh process that imports `edge` from one checkout (its own numba cache,
``<checkout>/.numba_cache``; warm it first, e.g. with tools/bench_decode.py) and times
`edge.decode.backends.cpu.search` (lane search, 128-column band) and `.hard` on
tools/bench_decode.py's input (ecc-22-10, 600 x 700 uint8): median process CPU time of --repeats
calls after one untimed call.  Runs alternate between the checkouts, the order flipping every
pair, so both see the same machine state; the last lines are the medians over all runs.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def child(repeats: int) -> int:
    """Time the searches of the `edge` first on sys.path; print one JSON line (ms per call)."""
    root = os.environ["EDGE_AB_ROOT"]
    sys.path.insert(0, root)
    from tools.bench_decode import make_input  # the checkout's own input (same in both)
    from edge.decode.backends import cpu
    from edge.decode.inputs import validate

    code, _, cap = make_input(600, 700, 128, 0)
    st = validate(cap.frames, cap.white, cap.black, code)
    kw = dict(metric=0, sigma_r=0.01, sigma_s=0.03, columns=code.size, stripe=1)
    calls = {"lanes": lambda: cpu.search(st, code, band=(False, 0, 0), **kw),
             "band": lambda: cpu.search(st, code, band=(True, 0, 127), **kw),
             "hard": lambda: cpu.hard(st, code, columns=code.size, band=(False, 0, 0), stripe=1)}
    out = {}
    for name, fn in calls.items():
        fn()
        ts = []
        for _ in range(repeats):
            t0 = time.process_time()
            fn()
            ts.append(time.process_time() - t0)
        out[name] = 1000 * statistics.median(ts)
    print(json.dumps(out))
    return 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--base", type=Path, help="the other checkout (its repository root; required)")
    p.add_argument("--pairs", type=int, default=5, help="runs per checkout (default 5)")
    p.add_argument("--repeats", type=int, default=7, help="timed calls per run (default 7)")
    p.add_argument("--_child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args._child:
        return child(args.repeats)
    base = args.base.resolve() if args.base is not None else None
    if base is None or not (base / "edge" / "decode").is_dir():
        print(f"bench_decode_ab: error: --base: expected a checkout of edge, got {base}", file=sys.stderr)
        return 2
    results: dict[str, list[dict]] = {"base": [], "this": []}
    for i in range(args.pairs):
        order = [("base", base), ("this", HERE)] if i % 2 == 0 else [("this", HERE), ("base", base)]
        for label, root in order:
            env = dict(os.environ, PYTHONPATH=str(root), EDGE_AB_ROOT=str(root),
                       NUMBA_CACHE_DIR=str(root / ".numba_cache"))
            r = subprocess.run([sys.executable, __file__, "--_child", "--repeats", str(args.repeats)],
                               env=env, capture_output=True, text=True)
            if r.returncode != 0:
                print(f"bench_decode_ab: error: the run in {root} failed:\n{r.stderr.strip()}", file=sys.stderr)
                return 1
            res = json.loads(r.stdout.strip().splitlines()[-1])
            results[label].append(res)
            print(f"{label:<4} " + "  ".join(f"{k} {v:7.1f} ms" for k, v in res.items()), flush=True)
    for label, runs in results.items():
        med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
        print(f"median {label:<4} " + "  ".join(f"{k} {v:7.1f} ms" for k, v in med.items()))
    return 0


if __name__ == "__main__":
    if "--_child" in sys.argv:  # runs on the compared revision's edge, which may predate tool_main
        raise SystemExit(main())
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
