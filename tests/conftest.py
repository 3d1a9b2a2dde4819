"""Session order: the CUDA simulator checks (tests/test_decode_cuda.py) run last.

They run in a subprocess that also calls the CPU decoder for its references. Run last, they find
those numba kernels in the session's on-disk cache (NUMBA_CACHE_DIR) instead of compiling them a
second time on a cold CI machine.
"""

from __future__ import annotations


def pytest_collection_modifyitems(session, config, items):
    """Move the items of test_decode_cuda.py to the end, keeping every other item's order."""
    last = [item for item in items if item.nodeid.startswith("tests/test_decode_cuda.py")]
    if last:
        rest = [item for item in items if not item.nodeid.startswith("tests/test_decode_cuda.py")]
        items[:] = rest + last
