"""Small finite fields GF(p) and GF(2**m) for building generator matrices (not for decoding pixels).

Field elements are stored as integers ``0..q-1``.  For a prime ``q`` they are residues mod q.  For
``q = 2**m`` an integer is the polynomial-basis vector of the element (bit i = coefficient of
``alpha**i``) over the primitive polynomial `PRIMITIVE_POLY[m]` (the one galois uses for BCH
codes and, for GF(8) and GF(16), for ``galois.GF(2**m)``), so addition is XOR and multiplication uses log/antilog tables.

Polynomials over GF(2) are Python ints (bit i = coefficient of x**i).  Polynomials over GF(q) are
lists of field elements, lowest degree first.
"""

from __future__ import annotations

import functools

import numpy as np

#: Primitive polynomials x**m + ..., as ints with the x**m bit set: the lexicographically smallest
#: primitive polynomial of each degree (``galois.primitive_poly(2, m)``, what ``galois.BCH`` uses;
#: also ``galois.GF(2**m)``'s default except for m = 6, where GF uses the Conway polynomial).
PRIMITIVE_POLY = {
    2: 0b111,
    3: 0b1011,
    4: 0b10011,
    5: 0b100101,
    6: 0b1000011,
    7: 0b10000011,
    8: 0b100011101,
}


def is_prime(q: int) -> bool:
    return q >= 2 and all(q % p for p in range(2, int(q**0.5) + 1))


def field_kind(q: int) -> str:
    """``"prime"`` for GF(p), ``"binary-extension"`` for GF(2**m); ValueError for other q."""
    if is_prime(q):
        return "prime"
    m = q.bit_length() - 1
    if q == 1 << m and m in PRIMITIVE_POLY:
        return "binary-extension"
    raise ValueError(f"alphabet size q must be a prime or 2**m with 2 <= m <= 8, got q={q}")


@functools.lru_cache(maxsize=None)
def gf2m_tables(m: int) -> tuple[np.ndarray, np.ndarray]:
    """(exp, log) tables of GF(2**m): exp has length 2*(2**m - 1) (no wrap needed), log[0] = -1."""
    if m not in PRIMITIVE_POLY:
        raise ValueError(f"GF(2**m) supported for 2 <= m <= 8, got m={m}")
    order = (1 << m) - 1
    exp = np.zeros(2 * order, dtype=np.int64)
    log = np.full(1 << m, -1, dtype=np.int64)
    x = 1
    for i in range(order):
        exp[i] = x
        log[x] = i
        x <<= 1
        if x >> m:
            x ^= PRIMITIVE_POLY[m]
    exp[order:] = exp[:order]
    exp.setflags(write=False)
    log.setflags(write=False)
    return exp, log


def gf_mul(a: np.ndarray | int, b: np.ndarray | int, q: int) -> np.ndarray:
    """Elementwise product in GF(q) of integer arrays (broadcasting)."""
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    if field_kind(q) == "prime":
        return (a * b) % q
    exp, log = gf2m_tables(q.bit_length() - 1)
    out = exp[(log[a] + log[b]) % (q - 1)]
    return np.where((a == 0) | (b == 0), 0, out)


def gf_add(a: np.ndarray | int, b: np.ndarray | int, q: int) -> np.ndarray:
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    return (a + b) % q if field_kind(q) == "prime" else a ^ b


def gf_neg(a: np.ndarray | int, q: int) -> np.ndarray:
    a = np.asarray(a, dtype=np.int64)
    return (-a) % q if field_kind(q) == "prime" else a


def gf_inv(a: int, q: int) -> int:
    if a % q == 0:
        raise ZeroDivisionError("0 has no inverse")
    if field_kind(q) == "prime":
        return pow(int(a), q - 2, q)
    exp, log = gf2m_tables(q.bit_length() - 1)
    return int(exp[(q - 1 - log[a]) % (q - 1)])


def gf_matmul(a: np.ndarray, b: np.ndarray, q: int) -> np.ndarray:
    """Matrix product over GF(q): (r, s) @ (s, t) -> (r, t) int64 with entries 0..q-1."""
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    if field_kind(q) == "prime":
        return (a @ b) % q
    out = np.zeros((a.shape[0], b.shape[1]), dtype=np.int64)
    for i in range(a.shape[1]):
        out ^= gf_mul(a[:, i:i + 1], b[i:i + 1, :], q)
    return out


def systematic_form_q(generator: np.ndarray, q: int) -> np.ndarray:
    """Row-reduce a full-rank (k, n) generator over GF(q) to [I_k | P] (int64).

    The one Gauss-Jordan elimination of the package (`edge.codes.gf2.systematic_form` is its
    q = 2 case).  The first k columns must be an information set (ValueError otherwise; permute
    columns first, `edge.codes.linear.information_set_first`).
    """
    g = np.asarray(generator, dtype=np.int64).copy() % q
    k = g.shape[0]
    for c in range(k):
        pivot = np.nonzero(g[c:, c])[0]
        if pivot.size == 0:
            raise ValueError("generator's first k columns are not an information set; permute columns first")
        p = c + pivot[0]
        g[[c, p]] = g[[p, c]]
        if g[c, c] != 1:
            g[c] = gf_mul(g[c], gf_inv(int(g[c, c]), q), q)
        hit = np.nonzero(g[:, c])[0]
        hit = hit[hit != c]
        if hit.size:
            g[hit] = gf_add(g[hit], gf_neg(gf_mul(g[hit, c:c + 1], g[c][None, :], q), q), q)
    return g


# --- binary polynomials (ints) ---------------------------------------------------------------

def poly2_mul(a: int, b: int) -> int:
    out = 0
    while b:
        if b & 1:
            out ^= a
        a <<= 1
        b >>= 1
    return out


def poly2_mod(a: int, b: int) -> int:
    db = b.bit_length() - 1
    while a.bit_length() - 1 >= db and a:
        a ^= b << (a.bit_length() - 1 - db)
    return a


def cyclotomic_coset(i: int, n: int) -> list[int]:
    """The 2-cyclotomic coset of i mod n: {i, 2i, 4i, ...}."""
    coset, j = [], i % n
    while j not in coset:
        coset.append(j)
        j = (2 * j) % n
    return coset


def minimal_polynomial(i: int, m: int) -> int:
    """Binary minimal polynomial of alpha**i in GF(2**m), as an int (bit d = coeff of x**d)."""
    n = (1 << m) - 1
    q = 1 << m
    poly = [1]  # over GF(2**m), lowest degree first
    for j in cyclotomic_coset(i, n):
        root = int(gf2m_tables(m)[0][j])
        poly = poly_q_mul(poly, [root, 1], q)
    if any(c not in (0, 1) for c in poly):
        raise AssertionError("minimal polynomial has non-binary coefficients")
    return sum(c << d for d, c in enumerate(poly))


def poly_q_mul(a: list[int], b: list[int], q: int) -> list[int]:
    """Product of two polynomials over GF(q) (lists, lowest degree first)."""
    out = [0] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] = int(gf_add(out[i + j], gf_mul(x, y, q), q))
    return out
