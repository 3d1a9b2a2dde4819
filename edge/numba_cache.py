"""Make numba's on-disk kernel cache safe for processes that share it.

numba saves a newly compiled signature of a ``cache=True`` function in four steps
(`numba.core.caching.IndexDataCacheFile.save`): read the function's index file, pick the first
data-file number the index does not use, write the index, write the data file.  It loads one by
reading the index, then the data file the index names.  Each file is replaced atomically, but
the sequence is not.  Two processes that add different signatures of one function at once can
both read the same index and pick the same number.  The index can then name one signature while
the data file holds the other signature's machine code (numba issue #10128), and a process that
loads that entry calls code compiled for other argument types: a crash or wrong output.

Processes share a cache in three places here: the test suite's two pytest-xdist workers, the Ray
workers of ``edge replay --workers`` (they get the driver's ``NUMBA_CACHE_DIR``), and two edge
processes on one host with the same ``NUMBA_CACHE_DIR``.  Two processes doing 150 saves each of
distinct signatures into one cache, each loading back after every save, got another
signature's data 4-9 times in each of three runs with plain numba 0.68
(`tests/test_numba_cache.py` runs that workload with the lock and requires none).

`install` makes each save and each load one critical section: ``save`` and ``flush`` under an
exclusive, ``load`` under a shared ``fcntl.flock`` on one lock file per cache directory
(`LOCK_NAME`).  Saves are rare and short (an index and one data file), so the lock costs
nothing measurable.  Where the lock file cannot be created or opened (a read-only cache
directory, a directory numba has not created yet) the call goes on unlocked, as numba's own
would.  Without ``fcntl`` (Windows) `install` does nothing.  numba-cuda keeps its own copy of
the class (``numba.cuda.core.caching``); it is patched too where it is already imported, and
the CUDA backend calls `install` again after importing it.

Every package and module of edge that defines numba kernels calls `install` on import
(`tests/test_numba_cache.py` checks that statically), so no edge kernel is compiled or loaded
before it is in place.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
from typing import Any, Iterator

try:
    import fcntl
except ImportError:  # Windows: no flock; numba's behaviour is left as it is
    fcntl = None  # type: ignore[assignment]

#: The lock file, one per cache directory.
LOCK_NAME = "edge-numba-cache.lock"

#: The modules whose ``IndexDataCacheFile`` is wrapped: numba's, and numba-cuda's copy.
CACHING_MODULES = ("numba.core.caching", "numba.cuda.core.caching")

_MARK = "_edge_locked"


def install() -> list[str]:
    """Wrap ``IndexDataCacheFile.save`` / ``flush`` / ``load`` of numba's caching module (imported
    here) and of numba-cuda's (where already imported) in the directory lock.  Idempotent.
    Returns the modules whose class is wrapped (empty without ``fcntl``)."""
    if fcntl is None:
        return []
    from numba.core import caching  # the CPU kernels' cache

    wrapped = []
    for name in CACHING_MODULES:
        module = caching if name == caching.__name__ else sys.modules.get(name)
        cls = getattr(module, "IndexDataCacheFile", None)
        if cls is None:
            continue
        if not getattr(cls, _MARK, False):
            if not all(hasattr(cls, attr) for attr in ("save", "load", "flush")):
                continue  # a numba whose cache file class is not this one: left as it is
            cls.save = _locked(cls.save, fcntl.LOCK_EX)
            cls.flush = _locked(cls.flush, fcntl.LOCK_EX)
            cls.load = _locked(cls.load, fcntl.LOCK_SH)
            setattr(cls, _MARK, True)
        wrapped.append(name)
    return wrapped


def is_installed(module: str = "numba.core.caching") -> bool:
    """Whether ``module``'s ``IndexDataCacheFile`` is wrapped (False where it is not imported)."""
    cls = getattr(sys.modules.get(module), "IndexDataCacheFile", None)
    return bool(getattr(cls, _MARK, False))


def _locked(method: Any, mode: int) -> Any:
    @functools.wraps(method)
    def call(self, *args, **kwargs):
        with directory_lock(getattr(self, "_cache_path", None), mode):
            return method(self, *args, **kwargs)

    return call


@contextlib.contextmanager
def directory_lock(path: str | None, mode: int) -> Iterator[bool]:
    """Hold ``fcntl.flock(mode)`` on ``path``/`LOCK_NAME` for the block; yields whether it is held
    (False, and no lock, where ``path`` is None or the lock file can be neither created nor
    opened).  The lock is released when its file is closed, also on an exception."""
    fd = _open_lock(path)
    if fd is None:
        yield False
        return
    try:
        fcntl.flock(fd, mode)
        yield True
    finally:
        os.close(fd)


def _open_lock(path: str | None) -> int | None:
    if path is None:
        return None
    lock = os.path.join(path, LOCK_NAME)
    for flags in (os.O_RDWR | os.O_CREAT, os.O_RDONLY):  # read-only directory: an existing file
        try:
            return os.open(lock, flags, 0o666)
        except OSError:
            continue
    return None
