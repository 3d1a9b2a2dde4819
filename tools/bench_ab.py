"""A/B benchmark of `decode()` and the service's stack decode: this tree against a git revision.

This machine's speed drifts by 10-20 % between runs, more than many changes gain, so two
benchmark runs minutes apart cannot compare revisions.  This tool alternates them: each round
runs every case once per side in a fresh process (side A: the revision, checked out into a
temporary git worktree; side B: this working tree), in alternating order, and reports per case
the median over rounds of each side's median, their ratio (B / A), and whether both sides'
outputs agree (column and valid mask equal; P(wrong) equal where it is below 1/2, the range
the error rule states exactly).

    python tools/bench_ab.py --rev HEAD~1 --rounds 4 --repeats 3

Cases: "easy" and "hard" (`tools/bench_decode.py`'s two 600 x 700 inputs, `decode()` with its
defaults), "easy-median" and "easy-sgm" (the easy input with ``method="median"`` / ``"sgm"``: the
spatial paths, which the defaults do not run; "median" on the exact top-3 search), "hard-band" (the same in its disparity band), "service" (`DepthPipeline.process`
of a `sim-dlp` stack from the simulated sensor) and "real" (the real OpenCV Gray-code capture,
``--real``, pattern + inverse frames, `decode()` with its defaults: the confidence rule and its
goodness-of-fit test; in the default cases where the folder is there).  Each side compiles into its own numba cache
(the revision's under the temporary directory; this tree's is ``NUMBA_CACHE_DIR`` where set);
no compile is timed: every run calls each case once before it times it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from real_data import REAL_CAPTURE  # noqa: E402
from revision_tree import revision_tree  # noqa: E402

CASES = ("easy", "easy-median", "easy-sgm", "hard", "hard-band", "service", "real")
#: The real capture beside the repository (`tools/real_data.py`).
REAL = REAL_CAPTURE


def _digest(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def _decoded_digest(d) -> str:
    error = np.asarray(d.error, np.float32) if d.error is not None else np.zeros(1, np.float32)
    return _digest(np.asarray(d.column, np.int32), np.asarray(d.valid, bool),
                   np.where(error < 0.5, error, np.float32(1.0)))


def child(cases: list[str], repeats: int, real: Path) -> dict:
    """Run in the side's tree (cwd): {case: {"median_s": ..., "digest": ...}}."""
    sys.path.insert(0, str(Path.cwd() / "tools"))
    sys.path.insert(0, str(Path.cwd()))
    import bench_decode as B

    from edge.decode import decode

    jobs = {}
    if {"easy", "easy-median", "easy-sgm"} & set(cases):
        code, _, cap = B.make_input(600, 700, 128, 0)
        jobs["easy"] = lambda: decode(cap.frames, cap.white, cap.black, code)
        jobs["easy-median"] = lambda: decode(cap.frames, cap.white, cap.black, code, method="median")
        jobs["easy-sgm"] = lambda: decode(cap.frames, cap.white, cap.black, code, method="sgm")
    if "hard" in cases or "hard-band" in cases:
        hcode, _, hard, (lo, hi) = B.make_hard_input(600, 700, 0)
        jobs["hard"] = lambda: decode(hard.frames, hard.white, hard.black, hcode, bit_depth=12)
        jobs["hard-band"] = lambda: decode(hard.frames, hard.white, hard.black, hcode, bit_depth=12,
                                           min_disparity=lo, max_disparity=hi)
    if "service" in cases:
        from edge.profiles import load_profile
        from edge.runtime.assembly import StackAssembler
        from edge.runtime.pipeline import DepthPipeline
        from edge.sensors.sim import SimSensor

        profile = load_profile("sim-dlp")
        pipe = DepthPipeline(profile)
        sensor = SimSensor(profile, stacks=1, max_speed=True)
        sensor.start()
        try:
            asm, stack = StackAssembler(pipe.schedule), None
            while stack is None:
                frame = sensor.read(5.0)
                stack = asm.push(frame) if frame is not None else None
        finally:
            sensor.stop()
        pipe.warm_up()

        class _Depth:  # the digest's fields, from the published depth map
            def __init__(self, r):
                self.column, self.valid, self.error = r.depth_mm, r.depth_mm > 0, None

        jobs["service"] = lambda: _Depth(pipe.process(stack))
    if "real" in cases:
        from edge.decode import load_opencv_graycode

        rc = load_opencv_graycode(real, (1024, 768))
        jobs["real"] = lambda: decode(rc.frames, rc.white, rc.black, rc.code, columns=rc.columns, inverse=rc.inverse)
    out = {}
    for name in cases:
        fn = jobs[name]
        result = fn()  # warm: compile or load from the cache
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        out[name] = {"median_s": statistics.median(times), "digest": _decoded_digest(result)}
    return out


