"""Named codes: ``get_code("ecc-22-10")`` and friends.

Name grammar (K = message bits, N = frames):

* uncoded: ``binary-K``, ``gray-K``, ``xor02-K``, ``xor04-K`` (1 <= K <= 16)
* error-correcting: ``ecc-N-K`` = the best code of the lookup table (`edge.codes.best`); the
  paper's codes have fixed constructions: ``ecc-15-10`` (extended Hamming (16,11,4) shortened),
  ``ecc-22-10`` (extended Golay shortened), ``ecc-31-10`` (extended BCH (32,11,12) shortened),
  ``ecc-63-10`` (BCH (63,10,27)); ``ecc-(K+12)-K`` (6 <= K <= 12) is always the shortened extended Golay code.
* families: ``hamming-N-K``, ``ext-hamming-N-K``, ``bch-N-K``, ``ext-bch-N-K``, ``rm-R-M``,
  ``golay-23-12``, ``golay-24-12``; search: ``search-N-K`` (seed 0), ``poisson-N-K``
* CRC: ``BASE+crcW`` (default polynomial of `crc.DEFAULT_POLY`, CRC-5 = 0x15) or
  ``BASE+crcW-0xHEX`` (polynomial without or with its leading term), BASE any name above
* N-ary: ``naryQ-K`` (uncoded q-ary Gray), ``ternary-golay-11-6``, ``ternary-golay-12-6``,
  ``rs8-N-K`` (N <= 7), ``rs16-N-K`` (N <= 15)
"""

from __future__ import annotations

import functools
import math
import re
from typing import Callable

from .code import Code
from .crc import DEFAULT_POLY, crc_code
from .families import bch, hamming, reed_muller
from .gray import binary_code, gray_code, xor_code
from .linear import golay, shorten
from .nary import nary_code, reed_solomon, ternary_golay
from .search import search_code
from .table import best


def _ecc_22(k: int) -> Code:
    if not 1 <= k <= 12:
        raise ValueError(f"ecc-(k+12)-k from the extended Golay code exists for 1 <= k <= 12, got k={k}")
    g = golay(extended=True)
    return shorten(g, 12 - k, name=f"ecc-{24 - (12 - k)}-{k}") if k < 12 else g.with_name("ecc-24-12")


def _ecc(n: int, k: int) -> Code:
    if n == k + 12 and 6 <= k <= 12:
        return _ecc_22(k)
    return best(n, k)


def _hamming(n: int, k: int, extended: bool) -> Code:
    for m in range(2, 9):
        if n == (1 << m) - (0 if extended else 1) and k == (1 << m) - 1 - m:
            return hamming(m, extended=extended)
    raise ValueError(f"no {'extended ' if extended else ''}Hamming code ({n}, {k}): "
                     f"{'n = 2**m, k = 2**m - 1 - m' if extended else 'n = 2**m - 1, k = n - m'}")


def _bch(n: int, k: int, extended: bool) -> Code:
    return bch(n - 1 if extended else n, k, extended=extended)


def _crc(base: str, width: str, poly: str | None) -> Code:
    w = int(width)
    if poly is None:
        if w not in DEFAULT_POLY:
            raise ValueError(f"CRC width must be 3..8, got {w}")
        p = DEFAULT_POLY[w]
    else:
        p = int(poly, 16)
    return crc_code(get_code(base), p, w)


#: Most codewords (projector columns) a code may have: 2**16, far beyond any projector's width;
#: larger codebooks are refused by name, before they are built (2**k rows of n symbols each).
MAX_CODEWORDS = 1 << 16
_MAX_BITS = 16


def _rm_k(r: str, m: str) -> int:
    """k of the Reed-Muller code RM(r, m) (m above 64 counts as 64: already far too many)."""
    m_ = min(int(m), 64)
    return sum(math.comb(m_, i) for i in range(min(int(r), m_) + 1))


