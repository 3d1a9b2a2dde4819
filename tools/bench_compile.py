"""First-call (compile) time of `decode()` or of `edge run`: this tree, or against a git revision.

A fresh machine, a CI run and a first `edge run` compile every numba kernel they call; the
test suite spends most of its cold run there.  This tool times that: each run is a fresh
process with an empty numba cache (a temporary ``NUMBA_CACHE_DIR``).

* ``--target decode`` (default): the process decodes one small ecc-22-10 capture
  (`edge.decode.synthetic.make_capture`, uint8, seed 0, ``--height`` x ``--width``) with
  `decode()`'s defaults, first cold (compile and decode), then warm (median of three).
* ``--target run``: the Quick start's service on its default simulated sensor,
  ``edge run --stacks N --no-zenoh --quiet`` (``--stacks``, default 1), in a process with the
  empty cache (the first run on a fresh machine), then once more in a second process with the
  cache that run left (every later run); warm is that second run's seconds.

It prints the seconds of the first call, the warm time and, per numba function, the seconds
spent compiling it alone (numba's "numba:compile" events, the time of the functions it compiled
on the way subtracted), most first.

    python tools/bench_compile.py                      # this tree, one run
    python tools/bench_compile.py --rev HEAD~1 --rounds 2
    python tools/bench_compile.py --target run

With ``--rev`` side A is the revision (a temporary git worktree) and side B this tree, run in
alternating order; the report gives each side's median over rounds and B / A.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from revision_tree import HERE, revision_tree  # noqa: E402


class CompileTimes:
    """Exclusive compile seconds per numba function, from numba's "numba:compile" events.

    `seconds[name]` is the time between the start and end events of the compiles of `name`
    (module-qualified), minus the time of the compiles nested inside them (the callees numba
    compiled on the way); `compiles[name]` counts them (one per signature).  Records while
    entered (``with CompileTimes() as times: ...``).
    """

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.compiles: dict[str, int] = {}
        self._open: list[list[float]] = []  # [start, nested seconds] per compile in progress

    def __enter__(self) -> CompileTimes:
        from numba.core import event

        recorder = self

        class _Listener(event.Listener):
            def on_start(self, ev) -> None:
                recorder._open.append([time.perf_counter(), 0.0])

            def on_end(self, ev) -> None:
                recorder._end(ev.data.get("dispatcher"))

        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc) -> None:
        from numba.core import event

        event.unregister("numba:compile", self._listener)

    def _end(self, dispatcher) -> None:
        start, nested = self._open.pop()
        took = time.perf_counter() - start
        if self._open:
            self._open[-1][1] += took
        fn = getattr(dispatcher, "py_func", None)
        name = f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', dispatcher)}"
        self.seconds[name] = self.seconds.get(name, 0.0) + took - nested
        self.compiles[name] = self.compiles.get(name, 0) + 1


def child(height: int, width: int) -> dict:
    """One cold run in this process (the caller gives it an empty cache): the first call's
    seconds, the warm median in ms and the per-function compile seconds."""
    import numpy as np

    from edge.codes import get_code
    from edge.decode import decode
    from edge.decode.synthetic import make_capture

    code = get_code("ecc-22-10")
    rng = np.random.default_rng(0)
    cap = make_capture(code, rng.integers(0, code.size, (height, width)), rng=rng)
    with CompileTimes() as times:
        t0 = time.perf_counter()
        decode(cap.frames, cap.white, cap.black, code)
        first = time.perf_counter() - t0
    warm = []
    for _ in range(3):
        t0 = time.perf_counter()
        decode(cap.frames, cap.white, cap.black, code)
        warm.append(time.perf_counter() - t0)
    return {"first_s": first, "warm_ms": statistics.median(warm) * 1e3, "seconds": times.seconds,
            "compiles": times.compiles}


def child_run(stacks: int) -> dict:
    """One `edge run --stacks N --no-zenoh --quiet` in this process (its output to stderr): its
    seconds and the per-function compile seconds.  The warm time is the caller's second run."""
    from edge.cli import main as edge_main

    with CompileTimes() as times, contextlib.redirect_stdout(sys.stderr):
        t0 = time.perf_counter()
        rc = edge_main(["run", "--stacks", str(stacks), "--no-zenoh", "--quiet"])
        first = time.perf_counter() - t0
    if rc != 0:
        raise SystemExit(f"edge run exited with {rc}")
    return {"first_s": first, "seconds": times.seconds, "compiles": times.compiles}


