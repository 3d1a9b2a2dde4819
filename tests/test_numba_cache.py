"""`edge.numba_cache`: processes that share numba's on-disk cache never load another
signature's code (numba issue #10128), and every edge module with kernels installs the lock."""

from __future__ import annotations

import ast
import multiprocessing as mp
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from _tools import load_tool

pytest.importorskip("fcntl")  # the lock is POSIX's flock; without it install() does nothing

from numba.core.caching import IndexDataCacheFile  # noqa: E402

from edge import numba_cache  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FORK = mp.get_context("fork")


def test_processes_sharing_a_cache_load_only_what_was_saved_under_the_key():
    """tools/check_numba_cache_race.py's workload with the lock: two processes each save 100
    entries (distinct signatures of one function) into one cache and load back both processes'
    latest after every save; no load returns an entry saved under another key.  (Plain numba
    0.68 gets such loads in most runs of the tool.)"""
    tool = load_tool("check_numba_cache_race")
    assert tool.wrong_loads(processes=2, saves=100, kib=100, locked=True) == 0


def _paused_save(path, ready, go, done):
    """Child: save key "a" with a pause after the index is read and before it is written (the
    window where plain numba lets another process read the same index and pick the same file)."""
    numba_cache.install()
    original = IndexDataCacheFile._save_index

    def slow(self, overloads):
        ready.set()
        go.wait(10)
        original(self, overloads)

    IndexDataCacheFile._save_index = slow
    IndexDataCacheFile(path, "kernel-1.py311", ("stamp", 1)).save("a", "code for a")
    done.set()


def test_a_save_waits_for_another_processes_save_to_finish(tmp_path):
    """A child process pauses inside a save; this process's save of another key, started in that
    window, must wait for it (the lock), so it reads the child's index entry and takes the next
    file: both entries load, each its own data.  Unlocked, it would read the index before the
    child wrote it, take the same data file, and one entry would be lost or point at the other's
    data."""
    numba_cache.install()
    ready, go, done = FORK.Event(), FORK.Event(), FORK.Event()
    child = FORK.Process(target=_paused_save, args=(str(tmp_path), ready, go, done))
    child.start()
    try:
        assert ready.wait(30), "the child did not reach its save"
        saver = threading.Thread(
            target=lambda: IndexDataCacheFile(str(tmp_path), "kernel-1.py311", ("stamp", 1)).save("b", "code for b"))
        saver.start()
        saver.join(0.5)
        assert saver.is_alive(), "the save did not wait for the other process's save"
        go.set()
        saver.join(30)
        assert not saver.is_alive()
        assert done.wait(30)  # (the child sets it after its save returned: maybe after ours)
    finally:
        go.set()
        child.join(30)
    assert child.exitcode == 0
    cache = IndexDataCacheFile(str(tmp_path), "kernel-1.py311", ("stamp", 1))
    assert cache.load("a") == "code for a"
    assert cache.load("b") == "code for b"
    assert (tmp_path / numba_cache.LOCK_NAME).exists()


def test_install_is_idempotent_and_keeps_numbas_methods():
    """A second install wraps nothing twice; the wrappers call numba's own methods."""
    numba_cache.install()
    save = IndexDataCacheFile.save
    assert numba_cache.install()[0] == "numba.core.caching"
    assert IndexDataCacheFile.save is save
    assert numba_cache.is_installed()
    inner = save.__wrapped__
    assert not hasattr(inner, "__wrapped__") and inner.__qualname__ == "IndexDataCacheFile.save"


def test_the_lock_is_skipped_where_its_file_cannot_exist(tmp_path):
    """No directory (numba has not created the cache yet) or no path: the call goes on unlocked."""
    import fcntl

    with numba_cache.directory_lock(None, fcntl.LOCK_SH) as held:
        assert not held
    with numba_cache.directory_lock(str(tmp_path / "missing"), fcntl.LOCK_SH) as held:
        assert not held
    with numba_cache.directory_lock(str(tmp_path), fcntl.LOCK_EX) as held:
        assert held
    # a load before anything was saved finds nothing, without error
    assert IndexDataCacheFile(str(tmp_path / "missing"), "k-1.py311", ("s", 1)).load("x") is None


def test_a_real_kernel_is_saved_and_loaded_through_the_lock(tmp_path):
    """A ``cache=True`` kernel compiled in a process that imported an edge kernel module is saved
    under the lock (its file appears in the cache directory) and loads in a second process."""
    script = (
        "import edge.source.events\n"  # a module that installs the lock itself (no package does it first)
        "from edge.numba_cache import is_installed\n"
        "assert is_installed()\n"
        "from numba import njit\n"
        "@njit(cache=True)\n"
        "def twice(x):\n"
        "    return 2 * x\n"
        "assert twice(21) == 42\n"
        "print(twice.stats.cache_hits.get((__import__('numba').int64,), 0), len(twice.stats.cache_misses))\n"
    )
    src = tmp_path / "kernel_mod.py"
    src.write_text(script)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(ROOT))
    first = subprocess.run([sys.executable, str(src)], env=env, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    assert first.stdout.split() == ["0", "1"]  # compiled (a miss), then saved
    locks = list((tmp_path / "cache").rglob(numba_cache.LOCK_NAME))
    assert locks, "numba's save did not go through the lock"
    second = subprocess.run([sys.executable, str(src)], env=env, capture_output=True, text=True, timeout=120)
    assert second.returncode == 0, second.stderr
    assert second.stdout.split() == ["1", "0"]  # loaded from the cache, under the lock


def _numba_modules() -> list[Path]:
    out = []
    for path in sorted((ROOT / "edge").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            if any(n == "numba" or n.startswith("numba.") for n in names):
                out.append(path)
                break
    return out


def _installs(path: Path) -> bool:
    """Whether the module's own top level calls ``_install_cache_lock()``."""
    for node in ast.parse(path.read_text()).body:
        if (isinstance(node, ast.Expr) and isinstance(node.value, ast.Call)
                and getattr(node.value.func, "id", None) == "_install_cache_lock"):
            return True
    return False


def test_every_edge_module_with_kernels_installs_the_lock_on_import():
    """Every module of edge that imports numba is covered: it calls `install` at its top level,
    or a package above it does in its ``__init__`` (run before the module)."""
    modules = _numba_modules()
    assert len(modules) >= 20
    uncovered = []
    for path in modules:
        if path.name == "numba_cache.py":
            continue
        chain = [path] + [p / "__init__.py" for p in path.parents if ROOT / "edge" in (p, *p.parents)]
        if not any(_installs(p) for p in chain if p.exists()):
            uncovered.append(str(path.relative_to(ROOT)))
    assert not uncovered, f"modules with numba kernels that may compile before the cache lock: {uncovered}"
