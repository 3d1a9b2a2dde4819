"""tools/bench_compile.py: the compile-time recorder attributes each numba compile to its own
function, nested compiles subtracted, and the tool rejects bad arguments in one line."""

from __future__ import annotations

import time

import pytest
from numba import njit

from _tools import load_tool


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


@pytest.mark.parametrize("argv", [["--rounds", "0"], ["--height", "0"]])
def test_bad_arguments_are_one_line(argv):
    tool = load_tool("bench_compile")
    with pytest.raises(SystemExit, match="must be at least 1"):
        tool.main(argv)
