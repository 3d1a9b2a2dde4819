"""Linear algebra over GF(2) on uint8 0/1 matrices (small k, n: plain numpy is enough)."""

from __future__ import annotations

import numpy as np


def rank(matrix: np.ndarray) -> int:
    """Rank of a 0/1 matrix over GF(2)."""
    m = (np.asarray(matrix, dtype=np.uint8) & 1).copy()
    rows, cols = m.shape
    r = 0
    for c in range(cols):
        pivot = np.nonzero(m[r:, c])[0]
        if pivot.size == 0:
            continue
        p = r + pivot[0]
        m[[r, p]] = m[[p, r]]
        hit = np.nonzero(m[:, c])[0]
        hit = hit[hit != r]
        m[hit] ^= m[r]
        r += 1
        if r == rows:
            break
    return r


def systematic_form(generator: np.ndarray) -> np.ndarray:
    """Row-reduce a full-rank (k, n) generator to [I_k | P] (raises if the first k columns are singular)."""
    g = (np.asarray(generator, dtype=np.uint8) & 1).copy()
    k = g.shape[0]
    for c in range(k):
        pivot = np.nonzero(g[c:, c])[0]
        if pivot.size == 0:
            raise ValueError("generator's first k columns are not an information set; permute columns first")
        p = c + pivot[0]
        g[[c, p]] = g[[p, c]]
        hit = np.nonzero(g[:, c])[0]
        hit = hit[hit != c]
        g[hit] ^= g[c]
    return g


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


def parity_check(generator_systematic: np.ndarray) -> np.ndarray:
    """Parity-check matrix H = [P^T | I_{n-k}] of a systematic generator [I_k | P]."""
    g = np.asarray(generator_systematic, dtype=np.uint8)
    k, n = g.shape
    p = g[:, k:]
    return np.concatenate([p.T, np.eye(n - k, dtype=np.uint8)], axis=1)


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