def _run_side(root: Path, cache: Path, cases: list[str], repeats: int, real: Path) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(root), MPLBACKEND="Agg")
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--repeats", str(repeats), "--real", str(real),
           "--cases", *cases]
    proc = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"bench_ab: the run in {root} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rev", default="HEAD", help="side A: the git revision to compare against (default HEAD)")
    ap.add_argument("--rounds", type=int, default=4,
                    help="alternating rounds (each side once per round; default %(default)s)")
    ap.add_argument("--repeats", type=int, default=3, help="timed calls per case in each run (default %(default)s)")
    ap.add_argument("--cases", nargs="+", choices=CASES, default=None,
                    help=f"what to time (default: all, {' '.join(CASES)}; 'real' only where --real is there)")
    ap.add_argument("--real", type=Path, default=REAL,
                    help="the real capture folder of the 'real' case (default: the repository's ../shared/data/"
                         "procam-graycode/capture_0)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.cases, args.repeats, args.real)))
        return 0
    real = args.real.resolve()  # side A runs in a temporary worktree: an absolute path
    if args.cases is None:
        args.cases = [c for c in CASES if c != "real" or real.is_dir()]
    elif "real" in args.cases and not real.is_dir():
        raise ValueError(f"--real: {args.real} is not a folder (the 'real' case needs the capture)")
    here = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory(prefix="bench-ab-") as tmp, revision_tree(args.rev, Path(tmp) / "a") as rev:
        own = os.environ.get("NUMBA_CACHE_DIR")  # this tree's cache where one is set
        sides = {"A": (Path(tmp) / "a", Path(tmp) / "cache-a"),
                 "B": (here, Path(own) if own else Path(tmp) / "cache-b")}
        print(f"A = {rev} ({args.rev}), B = this working tree; {args.rounds} rounds x "
              f"{args.repeats} repeats, cases {' '.join(args.cases)}", flush=True)
        runs: dict[str, list[dict]] = {"A": [], "B": []}
        for r in range(args.rounds):
            for side in (("A", "B") if r % 2 == 0 else ("B", "A")):
                runs[side].append(_run_side(*sides[side], args.cases, args.repeats, real))
            print(f"  round {r + 1}: " + "  ".join(
                f"{c} {runs['A'][-1][c]['median_s'] * 1e3:.0f}/{runs['B'][-1][c]['median_s'] * 1e3:.0f} ms"
                for c in args.cases), flush=True)
    print(f"{'case':<12} {'A median':>10} {'B median':>10} {'B / A':>7}  outputs")
    for c in args.cases:
        a = statistics.median(x[c]["median_s"] for x in runs["A"])
        b = statistics.median(x[c]["median_s"] for x in runs["B"])
        same = len({x[c]["digest"] for x in runs["A"] + runs["B"]}) == 1
        print(f"{c:<12} {a * 1e3:8.1f} ms {b * 1e3:8.1f} ms {b / a:7.2f}  {'equal' if same else 'DIFFER'}")
    return 0


if __name__ == "__main__":
    if "--child" in sys.argv:  # runs on the compared revision's edge, which may predate tool_main
        raise SystemExit(main())
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
