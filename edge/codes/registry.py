"""Named codes: ``get_code("ecc-22-10")`` and friends."""

from __future__ import annotations

import functools
import re
from typing import Callable

from .code import Code
from .gray import binary_code, gray_code, xor_code
from .linear import golay, shorten


def _ecc_22(k: int) -> Code:
    if not 1 <= k <= 12:
        raise ValueError("ecc-(k+12)-k from the extended Golay code exists for k <= 12")
    g = golay(extended=True)
    return shorten(g, 12 - k, name=f"ecc-{24 - (12 - k)}-{k}") if k < 12 else g.with_name("ecc-24-12")


_PATTERNS: list[tuple[re.Pattern[str], Callable[..., Code]]] = [
    (re.compile(r"binary-(\d+)"), lambda k: binary_code(int(k))),
    (re.compile(r"gray-(\d+)"), lambda k: gray_code(int(k))),
    (re.compile(r"xor02-(\d+)"), lambda k: xor_code(int(k), 2)),
    (re.compile(r"xor04-(\d+)"), lambda k: xor_code(int(k), 4)),
]

_FIXED: dict[str, Callable[[], Code]] = {
    "ecc-22-10": lambda: _ecc_22(10),
    "golay-24-12": lambda: golay(True),
    "golay-23-12": lambda: golay(False),
}


def names() -> list[str]:
    """Names `get_code` accepts (k-parametrised families shown for k = 10)."""
    return sorted(set(_FIXED) | {"binary-10", "gray-10", "xor02-10", "xor04-10"})


@functools.lru_cache(maxsize=128)
def get_code(name: str) -> Code:
    """The code registered under ``name``; ValueError listing the valid names otherwise."""
    if name in _FIXED:
        return _FIXED[name]().with_name(name)
    for pattern, build in _PATTERNS:
        m = pattern.fullmatch(name)
        if m:
            return build(*m.groups())
    raise ValueError(f"unknown code {name!r}; valid names: {', '.join(names())}")
