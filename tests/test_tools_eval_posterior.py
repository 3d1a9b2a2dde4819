"""tools/eval_posterior.py's bound (`bound_costs` / `bound_error`): the vectorised costs against a
loop over the codewords, and the order the bound must keep on a capture of the tests' own
renderer (true levels <= the decoder's defaults <= own levels with no prior, in errors)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from edge.codes import get_code
from edge.decode import decode

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from _plane_box_sphere import render, scene  # noqa: E402
from _tools import load_tool  # noqa: E402


def _tool():
    return load_tool("eval_posterior")


def test_bound_costs_match_a_loop_over_the_codewords():
    tool = _tool()
    code = get_code("ecc-22-10")
    rng = np.random.default_rng(0)
    a, beta = 4e-6, 1.6e-3
    p = 40
    on, off = rng.uniform(0.02, 0.3, p), rng.uniform(0.0, 0.05, p)
    rows = rng.integers(0, code.size, p)
    x = np.concatenate([code.codebook[rows], np.ones((p, 1)), np.zeros((p, 1))], 1).astype(np.float64)
    mean = off[:, None] + (on - off)[:, None] * x
    samples = mean + rng.standard_normal(mean.shape) * np.sqrt(a + beta * mean)
    true, own = tool.bound_costs(samples, on, off, code, (a, beta))
    for i in range(p):
        t_ref, o_ref = np.empty(code.size), np.empty(code.size)
        for k in range(code.size):
            xk = np.r_[code.codebook[k], 1, 0].astype(bool)
            lv = np.where(xk, on[i], off[i])
            var = a + beta * lv
            t_ref[k] = np.sum((samples[i] - lv) ** 2 / var + np.log(var))
            hi, lo = samples[i][xk].mean(), samples[i][~xk].mean()
            fit = np.where(xk, hi, lo) if hi >= lo else np.full(xk.size, samples[i].mean())
            o_ref[k] = np.sum((samples[i] - fit) ** 2 / np.where(xk, a + beta * on[i], a + beta * off[i]))
        # costs up to a per-pixel constant (the own-level cost under v(off) where pooled)
        np.testing.assert_allclose(true[i] - true[i].min(), t_ref - t_ref.min(), atol=1e-6)
        pooled = np.array([samples[i][np.r_[code.codebook[k], 1, 0].astype(bool)].mean()
                           < samples[i][~np.r_[code.codebook[k], 1, 0].astype(bool)].mean()
                           for k in range(code.size)])
        fitted = ~pooled
        assert fitted.sum() > code.size // 2
        np.testing.assert_allclose(own[i][fitted], o_ref[fitted], rtol=1e-9, atol=1e-6)


@pytest.mark.parametrize("name", ["gray-10", "ecc-22-10"])
def test_bound_orders_true_levels_decoder_and_own_levels(name):
    """At fixed total exposure, ambient = projector: knowing the levels beats the decoder, which
    beats the codewords' own levels without a level prior (plane-box-sphere, 12-bit; measured
    gray-10 27.5 / 34.1 / 39.5 %, ecc-22-10 1.0 / 1.4 / 3.9 %)."""
    tool = _tool()
    code = get_code(name)
    col, albedo = scene(160, 120, seed=11)
    f, w, b = render(code.codebook, col, albedo, ambient=0.12, projector=0.12, bits=12, seed=12)
    t = 10.0 / code.n
    on, off = t * albedo * 0.24, t * albedo * 0.12
    lit = np.ones(col.shape, bool)
    true, own = tool.bound_error(f, w, b, 12, on, off, code, col, lit, (0.002 ** 2, 0.04 ** 2))
    d = decode(f, w, b, code, bit_depth=12)
    decoded = float(((d.column != col) | ~d.valid).mean())
    assert true < decoded < own
