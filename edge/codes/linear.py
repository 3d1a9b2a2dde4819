"""Binary linear block codes built from a generator matrix, and the operations on them."""

from __future__ import annotations

import numpy as np

from .code import Code, gray
from .gf2 import all_codewords, as_ints, cyclic_generator, encode, independent, rank, systematic_form

GOLAY_23_POLY = 0b110001110101  # x^11 + x^10 + x^6 + x^5 + x^4 + x^2 + 1


def min_weight_basis(generator: np.ndarray) -> np.ndarray:
    """k linearly independent messages whose codewords have the smallest possible weights.

    Greedy over codewords sorted by weight (ties by message value): returns a (k,) int64 array of
    message integers, first = lowest weight.  When the minimum-weight codewords span the code,
    every returned codeword has weight d_min.
    """
    k = generator.shape[0]
    words = all_codewords(generator)
    weights = words.sum(axis=1)
    order = np.lexsort((np.arange(len(weights)), weights))
    nonzero = order[weights[order] > 0]
    basis = [int(nonzero[i]) for i in independent((int(m) for m in nonzero), limit=k)]
    return np.array(basis, dtype=np.int64)


def column_messages(generator: np.ndarray, order: str = "gray") -> np.ndarray:
    """Message integer of every projector column for a systematic encoder.

    ``"binary"``: column j sends message j.  ``"gray"``: a Gray walk over a minimum-weight basis,
    so that neighbouring columns differ by exactly one basis codeword (distance d_min where the
    minimum-weight codewords span the code).  ``"gray-plain"``: message gray(j) into the encoder
    (the paper's arrangement).
    """
    k = generator.shape[0]
    j = np.arange(2**k, dtype=np.int64)
    if order == "binary":
        return j
    if order == "gray-plain":
        return gray(j)
    if order == "gray":
        basis = min_weight_basis(generator)
        # Gray bit i (LSB = 0) flips most often: give it the basis word listed first.
        g = gray(j)
        out = np.zeros_like(j)
        for i, word in enumerate(basis):
            out ^= np.where((g >> i) & 1, word, 0)
        return out
    raise ValueError(f"column order must be 'gray', 'gray-plain' or 'binary', got {order!r}")


def information_set_first(generator: np.ndarray) -> np.ndarray:
    """Permute the columns of a full-rank (k, n) generator so that its first k columns are
    linearly independent (an information set); the other columns keep their relative order.

    The result generates an equivalent code (same weights, same d_min), with frames reordered.
    """
    g = np.asarray(generator, dtype=np.uint8) & 1
    k, n = g.shape
    chosen = independent(as_ints(g.T), limit=k)
    if len(chosen) < k:
        raise ValueError(f"generator of shape {g.shape} is not full rank")
    rest = [c for c in range(n) if c not in set(chosen)]
    return g[:, chosen + rest]


def from_generator(
    generator: np.ndarray,
    *,
    name: str,
    family: str,
    construction: str,
    order: str = "gray",
    promised_d_min: int | None = None,
) -> Code:
    """A systematic binary linear code from any full-rank (k, n) generator.

    If the first k columns are not an information set, the columns are permuted first
    (`information_set_first`), so the frames of the code may come in another order.
    """
    g = np.asarray(generator, dtype=np.uint8) & 1
    k, n = g.shape
    if rank(g) != k:
        raise ValueError(f"{name}: generator of shape {g.shape} is not full rank")
    if rank(g[:, :k]) != k:
        g = information_set_first(g)
    g = systematic_form(g)
    messages = column_messages(g, order)
    return Code(
        name=name, family=family, codebook=encode(messages, g), k=k, systematic=True, generator=g,
        messages=messages, construction=construction, order=order, promised_d_min=promised_d_min,
    )


def shorten(code: Code, length: int, *, name: str | None = None, order: str | None = None) -> Code:
    """Shorten a systematic binary linear code (n, k) -> (n-L, k-L): messages whose first L bits are
    0, with those L positions removed.  d_min can only grow (paper, appendix A)."""
    if not code.systematic or code.generator is None or code.q != 2:
        raise ValueError(f"only systematic binary linear codes can be shortened; {code.name!r} is not")
    if not 0 <= length < code.k:
        raise ValueError(f"shortening {code.name!r} (k={code.k}) by L={length}: need 0 <= L < k")
    g = code.generator[length:, length:]
    new = from_generator(
        g, name=name or f"{code.name}-short{length}", family=code.family,
        construction=f"{code.construction}, shortened by {length}", order=order or code.order,
        promised_d_min=code.d_min,
    )
    return new


def extend(code: Code, *, name: str | None = None) -> Code:
    """Append an overall parity bit (n, k, d) -> (n+1, k, d or d+1 when d is odd)."""
    if code.generator is None or code.q != 2:
        raise ValueError(f"only binary linear codes can be extended; {code.name!r} is not")
    g = code.generator
    parity = g.sum(axis=1, keepdims=True).astype(np.uint8) & 1
    d = code.d_min + (code.d_min % 2)
    return from_generator(
        np.concatenate([g, parity], axis=1), name=name or f"{code.name}-ext", family=code.family,
        construction=f"{code.construction}, extended by overall parity", order=code.order, promised_d_min=d,
    )


def golay(extended: bool = True, order: str = "gray") -> Code:
    """Binary Golay code (23, 12, 7), or the extended (24, 12, 8) code."""
    g = cyclic_generator(GOLAY_23_POLY, 23)
    base = from_generator(
        g, name="golay-23-12", family="golay", construction="cyclic Golay code, g(x)=x^11+x^10+x^6+x^5+x^4+x^2+1",
        order=order, promised_d_min=7,
    )
    if not extended:
        return base
    return extend(base, name="golay-24-12")

