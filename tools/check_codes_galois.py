"""Cross-check edge's own BCH / Reed-Solomon generator polynomials and d_min against galois.

    python tools/check_codes_galois.py

galois JIT-compiles per field (seconds per code), which is why edge builds generators itself and
the unit tests hold the galois values as constants.  Prints one line per code and exits 1 on any
mismatch.
"""

from __future__ import annotations

import argparse

from edge.codes import get_code
from edge.codes.families import bch_generator_poly
from edge.codes.nary import reed_solomon_generator_poly


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args(argv)  # --help; no options
    import galois  # an optional check: --help works without it

    bad = 0
    for n, k in [(15, 7), (15, 5), (31, 11), (31, 16), (63, 10), (63, 16)]:
        ref = galois.BCH(n, k)
        poly, delta = bch_generator_poly(n, k)
        ok = int(ref.generator_poly) == poly and ref.d == delta and get_code(f"bch-{n}-{k}").d_min >= ref.d
        bad += not ok
        print(f"BCH({n},{k}): galois d={ref.d} g=0x{int(ref.generator_poly):x}  edge g=0x{poly:x} "
              f"designed {delta}, exact d_min {get_code(f'bch-{n}-{k}').d_min}  {'ok' if ok else 'MISMATCH'}")
    for q, n, k in [(8, 7, 3), (16, 15, 11), (16, 15, 4)]:
        ref = galois.ReedSolomon(n, k, field=galois.GF(q))
        ref_poly = [int(c) for c in ref.generator_poly.coeffs[::-1]]
        ok = ref_poly == reed_solomon_generator_poly(q, n, k)
        if q**k <= 1 << 16:
            ok = ok and get_code(f"rs{q}-{n}-{k}").d_min == ref.d
        bad += not ok
        print(f"RS({n},{k}) over GF({q}): galois d={ref.d} g={ref_poly}  {'ok' if ok else 'MISMATCH'}")
    return 1 if bad else 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
