"""Property-based fuzzing (hypothesis) of profiles, config updates over zenoh and decode() inputs.

CI runs the small budget of tools/faults_fuzz.py (``EDGE_FUZZ=ci``, the default);
``EDGE_FUZZ=full`` (or ``python tools/faults_fuzz.py --full``) runs thousands of examples and the
4000 x 3000 stack with bounded memory.
"""

from __future__ import annotations

import os
import sys
from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import faults_fuzz as ff  # noqa: E402

FULL = os.environ.get("EDGE_FUZZ") == "full"


def test_profiles_fuzz_only_accepts_or_rejects_in_one_line():
    tally: Counter = Counter()
    ff.fuzz_profiles(tally)
    assert sum(tally.values()) >= ff.budget("profiles") // 2 and tally["rejected"] > 0, tally


def test_config_updates_over_zenoh_fuzz():
    tally: Counter = Counter()
    ff.fuzz_config(tally)
    assert tally["rejected"] + tally["huge rejected"] > 0, tally


def test_decode_fuzz_only_decodes_or_rejects_in_one_line():
    tally: Counter = Counter()
    ff.fuzz_decode(tally)
    assert tally["rejected"] > 0 and tally["decoded"] > 0, tally


def test_decode_pins():
    """Examples the fuzzer found or must always cover: 1-pixel, empty, NaN, mismatched."""
    import numpy as np

    from edge.codes import get_code

    code = get_code("gray-10")
    tally: Counter = Counter()
    one = np.full((code.n, 1, 1), 100, np.uint8)
    ff.check_decode(one, np.full((1, 1), 255, np.uint8), np.zeros((1, 1), np.uint8), code, {}, tally)
    ff.check_decode(np.zeros((code.n, 0, 4), np.uint8), np.zeros((0, 4), np.uint8), np.zeros((0, 4), np.uint8),
                    code, {}, tally)
    nan = np.full((code.n, 2, 2), np.nan, np.float32)
    ff.check_decode(nan, np.ones((2, 2), np.float32), np.zeros((2, 2), np.float32), code, {}, tally)
    ff.check_decode(one, np.ones((2, 1), np.uint8), np.zeros((1, 1), np.uint8), code, {}, tally)
    for kw in ({"min_disparity": float("inf")}, {"max_disparity": float("nan")}, {"stripe": 0},
               {"sigma_r": float("nan")}, {"method": "bogus"}):
        ff.check_decode(one, np.full((1, 1), 255, np.uint8), np.zeros((1, 1), np.uint8), code, kw, tally)
    assert tally["decoded"] >= 1 and tally["rejected"] >= 6, tally


@pytest.mark.skipif(not FULL, reason="allocation-heavy (about 0.5 GB): EDGE_FUZZ=full or tools/faults_fuzz.py --full")
def test_decode_4000x3000_with_bounded_memory():
    res = ff.large_stack(Counter())
    assert res["ok"], res
