"""tools/eval_per_pixel_limit.py: its kernels against naive references, its "every codeword"
column against `decode()`'s own candidate costs, the Bayes rule's bookkeeping, and one small run."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from edge.codes import get_code
from edge.decode.level_prior import kernel_args

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from _plane_box_sphere import render, scene  # noqa: E402
from _tools import load_tool  # noqa: E402


def _tool():
    return load_tool("eval_per_pixel_limit")


def _normal_cost(x: np.ndarray, mean: np.ndarray, a: float, beta: float) -> float:
    """-2 log of a product of normals of variance a + beta * mean, without the 2 pi constant."""
    v = a + beta * mean
    return float(((x - mean) ** 2 / v + np.log(v)).sum())


def test_marginal_costs_match_a_naive_sum_over_the_atoms():
    tool = _tool()
    rng = np.random.default_rng(3)
    a, beta = 4e-6, 1.6e-3
    code = get_code("ecc-15-10")
    X = tool.ev.symbols(code)
    S = rng.uniform(0.0, 0.4, (6, X.shape[1]))
    rows = rng.integers(0, code.size, (6, 4)).astype(np.int64)
    on, off = rng.uniform(0.1, 0.4, 5), rng.uniform(0.0, 0.08, 5)
    flat = rng.uniform(0.0, 0.2, 3)
    lit, unlit = np.empty(rows.shape), np.empty(6)
    tool.marginal_costs(S, X, rows, on, off, flat, a, beta, lit, unlit)
    for p in range(6):
        for t in range(4):
            x = X[rows[p, t]]
            logs = [-0.5 * _normal_cost(S[p], off[k] + (on[k] - off[k]) * x, a, beta) for k in range(5)]
            assert np.isclose(lit[p, t], -2.0 * (np.logaddexp.reduce(logs) - np.log(5)), rtol=1e-10)
        logs = [-0.5 * _normal_cost(S[p], np.full(S.shape[1], f), a, beta) for f in flat]
        assert np.isclose(unlit[p], -2.0 * (np.logaddexp.reduce(logs) - np.log(3)), rtol=1e-10)


def test_every_codeword_column_is_decodes_own_model():
    """`model_costs` of each pixel's published candidates equals the distances `decode()`
    returns for them (the posterior's -2 log posterior, float32): the column sums decode()'s
    model, not another."""
    tool = _tool()
    code = get_code("ecc-22-10")
    col, albedo = scene(64, 48, seed=5)
    f, w, b = render(code.codebook, col, albedo, ambient=0.12, projector=0.12, seed=6, bits=12)
    d, noise, fdr, idx = tool.decode_with_model(f, w, b, 12, code)
    everywhere = np.ones(col.shape, bool)
    S = tool.ev.samples_of(f, w, b, 12, everywhere)
    own = np.empty((S.shape[0], code.size))
    tool.model_costs(S, tool.ev.symbols(code), float(noise.a), float(noise.beta), *kernel_args(noise.levels)[:7], own)
    cand = d.candidates.reshape(-1, 3)
    dist = d.distances.reshape(-1, 3).astype(np.float64)
    scored = (cand >= 0) & np.isfinite(dist)
    assert scored[:, 0].mean() > 0.9
    mine = np.take_along_axis(own, np.maximum(cand, 0), 1)
    assert np.allclose(mine[scored], dist[scored], rtol=2e-6, atol=1e-3)
    assert fdr.ndim == 1 and idx.shape == col.shape and noise.levels is not None


def test_published_errors_counts_wrong_and_unpublished():
    tool = _tool()
    rows = np.array([[0, 1, 5], [0, 1, 5], [3, 4, 9]], np.int64)
    cost = np.array([[0.0, 1.0, 40.0],   # best 0, its neighbour near: P(wrong) ~ 1e-9, right
                     [0.0, 30.0, 5.0],   # row 5 holds exp(-2.5) of the mass: unpublished
                     [0.0, 30.0, 40.0]])  # published, but the truth is 4 rows away... 3 vs truth 7
    truth = np.array([0, 0, 7])
    assert tool.published_errors(cost, rows, truth, np.zeros(3)) == 2
    assert tool.published_errors(cost[:1], rows[:1], truth[:1], np.array([0.5])) == 1  # P(not lit) 1/2
    assert tool.published_errors(cost[:1], rows[:1], truth[:1], np.zeros(1), np.array([0.0])) == 1  # unlit as likely
    assert tool.published_errors(cost[:1], rows[:1], truth[:1], np.zeros(1), np.array([60.0])) == 0


def test_a_small_run_prints_one_row_per_scene(capsys, tmp_path):
    tool = _tool()
    report = tmp_path / "limit" / "README.md"
    assert tool.main(["--size", "48x36", "--seeds", "0", "--ambient", "1", "--atoms", "32", "--top", "8",
                      "--out", str(report)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "\n".join(out) in report.read_text() and "--atoms 32 --top 8" in out[0]
    rows = [line for line in out if line.startswith("| edge.sim") or line.startswith("| plane-box-sphere")]
    assert len(rows) == 2
    for line in rows:
        cells = line.strip("|").split("|")[1:]
        assert len(cells) == 5
        for cell in cells:
            gray, ecc = (float(v.strip().split("%")[0]) for v in cell.split(" / ")[:2])
            assert 0.0 <= gray <= 100.0 and 0.0 <= ecc <= 100.0
