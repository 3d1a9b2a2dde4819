"""The `Code` value: a codebook of projector-column bit strings and its exact properties.

A structured-light code assigns to every projector column ``j`` a string of ``n`` symbols that
the column sends over time, frame 0 first.  For binary codes the symbols are bits (0 = dark,
1 = lit); N-ary (gray-level) codes use symbols ``0..q-1``.

Linear codes also carry their generator matrix and the message of every column, so that fast
decoders can work in the message space::

    codebook[j] == (bits(messages[j]) @ generator) % q      (q prime; GF(2**m) see `Code.encode`)

where ``bits(m)`` is the k-digit base-q expansion of ``m``, most significant digit first.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Largest message length for which `min_distance` of a non-linear code is computed exhaustively
#: (all pairs of 2**k codewords).  Linear codes are exact up to `MAX_K_LINEAR`.
MAX_K_PAIRWISE = 13
MAX_K_LINEAR = 20


def int_to_digits(values: np.ndarray | int, width: int, q: int = 2) -> np.ndarray:
    """Base-q digits of integers, most significant first.

    values: int array of any shape; returns uint8 array of shape values.shape + (width,).
    """
    v = np.asarray(values, dtype=np.int64)
    powers = q ** np.arange(width - 1, -1, -1, dtype=np.int64)
    return ((v[..., None] // powers) % q).astype(np.uint8)


def digits_to_int(digits: np.ndarray, q: int = 2) -> np.ndarray:
    """Inverse of `int_to_digits`: (..., width) digits, MSB first -> int64 array (...)."""
    d = np.asarray(digits, dtype=np.int64)
    width = d.shape[-1]
    powers = q ** np.arange(width - 1, -1, -1, dtype=np.int64)
    return (d * powers).sum(axis=-1)


def gray(j: np.ndarray | int) -> np.ndarray:
    """Reflected binary Gray code of integer(s) ``j``: ``j ^ (j >> 1)``."""
    j = np.asarray(j, dtype=np.int64)
    return j ^ (j >> 1)


def inverse_gray(g: np.ndarray | int) -> np.ndarray:
    """Inverse of `gray` for integers below 2**62."""
    g = np.asarray(g, dtype=np.int64).copy()
    shift = 1
    while shift < 64:
        g ^= g >> shift
        shift <<= 1
    return g


def encode_messages(messages: np.ndarray, generator: np.ndarray, q: int = 2) -> np.ndarray:
    """Codewords of message integers: (M,) int, (k, n) generator over GF(q) -> (M, n) uint8.

    Prime q: ``digits(m) @ generator % q``.  q = 2**m > 2: product in GF(q) with the
    polynomial-basis integers of `edge.codes.gfq` (``% q`` would be wrong there).
    """
    g = np.asarray(generator, dtype=np.int64)
    digits = int_to_digits(np.asarray(messages), g.shape[0], q).astype(np.int64)
    from .gfq import field_kind, gf_matmul

    if field_kind(q) == "prime":
        return ((digits @ g) % q).astype(np.uint8)
    return gf_matmul(digits, g, q).astype(np.uint8)


def _popcount64(x: np.ndarray) -> np.ndarray:
    return np.bitwise_count(x).astype(np.int64)


def weight_distribution(codebook: np.ndarray, q: int = 2) -> np.ndarray:
    """Number of codewords of each Hamming weight (symbols != 0): int64 array of length n+1."""
    weights = (np.asarray(codebook) != 0).sum(axis=1)
    return np.bincount(weights, minlength=codebook.shape[1] + 1).astype(np.int64)


def pairwise_min_distance(codebook: np.ndarray) -> int:
    """Exhaustive minimum Hamming distance over all pairs of distinct rows.

    Exact for any code (linear or not); O(M**2) pairs, chunked so memory stays O(M * chunk).
    """
    cb = np.asarray(codebook)
    m, n = cb.shape
    if m < 2:
        return n
    best = n
    if n <= 64 and cb.max(initial=0) <= 1:
        from .words import pack_words

        packed = pack_words(cb)
        for i in range(m - 1):
            d = _popcount64(packed[i + 1:] ^ packed[i]).min()
            if d < best:
                best = int(d)
                if best == 0:
                    break
        return best
    chunk = max(1, 2**22 // max(1, m * n))
    for start in range(0, m, chunk):
        block = cb[start:start + chunk]
        d = (block[:, None, :] != cb[None, :, :]).sum(axis=2)
        rows = np.arange(block.shape[0])
        d[rows, start + rows] = n + 1
        best = min(best, int(d.min()))
    return best


def linear_min_distance(codebook: np.ndarray) -> int:
    """Minimum distance of a linear code = smallest weight of a nonzero codeword (exact)."""
    weights = (np.asarray(codebook) != 0).sum(axis=1)
    nonzero = weights[weights > 0]
    if nonzero.size != len(weights) - 1:
        raise ValueError("codebook is not linear: it must hold the zero word exactly once")
    return int(nonzero.min()) if nonzero.size else codebook.shape[1]


@dataclass(frozen=True, eq=False)
class Code:
    """A structured-light code: which symbol string each projector column sends.

    Attributes:
        name: registry name (``"ecc-22-10"``) or a descriptive name.
        family: code family (``"gray"``, ``"golay"``, ``"bch"``, ``"crc"``, ``"search"``...).
        codebook: uint8 array (q**k, n); row j is what projector column j sends, frame 0 first.
        k: message length in symbols; the code distinguishes q**k columns.
        q: alphabet size (2 for binary patterns, 3, 8, 16 for gray-level codes).
        systematic: the first k symbols of every codeword are its message (``messages[j]``).
        generator: (k, n) uint8 generator over GF(q) for linear codes, else None.
        messages: (q**k,) int64 message of every column, for linear codes; ``codebook[j] ==
            encode(messages[j])``, which is ``bits(messages[j]) @ generator % q`` for prime q
            (2, 3, ...).  For q = 2**m > 2 (GF(8), GF(16)) the symbols are polynomial-basis
            integers and the product is taken in GF(q) (`Code.encode`, `edge.codes.gfq`); plain
            ``% q`` arithmetic is wrong there.  None for non-linear codes.
        construction: a human-readable line saying how the code was built.
        order: how columns map to messages: ``"gray"`` (default), ``"binary"`` or ``"custom"``.
        d_min: minimum Hamming distance, computed exhaustively at construction.
    """

    name: str
    family: str
    codebook: np.ndarray
    k: int
    q: int = 2
    systematic: bool = False
    generator: np.ndarray | None = None
    messages: np.ndarray | None = None
    construction: str = ""
    order: str = "gray"
    promised_d_min: int | None = None
    d_min: int = field(init=False)

    def __post_init__(self) -> None:
        cb = np.ascontiguousarray(np.asarray(self.codebook, dtype=np.uint8))
        if cb.ndim != 2:
            raise ValueError(f"code {self.name!r}: codebook must be 2-D (q**k, n), got shape {cb.shape}")
        if self.q < 2:
            raise ValueError(f"code {self.name!r}: alphabet size q must be >= 2, got {self.q}")
        if cb.shape[0] != self.q**self.k:
            raise ValueError(
                f"code {self.name!r}: codebook has {cb.shape[0]} rows, expected q**k = {self.q}**{self.k}"
            )
        if cb.size and int(cb.max()) >= self.q:
            raise ValueError(f"code {self.name!r}: codebook symbols must be < q={self.q}")
        cb.setflags(write=False)
        object.__setattr__(self, "codebook", cb)
        if self.generator is not None:
            g = np.ascontiguousarray(np.asarray(self.generator, dtype=np.uint8))
            if g.shape != (self.k, cb.shape[1]):
                raise ValueError(f"code {self.name!r}: generator shape {g.shape} != (k, n) = {(self.k, cb.shape[1])}")
            g.setflags(write=False)
            object.__setattr__(self, "generator", g)
        if self.messages is not None:
            msg = np.ascontiguousarray(np.asarray(self.messages, dtype=np.int64))
            msg.setflags(write=False)
            object.__setattr__(self, "messages", msg)
        if self.generator is not None and self.messages is not None:
            if not np.array_equal(self.encode(self.messages), cb):
                raise ValueError(f"code {self.name!r}: codebook does not equal messages @ generator")
        if self.systematic:
            if self.messages is None:
                raise ValueError(f"code {self.name!r}: a systematic code needs its messages")
            if not np.array_equal(cb[:, : self.k], int_to_digits(self.messages, self.k, self.q)):
                raise ValueError(f"code {self.name!r}: first k symbols are not the message")
        object.__setattr__(self, "d_min", self._compute_d_min(cb))
        if self.promised_d_min is not None and self.d_min < self.promised_d_min:
            raise AssertionError(
                f"code {self.name!r}: construction promises d_min >= {self.promised_d_min}, "
                f"exhaustive search found {self.d_min}"
            )

    def _compute_d_min(self, cb: np.ndarray) -> int:
        if self.is_linear:
            if self.k > MAX_K_LINEAR:
                raise ValueError(f"code {self.name!r}: k={self.k} too large for exhaustive d_min (max {MAX_K_LINEAR})")
            return linear_min_distance(cb)
        if self.k > MAX_K_PAIRWISE or (self.q != 2 and self.k > 8):
            raise ValueError(
                f"code {self.name!r}: k={self.k} too large for exhaustive d_min of a non-linear code "
                f"(max {MAX_K_PAIRWISE})"
            )
        return pairwise_min_distance(cb)

    @property
    def n(self) -> int:
        """Number of frames (symbols per column)."""
        return int(self.codebook.shape[1])

    @property
    def size(self) -> int:
        """Number of codewords = number of distinguishable projector columns (q**k)."""
        return int(self.codebook.shape[0])

    def encode(self, messages: np.ndarray) -> np.ndarray:
        """Codewords of message integers with the generator, in the arithmetic of GF(q).

        messages: (M,) int -> (M, n) uint8.  For prime q this is ``digits(m) @ generator % q``;
        for q = 2**m (GF(8), GF(16)) symbols are polynomial-basis integers of `edge.codes.gfq`
        and the product is taken in GF(q) (``% q`` would be wrong there).
        """
        if self.generator is None:
            raise ValueError(f"code {self.name!r} has no generator matrix")
        return encode_messages(messages, self.generator, self.q)

    @property
    def is_linear(self) -> bool:
        return self.generator is not None and self.messages is not None

    @property
    def column_of_message(self) -> np.ndarray:
        """(q**k,) int64: inverse of `messages` (the column that sends each message)."""
        if self.messages is None:
            raise ValueError(f"code {self.name!r} is not linear: it has no messages")
        inv = np.empty(self.size, dtype=np.int64)
        inv[self.messages] = np.arange(self.size, dtype=np.int64)
        return inv

    def neighbour_distances(self) -> np.ndarray:
        """(q**k - 1,) int: Hamming distance between the codewords of columns j and j+1."""
        return (self.codebook[1:] != self.codebook[:-1]).sum(axis=1)

    def transitions_per_frame(self, columns: int | None = None) -> np.ndarray:
        """(n,) int: number of symbol changes between neighbouring columns, per frame."""
        cb = self.codebook[: columns or self.size]
        return (cb[1:] != cb[:-1]).sum(axis=0)

    def weight_distribution(self) -> np.ndarray:
        """Number of codewords of each weight 0..n (int64, length n+1)."""
        return weight_distribution(self.codebook, self.q)

    def with_name(self, name: str) -> "Code":
        """The same code under another name."""
        return Code(
            name=name, family=self.family, codebook=self.codebook, k=self.k, q=self.q,
            systematic=self.systematic, generator=self.generator, messages=self.messages,
            construction=self.construction, order=self.order, promised_d_min=self.promised_d_min,
        )

    def __repr__(self) -> str:
        q = f", q={self.q}" if self.q != 2 else ""
        return f"Code({self.name!r}, n={self.n}, k={self.k}, d_min={self.d_min}{q}, family={self.family!r})"
