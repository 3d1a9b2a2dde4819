"""Words as integers: THE packing of a word of symbols (a codeword, a received hard decision).

Bit order (one for the whole tree): symbol ``i`` of a word -- frame ``i`` of a capture,
position ``i`` of a codeword -- has weight ``q**i``; for binary words that is bit ``i`` of the
integer, so **frame 0 is the least significant bit**.  Every packed word in edge (the decoder's
codeword masks `edge.decode.tables`, the EDC membership tables and kernels `edge.edc`, the code
searches' generator rows, distance computations) is made by `pack_words` or follows its order.

Message integers are another thing: a linear code's message ``m`` expands into its k digits most
significant first (`edge.codes.code.int_to_digits` / `digits_to_int`), as in
``codebook[j] == digits(messages[j]) @ generator``.
"""

from __future__ import annotations

import functools

import numpy as np

from .code import Code

#: Longest code for which the (2**n,) membership table is built (16 MiB of int32 at n = 22).
MAX_TABLE_BITS = 22


def bit_weights(n: int) -> np.ndarray:
    """(n,) uint64 weight of each position of a binary word: ``1 << i`` (n <= 64)."""
    if not 0 <= n <= 64:
        raise ValueError(f"binary words pack n <= 64 symbols, got n={n}")
    return np.left_shift(np.uint64(1), np.arange(n, dtype=np.uint64))


def pack_words(symbols: np.ndarray, *, q: int = 2, axis: int = -1) -> np.ndarray:
    """Pack words of symbols along ``axis`` into integers: symbol i has weight q**i.

    symbols: 0..q-1 values (bool for binary is fine), n = symbols.shape[axis].  q = 2: uint64
    (n <= 64), bit i = symbol i.  q > 2: int64 (q**n < 2**63).  Result: symbols.shape without
    ``axis``.
    """
    s = np.moveaxis(np.asarray(symbols), axis, -1)
    n = s.shape[-1]
    if q == 2:
        return (s.astype(np.uint64) * bit_weights(n)).sum(axis=-1, dtype=np.uint64)
    if n * np.log2(q) >= 63:
        raise ValueError(f"words of {n} symbols over q={q} do not fit in 63 bits")
    powers = np.int64(q) ** np.arange(n, dtype=np.int64)
    return (s.astype(np.int64) * powers).sum(axis=-1, dtype=np.int64)


def unpack_words(words: np.ndarray, n: int) -> np.ndarray:
    """Inverse of `pack_words` for binary words: (...) integers -> (..., n) uint8 bits, bit i = symbol i."""
    w = np.asarray(words).astype(np.uint64)
    return ((w[..., None] >> np.arange(n, dtype=np.uint64)) & np.uint64(1)).astype(np.uint8)


@functools.lru_cache(maxsize=32)
def _packed(code: Code) -> np.ndarray:
    if code.q != 2:
        raise ValueError(f"packed codewords need a binary code, got {code.name!r} with q={code.q}")
    words = pack_words(code.codebook).astype(np.int64)
    words.setflags(write=False)
    return words


@functools.lru_cache(maxsize=32)
def _table(code: Code) -> np.ndarray:
    if code.q != 2:
        raise ValueError(f"EDC look-up needs a binary code, got {code.name!r} with q={code.q}")
    if code.n > MAX_TABLE_BITS:
        raise ValueError(f"EDC look-up supports n <= {MAX_TABLE_BITS} frames, got {code.name!r} with n={code.n}")
    words = _packed(code)
    table = np.full(1 << code.n, -1, dtype=np.int32)
    # a word sent by several columns (d_min = 0) is ambiguous: it stays -1 except for its first column
    table[words[::-1]] = np.arange(code.size - 1, -1, -1, dtype=np.int32)
    table.setflags(write=False)
    return table


def packed_codewords(code: Code) -> np.ndarray:
    """(size,) int64 codeword of each column, packed by `pack_words` (read-only, cached)."""
    return _packed(code)


def membership_table(code: Code) -> np.ndarray:
    """(2**n,) int32: column whose codeword packs (`pack_words`) to each integer, -1 if none.

    Binary codes with n <= `MAX_TABLE_BITS` (ValueError otherwise); read-only, cached per code.
    """
    return _table(code)


def columns_of_words(words: np.ndarray, code: Code) -> np.ndarray:
    """Column of each packed binary word (`pack_words` order): int32 (...), -1 where the word is
    no codeword.  A word sent by several columns maps to the first of them.

    The one codebook-membership look-up: the (2**n,) `membership_table` for n <= `MAX_TABLE_BITS`,
    a binary search over the sorted codewords for longer codes (n <= 64).
    """
    w = np.asarray(words)
    if code.q != 2:
        raise ValueError(f"packed words need a binary code, got {code.name!r} with q={code.q}")
    if code.n <= MAX_TABLE_BITS:
        return _table(code)[w.astype(np.int64)]
    book = pack_words(code.codebook)
    order = np.argsort(book, kind="stable")
    sorted_book = book[order]
    flat = w.astype(np.uint64).ravel()
    pos = np.clip(np.searchsorted(sorted_book, flat), 0, sorted_book.size - 1)
    col = np.where(sorted_book[pos] == flat, order[pos], -1).astype(np.int32)
    return col.reshape(w.shape)
