"""Code search vs algebraic constructions: d_min reached and time per method and seed.

    python tools/bench_code_search.py [--seeds 3] [--iterations 20000] [--restarts 4] [--pairs 31x10,22x10]

For each (n, k) prints the d_min (and, in brackets, the number of minimum-weight words) reached
by the seeded tabu search over generator columns (per seed, with the median time), by the
exhaustive search over shortened/extended cyclic codes, by Poisson-disk sampling (non-linear,
n <= 22 only: it is slow), the best algebraic construction of the lookup table (`best`; for
(31, 10) the shortened extended BCH (32, 11, 12) of ``ecc-31-10``), and the Griesmer bound.
The tabu search stops early when it meets the Griesmer bound.  Timings are wall-clock on one
core after a warm-up call (numba compile excluded) and noisy on a shared machine.
"""

from __future__ import annotations

import argparse
import statistics
import time

from edge.codes import best, griesmer_bound
from edge.codes.search import poisson_disk_words, search_cyclic, search_generator_columns

PAIRS = [(15, 10), (20, 8), (22, 10), (27, 10), (31, 10), (40, 10)]


def _pairs(text: str) -> list[tuple[int, int]]:
    try:
        return [(int(a), int(b)) for a, b in (p.split("x") for p in text.split(","))]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--pairs wants NxK[,NxK...] such as 31x10,22x10; got {text!r} ({exc})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="tabu-search seeds per (n, k) (default 3)")
    parser.add_argument("--iterations", type=int, default=20000, help="tabu moves per seed, all restarts (default %(default)s)")
    parser.add_argument("--restarts", type=int, default=4, help="restarts of the tabu search per seed (default 4)")
    parser.add_argument("--pairs", type=_pairs, default=PAIRS, help="NxK list, default: " +
                        ",".join(f"{n}x{k}" for n, k in PAIRS))
    args = parser.parse_args()
    search_generator_columns(15, 10, iterations=10)  # compile / load the numba kernels
    search_cyclic(15, 10)
    print(f"tabu: {args.iterations} moves, {args.restarts} restarts per seed; d[count of weight-d words]")
    print(f"{'(n,k)':>8s} {'tabu d per seed':>30s} {'med s':>6s} {'cyclic d':>9s} {'s':>5s} "
          f"{'poisson':>7s} {'s':>5s} {'table d':>7s} {'griesmer':>8s}  table construction")
    for n, k in args.pairs:
        ds, ts = [], []
        for seed in range(args.seeds):
            t0 = time.perf_counter()
            _, d, count = search_generator_columns(n, k, seed=seed, iterations=args.iterations,
                                                   restarts=args.restarts)
            ts.append(time.perf_counter() - t0)
            ds.append(f"{d}[{count}]")
        t0 = time.perf_counter()
        cyc = search_cyclic(n, k) if n <= 64 else None
        t_cyc = time.perf_counter() - t0
        cyc_text = f"{cyc[1]}[{cyc[2]}]" if cyc else "-"
        if n <= 22 and k <= 10:
            t0 = time.perf_counter()
            poisson, t_poi = str(poisson_disk_words(n, k, darts=200_000)[1]), time.perf_counter() - t0
        else:
            poisson, t_poi = "-", float("nan")
        code = best(n, k)
        print(f"{str((n, k)):>8s} {' '.join(ds):>30s} {statistics.median(ts):6.2f} {cyc_text:>9s} "
              f"{t_cyc:5.2f} {poisson:>7s} {t_poi:5.1f} {code.d_min:7d} {griesmer_bound(n, k):8d}  "
              f"{code.construction}")


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
