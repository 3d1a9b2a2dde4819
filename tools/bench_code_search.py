"""Code search vs algebraic constructions: d_min reached and time per search.

    python tools/bench_code_search.py [--seeds 3] [--iterations 20000]

For each (n, k) prints the d_min of the seeded local search (median time over seeds), the
Poisson-disk sampler for small n, the best algebraic construction of the table (`best`) and the
Griesmer bound.  The paper's (31, 10, 12) is the shortened extended BCH (32, 11, 12).
Timings are noisy on a shared machine.
"""

from __future__ import annotations

import argparse
import statistics
import time

from edge.codes import best, griesmer_bound
from edge.codes.search import poisson_disk_words, search_parity_columns

PAIRS = [(15, 10), (20, 8), (22, 10), (27, 10), (31, 10), (40, 10)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--iterations", type=int, default=20000)
    args = parser.parse_args()
    print(f"{'(n,k)':>8s} {'search d (per seed)':>22s} {'median s':>8s} {'poisson d':>9s} {'table d':>7s} "
          f"{'griesmer':>8s}  table construction")
    for n, k in PAIRS:
        ds, ts = [], []
        for seed in range(args.seeds):
            t0 = time.perf_counter()
            _, d = search_parity_columns(n, k, seed=seed, iterations=args.iterations)
            ts.append(time.perf_counter() - t0)
            ds.append(d)
        poisson = poisson_disk_words(n, k, darts=200_000)[1] if n <= 22 else "-"
        code = best(n, k)
        print(f"{str((n, k)):>8s} {str(ds):>22s} {statistics.median(ts):8.2f} {str(poisson):>9s} {code.d_min:7d} "
              f"{griesmer_bound(n, k):8d}  {code.construction}")


if __name__ == "__main__":
    main()
