"""Linear algebra over GF(2) on uint8 0/1 matrices (small k, n: plain numpy is enough)."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


def as_ints(vectors: np.ndarray) -> list[int]:
    """Rows of a 0/1 matrix as Python integers (any length; first entry = most significant)."""
    m = np.asarray(vectors, dtype=np.uint8) & 1
    return [int.from_bytes(np.packbits(row).tobytes(), "big") >> (-m.shape[1] % 8) for row in m]


def independent(vectors: Iterable[int], limit: int | None = None) -> list[int]:
    """Indices of the GF(2) vectors (Python ints) that are independent of the ones before them.

    The one incremental elimination of the package: each vector is reduced against the basis kept
    so far (by leading bit); a vector that does not reduce to 0 joins it.  Stops after ``limit``
    independent vectors.  ``len(independent(v))`` is the rank of the span.
    """
    chosen: list[int] = []
    basis: dict[int, int] = {}  # leading bit -> reduced vector
    for i, v in enumerate(vectors):
        v = int(v)
        while v:
            lead = v.bit_length() - 1
            if lead in basis:
                v ^= basis[lead]
            else:
                basis[lead] = v
                chosen.append(i)
                break
        if limit is not None and len(chosen) >= limit:
            break
    return chosen


def rank(matrix: np.ndarray) -> int:
    """Rank of a 0/1 matrix over GF(2)."""
    m = np.asarray(matrix)
    if m.size == 0:
        return 0
    return len(independent(as_ints(m)))


def systematic_form(generator: np.ndarray) -> np.ndarray:
    """Row-reduce a full-rank (k, n) generator to [I_k | P] (uint8; raises if the first k columns are
    singular): `edge.codes.gfq.systematic_form_q` over GF(2)."""
    from .gfq import systematic_form_q

    return systematic_form_q(np.asarray(generator, dtype=np.uint8) & 1, 2).astype(np.uint8)


def encode(messages: np.ndarray, generator: np.ndarray) -> np.ndarray:
    """Codewords of message integers: (M,) int -> (M, n) uint8, message bits MSB first."""
    from .code import int_to_digits

    k = generator.shape[0]
    bits = int_to_digits(messages, k, 2).astype(np.int64)
    return ((bits @ generator.astype(np.int64)) & 1).astype(np.uint8)


def all_codewords(generator: np.ndarray) -> np.ndarray:
    """All 2**k codewords in message order: (2**k, n) uint8."""
    k = generator.shape[0]
    return encode(np.arange(2**k, dtype=np.int64), generator)


def poly_to_bits(poly: int, degree: int) -> np.ndarray:
    """Coefficients of a binary polynomial, highest degree first: (degree+1,) uint8."""
    return np.array([(poly >> (degree - i)) & 1 for i in range(degree + 1)], dtype=np.uint8)


def cyclic_generator(generator_poly: int, n: int) -> np.ndarray:
    """Non-systematic (k, n) generator of the cyclic code with generator polynomial g(x).

    Row i holds x**i * g(x); coefficients are written highest power first so that reversing is
    not needed for systematic reduction.
    """
    deg = generator_poly.bit_length() - 1
    k = n - deg
    g = poly_to_bits(generator_poly, deg)
    out = np.zeros((k, n), dtype=np.uint8)
    for i in range(k):
        out[i, i:i + deg + 1] = g
    return out