#: (name pattern, builder, log2 of the codewords the name asks for; None: checked by its parts).
_PATTERNS: list[tuple[re.Pattern[str], Callable[..., Code], Callable[..., float] | None]] = [
    (re.compile(r"(.+)\+crc(\d+)(?:-0x([0-9a-fA-F]+))?"), _crc, None),
    (re.compile(r"binary-(\d+)"), lambda k: binary_code(int(k)), lambda k: int(k)),
    (re.compile(r"gray-(\d+)"), lambda k: gray_code(int(k)), lambda k: int(k)),
    (re.compile(r"xor02-(\d+)"), lambda k: xor_code(int(k), 2), lambda k: int(k)),
    (re.compile(r"xor04-(\d+)"), lambda k: xor_code(int(k), 4), lambda k: int(k)),
    (re.compile(r"ecc-(\d+)-(\d+)"), lambda n, k: _ecc(int(n), int(k)), lambda n, k: int(k)),
    (re.compile(r"hamming-(\d+)-(\d+)"), lambda n, k: _hamming(int(n), int(k), False), lambda n, k: int(k)),
    (re.compile(r"ext-hamming-(\d+)-(\d+)"), lambda n, k: _hamming(int(n), int(k), True), lambda n, k: int(k)),
    (re.compile(r"bch-(\d+)-(\d+)"), lambda n, k: _bch(int(n), int(k), False), lambda n, k: int(k)),
    (re.compile(r"ext-bch-(\d+)-(\d+)"), lambda n, k: _bch(int(n), int(k), True), lambda n, k: int(k)),
    (re.compile(r"rm-(\d+)-(\d+)"), lambda r, m: reed_muller(int(r), int(m)), lambda r, m: _rm_k(r, m)),
    (re.compile(r"search-(\d+)-(\d+)"), lambda n, k: search_code(int(n), int(k)), lambda n, k: int(k)),
    (re.compile(r"poisson-(\d+)-(\d+)"), lambda n, k: search_code(int(n), int(k), method="poisson"),
     lambda n, k: int(k)),
    (re.compile(r"nary(\d+)-(\d+)"), lambda q, k: nary_code(int(q), int(k)),
     lambda q, k: int(k) * math.log2(max(int(q), 1))),
    (re.compile(r"rs(8|16)-(\d+)-(\d+)"), lambda q, n, k: reed_solomon(int(q), int(n), int(k)),
     lambda q, n, k: int(k) * math.log2(int(q))),
]

_FIXED: dict[str, Callable[[], Code]] = {
    "ecc-15-10": lambda: shorten(hamming(4, extended=True), 1),
    "ecc-22-10": lambda: _ecc_22(10),
    "ecc-31-10": lambda: shorten(bch(31, 11, extended=True), 1),
    "ecc-63-10": lambda: bch(63, 10),
    "golay-24-12": lambda: golay(True),
    "golay-23-12": lambda: golay(False),
    "ternary-golay-11-6": lambda: ternary_golay(False),
    "ternary-golay-12-6": lambda: ternary_golay(True),
}

#: Names listed by `names()` (parametrised families shown with typical parameters).
_EXAMPLES = [
    "binary-10", "gray-10", "gray-8", "xor02-10", "xor04-10",
    "ecc-15-10", "ecc-15-11", "ecc-20-8", "ecc-22-10", "ecc-31-10", "ecc-63-10",
    "xor02-10+crc5", "gray-10+crc5", "xor04-10+crc5", "gray-10+crc5-0x05",
    "hamming-15-11", "ext-hamming-16-11", "bch-31-11", "ext-bch-32-11", "bch-63-10", "rm-1-5", "rm-2-5",
    "search-31-10", "poisson-20-8",
    "nary3-6", "nary8-3", "rs8-7-3", "rs16-15-4", "rs16-12-3",
]


def names() -> list[str]:
    """Names `get_code` accepts (families with parameters are shown by examples)."""
    return sorted(set(_FIXED) | set(_EXAMPLES))


@functools.lru_cache(maxsize=128)
def get_code(name: str) -> Code:
    """The code registered under ``name``; ValueError listing the valid names otherwise."""
    if not isinstance(name, str):
        raise ValueError(f"code name must be a string, got {name!r}")
    if name in _FIXED:
        code = _FIXED[name]()
        return code if code.name == name else code.with_name(name)
    for pattern, build, codewords in _PATTERNS:
        m = pattern.fullmatch(name)
        if m:
            if codewords is not None and codewords(*m.groups()) > _MAX_BITS + 1e-9:
                raise ValueError(f"code {name!r}: 2**{codewords(*m.groups()):g} codewords, more than the "
                                 f"{MAX_CODEWORDS} (2**{_MAX_BITS}) columns a code may have")
            code = build(*m.groups())
            return code if code.name == name else code.with_name(name)
    raise ValueError(
        f"unknown code {name!r}; valid names: {', '.join(names())} "
        "(patterns: binary-K, gray-K, xor02-K, xor04-K, ecc-N-K, BASE+crcW[-0xHEX], hamming-N-K, "
        "bch-N-K, ext-bch-N-K, rm-R-M, search-N-K, naryQ-K, rs8-N-K, rs16-N-K)"
    )
