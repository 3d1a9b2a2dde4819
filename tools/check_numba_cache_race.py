"""Processes that share numba's on-disk cache: does a load ever return another signature's code?

    python tools/check_numba_cache_race.py [--processes 2] [--saves 150] [--trials 3] [--kib 200]

Each trial starts ``--processes`` processes on one fresh cache directory.  Process p saves
``--saves`` entries (keys (p, 0), (p, 1), ...: what numba does for each newly compiled signature
of one function, `numba.core.caching.IndexDataCacheFile.save`, with a ``--kib`` KiB payload, the
size of a small kernel's object code) and after each save loads back its own key and the
other processes' key of the same round.  A load that returns an entry whose key is not the one
asked for is *wrong*: numba would run machine code compiled for other argument types.  A load
that finds nothing is fine (that process compiles again).

Two columns per trial: plain numba, and with `edge.numba_cache.install` (the lock every edge
process uses).  The edge column must be 0 (exit code 1 otherwise); the plain column shows
whether the installed numba still has the race (numba issue #10128).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: The cache entry's file stem: one function, as numba names it (qualname-line.pyXY).
STEM = "kernel-10.py311"


def _worker(path: str, wid: int, processes: int, saves: int, kib: int, locked: bool, start, out) -> None:
    from numba.core.caching import IndexDataCacheFile

    from edge.numba_cache import install

    install()
    save, load = IndexDataCacheFile.save, IndexDataCacheFile.load
    if not locked:  # numba's own methods, under the lock's wrappers
        save, load = save.__wrapped__, load.__wrapped__
    payload = b"x" * (kib * 1024)
    wrong = 0
    start.wait()  # every process imported and ready: the saves overlap from the first
    for r in range(saves):
        key = (wid, r)
        save(IndexDataCacheFile(path, STEM, ("stamp", 1)), key, (key, payload))
        for other in range(processes):
            asked = (other, r)
            got = load(IndexDataCacheFile(path, STEM, ("stamp", 1)), asked)
            if got is not None and got[0] != asked:
                wrong += 1
    out.put(wrong)


def wrong_loads(processes: int = 2, saves: int = 150, kib: int = 200, locked: bool = True) -> int:
    """Wrong loads of one trial (see the module docstring) in a fresh temporary cache."""
    # fork: the children need not import this script by name (it is not a package); spawn elsewhere
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    with tempfile.TemporaryDirectory() as path:
        out = ctx.Queue()
        start = ctx.Barrier(processes)
        procs = [ctx.Process(target=_worker, args=(path, w, processes, saves, kib, locked, start, out))
                 for w in range(processes)]
        for p in procs:
            p.start()
        counts = [out.get(timeout=300) for _ in procs]
        for p in procs:
            p.join()
            if p.exitcode != 0:
                raise RuntimeError(f"a worker process failed (exit code {p.exitcode})")
    return sum(counts)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--processes", type=int, default=2, help="processes sharing the cache (default 2)")
    ap.add_argument("--saves", type=int, default=150, help="entries each process saves (default 150)")
    ap.add_argument("--trials", type=int, default=3, help="trials per column (default 3)")
    ap.add_argument("--kib", type=int, default=200, help="payload per entry in KiB (default 200)")
    args = ap.parse_args(argv)
    if min(args.processes, args.saves, args.trials, args.kib) < 1:
        print("check_numba_cache_race: --processes, --saves, --trials and --kib must be >= 1", file=sys.stderr)
        return 2
    import numba

    from edge import numba_cache

    if numba_cache.fcntl is None:
        print("check_numba_cache_race: the lock needs fcntl (a POSIX system)", file=sys.stderr)
        return 2
    print(f"numba {numba.__version__}; {args.processes} processes x {args.saves} saves of {args.kib} KiB, "
          f"{args.trials} trials; wrong loads per trial:")
    print("| trial | plain numba | with edge.numba_cache |")
    print("|---|---|---|")
    failed = False
    for t in range(args.trials):
        plain = wrong_loads(args.processes, args.saves, args.kib, locked=False)
        locked = wrong_loads(args.processes, args.saves, args.kib, locked=True)
        failed |= locked > 0
        print(f"| {t} | {plain} | {locked} |", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