def _child(root: Path, cache: str, args: list[str]) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(root), MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child", *args], cwd=root, env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"bench_compile: the run in {root} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _run_side(root: Path, args: argparse.Namespace) -> dict:
    with tempfile.TemporaryDirectory(prefix="bench-compile-cache-") as cache:
        if args.target == "decode":
            return _child(root, cache, ["--height", str(args.height), "--width", str(args.width)])
        argv = ["--target", "run", "--stacks", str(args.stacks)]
        cold = _child(root, cache, argv)
        cold["warm_ms"] = _child(root, cache, argv)["first_s"] * 1e3
        return cold


def _top(run: dict, count: int) -> list[str]:
    rows = sorted(run["seconds"].items(), key=lambda kv: -kv[1])[:count]
    return [f"  {s:7.1f} s  {run['compiles'][name]:2d} x  {name}" for name, s in rows]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rev", default=None, help="side A: a git revision to compare against (default: none, "
                                                "this tree alone)")
    ap.add_argument("--rounds", type=int, default=1, help="runs per side, alternating (default %(default)s)")
    ap.add_argument("--target", choices=("decode", "run"), default="decode",
                    help="what is timed: decode() on a small capture, or the Quick start's `edge run` on the default "
                         "simulated sensor (default %(default)s)")
    ap.add_argument("--height", type=int, default=120, help="--target decode: capture rows (default %(default)s)")
    ap.add_argument("--width", type=int, default=160, help="--target decode: capture columns (default %(default)s)")
    ap.add_argument("--stacks", type=int, default=1, help="--target run: stacks the service decodes "
                                                          "(default %(default)s)")
    ap.add_argument("--top", type=int, default=12, help="functions listed per side (default %(default)s)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if min(args.rounds, args.height, args.width, args.stacks, args.top) < 1:
        raise ValueError("--rounds, --height, --width, --stacks and --top must be at least 1")
    if args.child:
        print(json.dumps(child(args.height, args.width) if args.target == "decode" else child_run(args.stacks)))
        return 0
    runs: dict[str, list[dict]] = {"A": [], "B": []}
    with tempfile.TemporaryDirectory(prefix="bench-compile-") as tmp, contextlib.ExitStack() as stack:
        sides = {"B": HERE}
        if args.rev is not None:
            sides["A"] = Path(tmp) / "a"
            rev = stack.enter_context(revision_tree(args.rev, sides["A"]))
            print(f"A = {rev} ({args.rev}), B = this working tree", flush=True)
        for r in range(args.rounds):
            order = ("A", "B") if r % 2 == 0 else ("B", "A")
            for side in (s for s in order if s in sides):
                runs[side].append(_run_side(sides[side], args))
                print(f"  round {r + 1}, {side}: first call {runs[side][-1]['first_s']:.1f} s, warm "
                      f"{runs[side][-1]['warm_ms']:.1f} ms", flush=True)
    if args.target == "decode":
        print(f"decode() with its defaults, ecc-22-10 {args.height} x {args.width} uint8, empty numba cache:")
    else:
        print(f"edge run --stacks {args.stacks} --no-zenoh --quiet (default profile), empty numba cache; warm: a "
              f"second run on the cache the first left:")
    medians = {}
    for side in (s for s in ("A", "B") if runs[s]):
        medians[side] = statistics.median(x["first_s"] for x in runs[side])
        warm = statistics.median(x["warm_ms"] for x in runs[side])
        last = runs[side][-1]
        print(f"{side}: first call {medians[side]:.1f} s (median of {len(runs[side])}), warm {warm:.1f} ms; "
              f"compiles in the last run: {sum(last['seconds'].values()):.1f} s over {sum(last['compiles'].values())} "
              f"signatures; compile seconds per function (own time):")
        print("\n".join(_top(runs[side][-1], args.top)))
    if len(medians) == 2:
        print(f"B / A first call: {medians['B'] / medians['A']:.2f}")
    return 0


if __name__ == "__main__":
    if "--child" in sys.argv:  # runs on the compared revision's edge, which may predate tool_main
        sys.exit(main())
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
