"""tools/bench_compile.py: the compile-time recorder attributes each numba compile to its own
function, nested compiles subtracted, and the tool rejects bad arguments in one line, exit code 2."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest
from numba import njit

from _tools import TOOLS, load_tool


def test_compile_times_attribute_nested_compiles_to_their_own_function():
    tool = load_tool("bench_compile")

    @njit
    def inner(x):
        return x * 2.0 + 1.0

    @njit
    def outer(x):
        return inner(x) - 3.0

    t0 = time.perf_counter()
    with tool.CompileTimes() as times:
        assert outer(2.0) == 2.0
    elapsed = time.perf_counter() - t0
    assert outer(1.0) == 0.0  # after the block: compiled already, and nothing more is recorded
    names = {name.rsplit(".", 1)[-1]: name for name in times.seconds}
    assert set(names) == {"inner", "outer"}, names
    assert times.compiles[names["inner"]] == times.compiles[names["outer"]] == 1
    own_inner, own_outer = times.seconds[names["inner"]], times.seconds[names["outer"]]
    assert own_inner > 0 and own_outer > 0
    assert own_inner + own_outer <= elapsed  # exclusive times: the nested compile is counted once
    with tool.CompileTimes() as again:
        outer(3.0)
    assert again.seconds == {}


@pytest.mark.parametrize("argv, message", [(["--rounds", "0"], "must be at least 1"),
                                           (["--height", "0"], "must be at least 1"),
                                           (["--top", "0"], "must be at least 1"),
                                           (["--target", "run", "--stacks", "0"], "must be at least 1"),
                                           (["--rev", "no-such-revision"], "is not a revision")])
def test_bad_arguments_are_one_line_and_exit_code_2(argv, message):
    proc = subprocess.run([sys.executable, str(TOOLS / "bench_compile.py"), *argv], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.startswith("bench_compile.py: error: ") and message in proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
