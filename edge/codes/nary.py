"""N-ary (gray-level) codes: uncoded q-ary Gray patterns, ternary Golay codes, Reed-Solomon codes.

Codebook entries are symbols ``0..q-1`` (`edge.patterns.render` maps symbol s to the grey level
``round(255 * s / (q - 1))``).  Linear codes carry a generator over GF(q):

* q prime (3): symbols are residues, ``codebook == digits(messages) @ generator % q``;
* q = 2**m (8, 16): symbols are the polynomial-basis integers of GF(2**m) (`edge.codes.gfq`, same
  primitive polynomials as galois), and the product is taken in GF(q) (`Code.encode`).

Columns are arranged by the reflected q-ary Gray code of the column index: neighbouring columns
differ in one message digit, so their codewords differ in exactly the weight of one generator row.
"""

from __future__ import annotations

import numpy as np

from .code import Code, digits_to_int, encode_messages
from .gfq import PRIMITIVE_POLY, field_kind, gf2m_tables, poly_q_mul, systematic_form_q

#: Ternary Golay generator polynomial x^5 + x^4 - x^3 + x^2 - 1 over GF(3), lowest degree first.
TERNARY_GOLAY_POLY = (2, 0, 1, 2, 1, 1)
MAX_CODEWORDS = 1 << 16


def qary_gray_digits(k: int, q: int) -> np.ndarray:
    """Reflected q-ary Gray sequence: (q**k, k) uint8 digits, MSB first; consecutive rows differ in
    exactly one digit, by +-1."""
    seq = np.zeros((1, 0), dtype=np.uint8)
    for _ in range(k):
        blocks = []
        for d in range(q):
            body = seq if d % 2 == 0 else seq[::-1]
            blocks.append(np.concatenate([np.full((len(body), 1), d, dtype=np.uint8), body], axis=1))
        seq = np.concatenate(blocks, axis=0)
    return seq


def _check_size(q: int, k: int, what: str) -> None:
    if k < 1 or q**k > MAX_CODEWORDS:
        raise ValueError(f"{what}: need 1 <= k and q**k <= {MAX_CODEWORDS} codewords, got q={q}, k={k}")


def linear_qary_code(generator: np.ndarray, q: int, *, name: str, family: str, construction: str,
                     promised_d_min: int | None = None) -> Code:
    """A systematic linear code over GF(q) with q-ary Gray column order."""
    field_kind(q)
    g = systematic_form_q(generator, q).astype(np.uint8)
    k = g.shape[0]
    _check_size(q, k, name)
    messages = digits_to_int(qary_gray_digits(k, q), q)
    return Code(
        name=name, family=family, codebook=encode_messages(messages, g, q), k=k, q=q, systematic=True,
        generator=g, messages=messages, construction=construction, order="gray",
        promised_d_min=promised_d_min,
    )


def nary_code(q: int, k: int) -> Code:
    """Uncoded q-ary Gray patterns: k frames of q grey levels, q**k columns, d_min = 1."""
    if q < 3:
        raise ValueError(f"N-ary patterns need q >= 3 (use gray-K for binary), got q={q}")
    _check_size(q, k, f"nary{q}-{k}")
    return linear_qary_code(
        np.eye(k, dtype=np.int64), q, name=f"nary{q}-{k}", family="nary",
        construction=f"reflected {q}-ary Gray code, {k} digits, MSB first", promised_d_min=1,
    )


def _cyclic_generator_q(poly: list[int] | tuple[int, ...], n: int) -> np.ndarray:
    """Rows x**i g(x) over GF(q), coefficients written highest power first (g lowest first)."""
    deg = len(poly) - 1
    k = n - deg
    g = np.array(poly[::-1], dtype=np.int64)
    out = np.zeros((k, n), dtype=np.int64)
    for i in range(k):
        out[i, i:i + deg + 1] = g
    return out


def ternary_golay(extended: bool = True) -> Code:
    """Ternary Golay code (11, 6, 5), or the extended (12, 6, 6) code (parity: symbols sum to 0 mod 3)."""
    g = _cyclic_generator_q(TERNARY_GOLAY_POLY, 11)
    if extended:
        g = np.concatenate([g, (-g.sum(axis=1, keepdims=True)) % 3], axis=1)
    n = 12 if extended else 11
    return linear_qary_code(
        g, 3, name=f"ternary-golay-{n}-6", family="ternary-golay",
        construction="cyclic ternary Golay code, g(x)=x^5+x^4-x^3+x^2-1"
        + (", extended by a zero-sum parity symbol" if extended else ""),
        promised_d_min=6 if extended else 5,
    )


def reed_solomon_generator_poly(q: int, n_full: int, k_full: int) -> list[int]:
    """g(x) = prod_{i=1}^{n-k} (x - alpha**i) over GF(q), lowest degree first (galois' default c=1)."""
    exp, _ = gf2m_tables(q.bit_length() - 1)
    poly = [1]
    for i in range(1, n_full - k_full + 1):
        poly = poly_q_mul(poly, [int(exp[i]), 1], q)  # x - a == x + a in characteristic 2
    return poly


def reed_solomon(q: int, n: int, k: int) -> Code:
    """Reed-Solomon code over GF(q), q = 2**m, length n <= q - 1 (shortened from (q-1, k+q-1-n)).

    MDS: d_min = n - k + 1 (checked exhaustively).
    """
    if field_kind(q) != "binary-extension" or q.bit_length() - 1 not in PRIMITIVE_POLY:
        raise ValueError(f"Reed-Solomon codes here use GF(2**m) (q = 4, 8, 16, ...), got q={q}")
    if not 1 <= k < n <= q - 1:
        raise ValueError(f"Reed-Solomon over GF({q}) needs 1 <= k < n <= {q - 1}, got n={n}, k={k}")
    _check_size(q, k, f"rs{q}-{n}-{k}")
    shorten_by = (q - 1) - n
    n_full, k_full = q - 1, k + shorten_by
    poly = reed_solomon_generator_poly(q, n_full, k_full)
    full = systematic_form_q(_cyclic_generator_q(poly, n_full), q)
    g = full[shorten_by:, shorten_by:]
    what = f"Reed-Solomon RS({n_full},{k_full}) over GF({q})"
    if shorten_by:
        what += f", shortened by {shorten_by}"
    return linear_qary_code(g, q, name=f"rs{q}-{n}-{k}", family="reed-solomon", construction=what,
                            promised_d_min=n - k + 1)
