"""Examples found by tools/faults_fuzz.py (the decode property), kept as plain deterministic tests.

The property: `edge.decode.decode` returns a `Decoded` whose valid pixels all have a column and
whose confidence is finite everywhere, or raises one ValueError line.

1. ``sigma_r`` far below any noise (7.95e-162, accepted while the bound was 0 < sigma_r <= 1) with ``sigma_s = 0``:
   the per-pixel reciprocal variances of the cost model (``1 / sigma_r**2``, ``1 / (2 sigma_r**2)``
   with inverse frames) overflow to inf once ``sigma_r**2`` is below 1 / DBL_MAX (sigma_r below
   about 7.5e-155; 5.3e-155 with inverse frames), the per-sample costs become inf - inf = NaN, and
   the confidence comes back NaN (distances inf).  Found with ``--full --seed 3`` (hypothesis'
   shrunk example is the nary8-3 case below), on a capture with inverse frames (the "confidence"
   rule) and on one without under ``validity="confidence"``.  Fixed by the settings' lower bound
   `edge.decode.settings.MIN_SIGMA_R` (1e-6): such a sigma is refused by name, and the bound
   itself decodes with finite confidence (last test).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from edge.codes import get_code
from edge.decode import decode

ROOT = Path(__file__).resolve().parents[1]
TINY_SIGMA_R = 7.952021565598949e-162


def _check_property(frames, white, black, code, **kw) -> None:
    """The fuzz property (tools/faults_fuzz.py `check_decode`)."""
    try:
        d = decode(frames, white, black, code, **kw)
    except ValueError as exc:
        assert "\n" not in str(exc) and str(exc)
        return
    assert np.all(d.column[d.valid] >= 0), "a valid pixel without a column"
    assert np.all(np.isfinite(d.confidence)), f"non-finite confidence {d.confidence.ravel()}"


def test_tiny_sigma_r_with_inverse_frames_nary_shrunk_example():
    """hypothesis' shrunk example, verbatim: one pixel of nary8-3, uint8, with inverse frames."""
    frames = np.array([217, 163, 130], np.uint8).reshape(3, 1, 1)
    inverse = np.array([217, 163, 130], np.uint8).reshape(3, 1, 1)
    white = np.array([[217]], np.uint8)
    black = np.array([[121]], np.uint8)
    _check_property(frames, white, black, get_code("nary8-3"), inverse=inverse, sigma_r=TINY_SIGMA_R,
                    sigma_s=0.0, min_contrast=0.0, min_confidence=0.0)


@pytest.mark.parametrize("sigma_r", [TINY_SIGMA_R, 1e-155])
def test_tiny_sigma_r_with_inverse_frames_binary(sigma_r):
    """One pixel of gray-10, pattern and exact inverse, full white / black."""
    code = get_code("gray-10")
    frames = np.random.default_rng(0).integers(0, 256, (code.n, 1, 1)).astype(np.uint8)
    _check_property(frames, np.full((1, 1), 255, np.uint8), np.zeros((1, 1), np.uint8), code,
                    inverse=(255 - frames).astype(np.uint8), sigma_r=sigma_r, sigma_s=0.0)


def test_tiny_sigma_r_under_the_confidence_rule_without_inverse_frames():
    code = get_code("gray-10")
    frames = np.random.default_rng(0).integers(0, 256, (code.n, 1, 1)).astype(np.uint8)
    _check_property(frames, np.full((1, 1), 255, np.uint8), np.zeros((1, 1), np.uint8), code,
                    sigma_r=1e-160, sigma_s=0.0, validity="confidence")


# -- the fuzz tool's --seed / --examples ------------------------------------------------------------

def _fuzz_module():
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import faults_fuzz
    finally:
        sys.path.remove(str(ROOT / "tools"))
    return faults_fuzz


def test_fuzz_seed_repeats_the_draw_and_examples_sets_the_budget(monkeypatch):
    from hypothesis import given
    from hypothesis import strategies as st

    ff = _fuzz_module()
    monkeypatch.setenv("EDGE_FUZZ", "full")

    def draws(seed: int) -> list[int]:
        seen: list[int] = []
        monkeypatch.setitem(ff.RUN, "seed", seed)
        monkeypatch.setitem(ff.RUN, "examples", 7)

        @ff._settings("decode")
        @given(st.integers(0, 10**9))
        def prop(v: int) -> None:
            seen.append(v)

        prop()
        return seen

    first = draws(3)
    assert len(first) == 7 and draws(3) == first and draws(4) != first


def test_fuzz_examples_below_one_is_one_error_line():
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "faults_fuzz.py"), "--examples", "0"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip() == "faults_fuzz.py: error: --examples must be >= 1, got 0"


@pytest.mark.parametrize("inverse", [False, True])
def test_the_smallest_sigma_r_allowed_decodes_with_finite_confidence(inverse):
    """At `MIN_SIGMA_R` with sigma_s 0 the cost model stays finite under either rule."""
    from edge.decode.settings import MIN_SIGMA_R

    code = get_code("gray-10")
    frames = np.random.default_rng(1).integers(0, 256, (code.n, 4, 5)).astype(np.uint8)
    for validity in ("confidence", "error"):
        d = decode(frames, np.full((4, 5), 255, np.uint8), np.zeros((4, 5), np.uint8), code,
                   inverse=(255 - frames).astype(np.uint8) if inverse else None, sigma_r=MIN_SIGMA_R,
                   sigma_s=0.0, validity=validity)
        assert np.all(np.isfinite(d.confidence)) and np.all(d.column[d.valid] >= 0)
