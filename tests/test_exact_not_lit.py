"""Exactness of `edge.decode.posterior.not_lit_probability` against a brute-force reference written
here from its docstring (plain numpy; only the null law's Monte Carlo table comes from `_null`:
its sorted sample, tail quantile x_q and tail slope s).

The reference, per the docstring: the null survival ``S0(x) = P(gain >= x | not lit)`` is the
share of the null sample at or above x up to x_q, ``(1 - q) exp(-s (x - x_q))`` beyond (q =
`NULL_TAIL_QUANTILE`); a finite gain g falls in bin ``floor(sqrt(max(g, 0)) / GAIN_BIN)``, the
bins from nb on merged into the last, nb (the first bin edge past where the tail's survival is
below 1e-12 of its start, plus one); ``P0(k) = S0((k G)**2) - S0(((k + 1) G)**2)``; N the finite
gains, pi0 = ``min(1, #(g < null median) / (N / 2))`` (the null median: the sample's upper
median, element n // 2); per bin k < nb ``min(1, pi0 N P0(k) / count(k))`` (an empty bin counts
as one pixel: the literal x / 0 would set it, and by the envelope every bin below it, to 1),
then made non-increasing in u (each bin the maximum of itself and the bins above it), bin nb 0;
a pixel gets its bin's value, a gain that is not finite 0 (and it is not counted in N).

Compared (to 1e-12) on random gains mixing null draws and lit ones, with NaN, +-inf, negative
gains, zeros, gains exactly on bin edges and at the null median, gains beyond the last bin, an
image without finite gains, 1 x 1 and 1 x n images, float32 and non-contiguous input; with and
without inverse frames and for a few codebook row counts.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from edge.codes import get_code
from edge.decode.posterior import GAIN_BIN, NULL_TAIL_QUANTILE, _null, gain_bins, not_lit_probability

CODE = "ecc-22-10"


def _survival(x, sample, xq, slope):
    x = np.asarray(x, np.float64)
    emp = np.array([np.count_nonzero(sample >= v) for v in x.ravel()], np.float64).reshape(x.shape) / sample.size
    return np.where(x <= xq, emp, (1.0 - NULL_TAIL_QUANTILE) * np.exp(-slope * (x - xq)))


def _reference(gain, code, rows, inverse):
    sample, xq, slope = _null(code, rows, inverse)
    assert np.all(np.diff(sample) >= 0) and xq == pytest.approx(np.quantile(sample, NULL_TAIL_QUANTILE), rel=1e-12)
    median = sample[sample.size // 2]
    nb = math.ceil(math.sqrt(xq + math.log(1e12) / slope) / GAIN_BIN) + 1
    g = np.asarray(gain, np.float64)
    finite = np.isfinite(g)
    out = np.zeros(g.shape)
    n = int(finite.sum())
    if n == 0:
        return out, nb, median
    gf = g[finite]
    k = np.minimum(np.floor(np.sqrt(np.maximum(gf, 0.0)) / GAIN_BIN), nb).astype(int)
    count = np.array([np.count_nonzero(k == j) for j in range(nb)], np.float64)
    pi0 = min(1.0, np.count_nonzero(gf < median) / (n / 2.0))
    edges = (np.arange(nb + 1) * GAIN_BIN) ** 2
    s0 = _survival(edges, sample, xq, slope)
    p0 = np.maximum(s0[:-1] - s0[1:], 0.0)
    raw = [min(1.0, pi0 * n * p0[j] / max(count[j], 1.0)) for j in range(nb)]
    fdr = [max(raw[j:]) for j in range(nb)] + [0.0]
    out[finite] = np.array(fdr)[k]
    return out, nb, median


def _gains(rng, shape, code, rows, inverse, unlit_share):
    sample = _null(code, rows, inverse)[0]
    size = int(np.prod(shape))
    g = np.where(rng.random(size) < unlit_share, rng.choice(sample, size), rng.uniform(0.0, 300.0, size) ** 1.3)
    special = rng.random(size)
    g = np.where(special < 0.03, np.nan, g)
    g = np.where((special >= 0.03) & (special < 0.05), -rng.uniform(0, 5, size), g)
    g = np.where((special >= 0.05) & (special < 0.06), 0.0, g)
    g = np.where((special >= 0.06) & (special < 0.08), (rng.integers(0, 60, size) * GAIN_BIN) ** 2, g)  # on edges
    g = np.where((special >= 0.08) & (special < 0.09), sample[sample.size // 2], g)                    # the median
    g = np.where((special >= 0.09) & (special < 0.10), rng.uniform(1e4, 1e7, size), g)                 # past nb
    g = np.where((special >= 0.10) & (special < 0.105), np.inf, g)
    g = np.where((special >= 0.105) & (special < 0.11), -np.inf, g)
    return g.reshape(shape)


@pytest.mark.parametrize("inverse", [False, True])
@pytest.mark.parametrize("rows", [None, 40])
def test_matches_the_two_group_reference(inverse, rows):
    code = get_code(CODE)
    rows = code.size if rows is None else rows
    rng = np.random.default_rng([inverse, rows])
    _, nb, median = _reference(np.zeros((1, 1)), code, rows, inverse)
    assert gain_bins(code, rows, inverse) == (median, nb)
    for shape, share in [((48, 64), 0.3), ((48, 64), 0.0), ((40, 50), 0.9), ((1, 1), 0.5), ((1, 37), 0.5)]:
        g = _gains(rng, shape, code, rows, inverse, share)
        want, _, _ = _reference(g, code, rows, inverse)
        got = not_lit_probability(g, code, rows, inverse=inverse)
        assert got.shape == g.shape and got.dtype == np.float64
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12, err_msg=f"{shape} {share}")
    # the bins beyond the null's reach are lit; the envelope never rises with the gain
    g = _gains(rng, (64, 64), code, rows, inverse, 0.4)
    got = not_lit_probability(g, code, rows, inverse=inverse)
    order = np.argsort(np.where(np.isfinite(g), np.maximum(g, 0.0), np.inf).ravel(), kind="stable")
    finite = np.isfinite(g).ravel()[order]
    assert np.all(np.diff(got.ravel()[order][finite]) <= 0.0)
    assert np.all(got[np.isfinite(g) & (g >= (nb * GAIN_BIN) ** 2)] == 0.0)


def test_edge_cases_match_the_reference():
    code = get_code(CODE)
    rows = code.size
    sample, xq, _ = _null(code, rows)
    median = sample[sample.size // 2]
    cases = [
        np.full((5, 7), np.nan),                                      # no finite gain: all 0
        np.array([[np.nan, np.inf, -np.inf]]),
        np.array([[0.0]]), np.array([[-3.0]]), np.array([[1e9]]),    # one pixel
        np.array([[median, np.nextafter(median, 0.0), np.nextafter(median, np.inf)]]),  # at the null median
        np.array([[(k * GAIN_BIN) ** 2 for k in range(80)]]),         # every bin edge, once
        np.full((3, 3), 2.0), np.zeros((2, 6)), np.full((4, 4), -1.0),
        np.array([[xq, np.nextafter(xq, np.inf), 2.0 * xq, np.nan]]),  # across the tail quantile
    ]
    for g in cases:
        want, _, _ = _reference(g, code, rows, False)
        got = not_lit_probability(g, code, rows)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12, err_msg=str(g))
    assert (not_lit_probability(cases[0], code, rows) == 0.0).all()
    # float32 and non-contiguous gains: the same as their float64 contiguous copy
    rng = np.random.default_rng(9)
    g = _gains(rng, (30, 40), code, rows, False, 0.5)
    f32 = g.astype(np.float32)
    np.testing.assert_allclose(not_lit_probability(f32, code, rows), _reference(f32.astype(np.float64), code, rows,
                                                                                False)[0], rtol=1e-12, atol=1e-12)
    view = g.T[::2]
    np.testing.assert_allclose(not_lit_probability(view, code, rows), _reference(view, code, rows, False)[0],
                               rtol=1e-12, atol=1e-12)
