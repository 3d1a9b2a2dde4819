"""Classic binary linear code families: Hamming, Reed-Muller, BCH (and their extended versions).

Generator matrices are built here from first principles (GF(2**m) tables in `gfq`); galois gives
the same generator polynomials (checked in the tests) but takes seconds to JIT per code.
Every builder returns a systematic `Code` whose d_min is computed exhaustively (k <= 20).
"""

from __future__ import annotations

import functools
import itertools
import numpy as np

from .code import Code
from .gf2 import cyclic_generator
from .gfq import PRIMITIVE_POLY, cyclotomic_coset, minimal_polynomial, poly2_mul
from .linear import extend, from_generator

BCH_LENGTHS = (7, 15, 31, 63, 127)


def hamming_generator(m: int) -> np.ndarray:
    """(2**m - 1 - m, 2**m - 1) generator of the cyclic Hamming code (g(x) = primitive polynomial)."""
    if m not in PRIMITIVE_POLY or m < 2:
        raise ValueError(f"Hamming codes need 2 <= m <= 8 (n = 2**m - 1), got m={m}")
    return cyclic_generator(PRIMITIVE_POLY[m], (1 << m) - 1)


def hamming(m: int, *, extended: bool = False, order: str = "gray") -> Code:
    """Hamming code (2**m-1, 2**m-1-m, 3), or the extended (2**m, 2**m-1-m, 4) code."""
    n = (1 << m) - 1
    base = from_generator(
        hamming_generator(m), name=f"hamming-{n}-{n - m}", family="hamming",
        construction=f"cyclic Hamming code, g(x) = primitive polynomial of GF(2^{m})", order=order,
        promised_d_min=3,
    )
    return extend(base, name=f"ext-hamming-{n + 1}-{n - m}") if extended else base


def reed_muller_generator(r: int, m: int) -> np.ndarray:
    """(sum_{i<=r} C(m,i), 2**m) generator of RM(r, m): evaluations of all monomials of degree <= r
    at the points of GF(2)**m (point index bits = variables)."""
    if not (1 <= m <= 10 and 0 <= r <= m):
        raise ValueError(f"RM(r, m) needs 0 <= r <= m <= 10, got r={r}, m={m}")
    points = np.arange(1 << m)
    var = [((points >> i) & 1).astype(np.uint8) for i in range(m)]
    rows = []
    for degree in range(r + 1):
        for subset in itertools.combinations(range(m), degree):
            row = np.ones(1 << m, dtype=np.uint8)
            for i in subset:
                row &= var[i]
            rows.append(row)
    return np.array(rows, dtype=np.uint8)


def reed_muller(r: int, m: int, *, order: str = "gray") -> Code:
    """Reed-Muller code RM(r, m): (2**m, sum_{i<=r} C(m, i), 2**(m-r))."""
    return from_generator(
        reed_muller_generator(r, m), name=f"rm-{r}-{m}", family="reed-muller",
        construction=f"Reed-Muller RM({r},{m}): monomials of degree <= {r} in {m} variables",
        order=order, promised_d_min=1 << (m - r),
    )


@functools.lru_cache(maxsize=None)
def bch_table(n: int) -> tuple[tuple[int, int, int], ...]:
    """Narrow-sense primitive binary BCH codes of length n = 2**m - 1.

    Returns ((k, designed_distance, generator_poly), ...) for every distinct dimension 1 <= k < n,
    each with its largest designed distance, sorted by decreasing k.
    """
    m = n.bit_length()
    if n not in BCH_LENGTHS:
        raise ValueError(f"BCH length must be one of {BCH_LENGTHS}, got n={n}")
    out: dict[int, tuple[int, int]] = {}
    used: set[int] = set()
    poly = 1
    for delta in range(2, n + 1):
        # designed distance delta: roots alpha^1 .. alpha^(delta-1)
        i = delta - 1
        coset = min(cyclotomic_coset(i, n))
        if coset not in used:
            used.add(coset)
            poly = poly2_mul(poly, minimal_polynomial(i, m))
        k = n - (poly.bit_length() - 1)
        if k < 1:
            break
        out[k] = (delta, poly)
    return tuple((k, d, p) for k, (d, p) in sorted(out.items(), reverse=True))


def bch_generator_poly(n: int, k: int) -> tuple[int, int]:
    """(generator polynomial, designed distance) of the BCH code (n, k); ValueError if none."""
    for kk, delta, poly in bch_table(n):
        if kk == k:
            return poly, delta
    dims = ", ".join(str(kk) for kk, _, _ in bch_table(n))
    raise ValueError(f"no binary BCH code ({n}, {k}); dimensions for n={n}: {dims}")


def bch_generator(n: int, k: int) -> np.ndarray:
    """(k, n) non-systematic generator of the BCH code (rows x**i g(x))."""
    poly, _ = bch_generator_poly(n, k)
    return cyclic_generator(poly, n)


def bch(n: int, k: int, *, extended: bool = False, order: str = "gray") -> Code:
    """Binary narrow-sense BCH code (n, k, >= designed distance); extended adds overall parity."""
    poly, delta = bch_generator_poly(n, k)
    base = from_generator(
        cyclic_generator(poly, n), name=f"bch-{n}-{k}", family="bch",
        construction=f"BCH({n},{k}) designed distance {delta}, g(x)=0x{poly:x}", order=order,
        promised_d_min=delta,
    )
    return extend(base, name=f"ext-bch-{n + 1}-{k}") if extended else base
