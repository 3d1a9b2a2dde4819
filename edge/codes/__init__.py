"""Code library: structured-light codes as exact `Code` values.

Entry points: `get_code(name)` (see `registry` for the name grammar), `best(n, k)` (the best
binary code of the lookup table), `crc_code`, `edc_search`, `search_code`.
"""

from ..numba_cache import install as _install_cache_lock

_install_cache_lock()  # before any kernel of this package is compiled or loaded (edge.numba_cache)

from .code import Code, digits_to_int, gray, int_to_digits, inverse_gray
from .crc import crc_code, edc_search
from .registry import get_code, names
from .search import search_code
from .table import best, griesmer_bound

__all__ = [
    "Code", "get_code", "names", "best", "griesmer_bound", "crc_code", "edc_search", "search_code",
    "gray", "inverse_gray", "int_to_digits", "digits_to_int",
]
