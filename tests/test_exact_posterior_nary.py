"""Exactness of `edge.decode.posterior.posterior` on a q-ary code (nary3-4: 81 words of 4
ternary symbols), where the kernel scores each candidate with its per-lane `_nll` path (the
binary fast path and the tail mass do not apply): against a brute-force reference written here
from the module docstring, on a tiny image (3 x 5, not a multiple of the lane count) with
absent candidates (-1) and unlit pixels (the
search's candidates are distinct, so duplicates are not among the inputs):

* each candidate's -2 log-posterior: its own least-squares levels on x = symbol / (q - 1)
  (white x = 1, black x = 0; c >= 0), the Gaussian with variance a + beta * max(mu, 0), plus the
  level prior's cost (`prior_cost`, checked against the kernels' lookup elsewhere);
* the candidates re-ordered by it;
* P(confused) = far / (1 + every) over the other scored candidates (no tail for q-ary codes),
  combined with P(not lit) as 1 - (1 - P(not lit)) (1 - P(confused)).  P(not lit) is taken
  from `not_lit_probability` of the brute-force gains (its lookup has its own test in
  tests/test_decode_posterior.py).

Tolerance: the kernel sums float32 samples in float64; rtol 1e-5 / atol 1e-3 on -2 log values of
order 10-100 and rtol 2e-3 on the error (exp of differences of such values) cover float32
samples' rounding, as in tests/test_decode_posterior.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from edge.codes import get_code
from edge.decode.level_prior import level_prior, prior_cost
from edge.decode.posterior import Noise, not_lit_probability, posterior


def _fit(r, x):
    c, b = np.polyfit(x, r, 1)
    if c < 0:
        c, b = 0.0, r.mean()
    return float(b), float(c)


def _nll(r, mu, a, beta):
    v = a + beta * np.maximum(mu, 0)
    return float(((r - mu) ** 2 / v + np.log(v)).sum())


@pytest.mark.parametrize("with_prior", [False, True])
@pytest.mark.parametrize("sigma", [0.02, 0.08])
def test_qary_posterior_matches_brute_force(sigma, with_prior):
    code = get_code("nary3-4")
    assert code.q == 3
    rng = np.random.default_rng([int(sigma * 100), with_prior])
    h, w = 3, 5
    rows = rng.integers(0, code.size, (h, w))
    lit = rng.random((h, w)) > 0.2
    x_true = code.codebook[rows].astype(np.float64) / (code.q - 1)
    clean = 0.1 + 0.3 * x_true * lit[..., None]
    frames = np.moveaxis(clean + rng.normal(0, sigma, clean.shape), -1, 0).astype(np.float32)
    white = (0.1 + 0.3 * lit + rng.normal(0, sigma, (h, w))).astype(np.float32)
    black = (0.1 + rng.normal(0, sigma, (h, w))).astype(np.float32)
    cand = np.stack([rows, (rows + 2) % code.size, (rows + 1) % code.size], -1).astype(np.int32)
    cand[0, 0, 2] = -1
    cand[1, 1, 1:] = -1
    prior = level_prior(rng.normal(0.1, 0.02, 3000), np.abs(rng.normal(0.3, 0.05, 3000))) if with_prior else None
    noise = Noise(sigma ** 2, 0.001, True, h * w, prior)
    out = posterior(frames, white, black, 1.0, code, cand, noise, choices=code.size)
    comp = np.zeros((h, w))
    gains = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            r = np.r_[frames[:, y, x], white[y, x], black[y, x]].astype(np.float64)
            ks = [int(k) for k in cand[y, x] if k >= 0]
            xk = {k: np.r_[code.codebook[k] / (code.q - 1), 1.0, 0.0] for k in ks}
            ls = {}
            for k in ks:
                b, c = _fit(r, xk[k])
                ls[k] = _nll(r, b + c * xk[k], noise.a, noise.beta) + float(prior_cost(prior, b, c))
            order = sorted(ks, key=lambda k: ls[k])
            got = [int(k) for k in out.candidates[y, x] if k >= 0]
            assert got == order, (y, x)
            np.testing.assert_allclose([out.distances[y, x, got.index(k)] for k in order], [ls[k] for k in order],
                                       rtol=1e-5, atol=1e-3)
            best = order[0]
            e = {k: np.exp(-(ls[k] - ls[best]) / 2) for k in order[1:]}
            far = sum(v for k, v in e.items() if abs(k - best) > 1)
            comp[y, x] = far / (1 + sum(e.values()))
            flat = _nll(r, np.full_like(r, r.mean()), noise.a, noise.beta)
            gains[y, x] = flat - min(_nll(r, _fit(r, xk[k])[0] + _fit(r, xk[k])[1] * xk[k], noise.a, noise.beta)
                                     for k in ks)
    dark = not_lit_probability(gains, code, code.size)
    np.testing.assert_allclose(out.error, 1 - (1 - dark) * (1 - comp), rtol=2e-3, atol=1e-6)
