"""tools/memory_service.py's array census: every buffer counted once, at its first owner, views
and containers followed, arrays alive before the run left out; and its option checks."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from _tools import load_tool


@pytest.fixture(scope="module")
def tool():
    return load_tool("memory_service")


class _Holder:
    def __init__(self, **kw):
        self.__dict__.update(kw)


class _Slotted:
    __slots__ = ("a", "b")

    def __init__(self, a):
        self.a = a  # b left unset


def test_a_view_counts_its_buffer_once_at_the_first_owner(tool):
    big = np.zeros((100, 100), np.float32)
    other = np.ones(1000, np.uint8)
    first = _Holder(frames=[big[:10], big[50:]], q=deque([other]))
    second = _Holder(same=big, more={"x": big.T})
    seen: set[int] = set()
    a = tool.arrays_under(first, seen)
    b = tool.arrays_under(second, seen)
    assert set(a) == {id(big), id(other)} and b == {}
    assert tool.nbytes(a) == pytest.approx((big.nbytes + other.nbytes) / tool.MB)


def test_slots_tuples_and_the_depth_limit(tool):
    inner = np.arange(12, dtype=np.int64)
    assert set(tool.arrays_under(_Slotted((inner, None)), set())) == {id(inner)}
    nested = inner
    for _ in range(10):
        nested = _Holder(child=nested)
    assert tool.arrays_under(nested, set(), depth=3) == {}
    assert set(tool.arrays_under(nested, set(), depth=12)) == {id(inner)}


def test_arrays_in_exclude_and_modules_are_not_followed(tool):
    kept = np.zeros(8)
    assert tool.arrays_under(_Holder(k=kept, m=np), {id(kept)}) == {}


def test_by_shape_groups_the_largest_first(tool):
    arrays = {i: a for i, a in enumerate([np.zeros((4, 4), np.float32)] * 1 + [np.zeros(3, np.uint8)])}
    arrays[9] = np.zeros((4, 4), np.float32)
    assert tool.by_shape(arrays, 1) == "2 x (4, 4) float32 0.0"


@pytest.mark.parametrize("argv, text", [(["--stacks", "0"], "--stacks"), (["--poses", "-1"], "--poses"),
                                        (["--malloc-arenas", "-2"], "--malloc-arenas"), (["--top", "0"], "--top")])
def test_bad_options_are_refused_by_name(tool, argv, text):
    with pytest.raises(ValueError, match=text):
        tool.parse_args(argv)


def test_limit_arenas_zero_changes_nothing(tool):
    assert tool.limit_arenas(0) is False
