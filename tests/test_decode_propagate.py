"""Candidate propagation (`edge.decode.propagate`) for method "sgm".

Exactness: the four sweeps against a pixel-by-pixel reference of the module docstring, with its
own least-squares refit and Gaussian likelihood (numpy, independent of the numba kernels), on
small random captures with and without inverse frames and a level prior.  Behaviour, with `decode`'s defaults:
on edge.sim at ambient = 2 x projector, where many lit pixels have no top-3 candidate within one
row of the truth, sgm with propagation errs on fewer pixels than that floor (which bounds any
regularisation of the top three alone), and on both scene generators it stays within the error
target on the published pixels.
"""

from __future__ import annotations

import numpy as np
import pytest

from edge.codes import get_code
from edge.decode import decode
from edge.decode.level_prior import level_prior, prior_cost
from edge.decode.posterior import Noise
from edge.decode.propagate import propagate
from edge.decode.sgm import penalties
from test_decode_sgm import _pbs, _sim  # the same two generators as the sgm tests

ECC = get_code("ecc-22-10")


# -------------------------------------------------------------------------- reference

def _nll_ref(samples, x, a, beta, prior=None):
    """-2 log-likelihood of samples (m,) under levels b + c x (x (m,) in [0, 1]) refitted by least
    squares with c >= 0, variance a + beta * max(level, 0); plus the level prior's cost (the
    posterior's distance) where a prior is given."""
    m = samples.size
    sx, sxx, sr, sxr = x.sum(), (x * x).sum(), samples.sum(), (x * samples).sum()
    den = m * sxx - sx * sx
    c = max((m * sxr - sx * sr) / den, 0.0) if den > 0 else 0.0
    b = (sr - c * sx) / m
    mu = b + c * x
    v = a + beta * np.maximum(mu, 0.0)
    return float(((samples - mu) ** 2 / v + np.log(v)).sum() + prior_cost(prior, b, c))


def _propagate_ref(samples, xtab, cand, dist, error, a, beta, max_error, choices, rows, prior=None):
    """The module docstring, pixel by pixel.  samples (H, W, m) normalised (code samples, white,
    black); xtab (rows, m - 2) symbols / (q - 1)."""
    h, w, _ = samples.shape
    bound = 4.0 * penalties(choices).p2
    confident = (error < max_error) & (cand[..., 0] >= 0)
    track = np.where(confident, cand[..., 0], -1)
    track_l = np.where(confident, dist[..., 0].astype(np.float64), np.inf)
    extra = np.full((h, w), -1)
    extra_l = np.full((h, w), np.inf)

    def visit(y, x, c):
        best, best_l = -1, np.inf
        for r in (c - 1, c, c + 1):
            if not 0 <= r < rows:
                continue
            hits = [k for k in range(3) if cand[y, x, k] == r and np.isfinite(dist[y, x, k])]
            if hits:
                lr = float(dist[y, x, hits[-1]])
            else:
                lr = _nll_ref(samples[y, x], np.concatenate([xtab[r], [1.0, 0.0]]), a, beta, prior)
            if lr < best_l:
                best, best_l = r, lr
        if best < 0 or 0.5 * (best_l - float(dist[y, x, 0])) > bound:
            return
        if best_l < track_l[y, x]:
            track[y, x], track_l[y, x] = best, best_l
        scored = [cand[y, x, k] for k in range(3) if np.isfinite(dist[y, x, k])]
        if best not in scored and best_l < extra_l[y, x]:
            extra[y, x], extra_l[y, x] = best, best_l

    sweeps = ([(y, x, y, x - 1) for y in range(h) for x in range(1, w)],
              [(y, x, y, x + 1) for y in range(h) for x in range(w - 2, -1, -1)],
              [(y, x, y - 1, x) for x in range(w) for y in range(1, h)],
              [(y, x, y + 1, x) for x in range(w) for y in range(h - 2, -1, -1)])
    for sweep in sweeps:
        for y, x, qy, qx in sweep:
            if not confident[y, x] and cand[y, x, 0] >= 0 and track[qy, qx] >= 0:
                visit(y, x, int(track[qy, qx]))
    return extra, np.where(extra >= 0, extra_l, np.inf)


def _case(seed, inverse, with_prior=False):
    """A small slanted-surface capture of ecc-22-10 (uint16 12-bit) with synthetic top-3
    candidates: the truth left out of some pixels, unscored rows (inf distance), absent ones;
    with_prior: a level prior of levels drawn as the capture's (its distances include it)."""
    rng = np.random.default_rng(seed)
    h, w, n = 7, 9, ECC.n
    truth_col = 200 + np.arange(w)[None, :] + np.arange(h)[:, None] // 3
    bits = ECC.codebook[truth_col].astype(np.float64)                      # (H, W, n)
    level_on, level_off = rng.uniform(0.3, 0.6, (h, w)), rng.uniform(0.02, 0.1, (h, w))
    clean = level_off[..., None] + (level_on - level_off)[..., None] * bits
    parts = [clean] + ([level_off[..., None] + (level_on - level_off)[..., None] * (1 - bits)] if inverse else [])
    code_samples = np.concatenate(parts, axis=2)
    white, black = level_on, level_off
    noisy = lambda v: np.clip(np.round((v + rng.normal(0, 0.03, v.shape)) * 4095), 0, 4095).astype(np.uint16)
    frames = noisy(np.moveaxis(code_samples[..., :n], -1, 0))
    inv = noisy(np.moveaxis(code_samples[..., n:], -1, 0)) if inverse else None
    white_raw, black_raw = noisy(white), noisy(black)
    scale = 1.0 / 4095.0
    stack = [frames] + ([inv] if inverse else [])
    samples = np.concatenate([np.moveaxis(np.concatenate(stack, 0), 0, -1), white_raw[..., None], black_raw[..., None]],
                             axis=2).astype(np.float64) * scale
    xtab = ECC.codebook.astype(np.float64)
    if inverse:
        xtab = np.concatenate([xtab, 1.0 - xtab], axis=1)
    a, beta = 0.03 ** 2, 0.0
    prior = None
    if with_prior:
        off = rng.uniform(0.02, 0.1, 4000)
        prior = level_prior(off, rng.uniform(0.3, 0.6, 4000) - off)
    cand = np.empty((h, w, 3), np.int32)
    dist = np.empty((h, w, 3), np.float32)
    for y in range(h):
        for x in range(w):
            t = truth_col[y, x]
            rows = [t, t + rng.integers(5, 300), t - rng.integers(5, 150)] if rng.random() < 0.5 else \
                [t + 17, t + rng.integers(20, 300), t - rng.integers(20, 150)]
            ls = [_nll_ref(samples[y, x], np.concatenate([xtab[r], [1.0, 0.0]]), a, beta, prior) for r in rows]
            order = np.argsort(ls)
            cand[y, x] = np.asarray(rows)[order]
            dist[y, x] = np.asarray(ls)[order]
            if rng.random() < 0.2:
                dist[y, x, 2] = np.inf          # not rescored
            if rng.random() < 0.1:
                cand[y, x, 1:], dist[y, x, 1:] = -1, np.inf
    error = rng.uniform(0.0, 0.03, (h, w)).astype(np.float32)
    return frames, white_raw, black_raw, inv, scale, samples, xtab, cand, dist, error, a, beta, prior


@pytest.mark.parametrize("seed, inverse, with_prior", [(0, False, False), (1, False, True), (2, True, True)])
def test_propagation_matches_the_pixel_by_pixel_reference(seed, inverse, with_prior):
    frames, white, black, inv, scale, samples, xtab, cand, dist, error, a, beta, prior = _case(seed, inverse, with_prior)
    assert (prior is not None) == with_prior
    got = propagate(frames, white, black, scale, ECC, cand, dist, error, Noise(a, beta, True, 0, prior), max_error=0.01,
                    choices=ECC.size, inverse=inv)
    want, want_l = _propagate_ref(samples, xtab, cand, dist, error, a, beta, 0.01, ECC.size, ECC.size, prior)
    assert got.candidates.shape == (7, 9, 4) and got.distances.shape == (7, 9, 4)
    np.testing.assert_array_equal(got.candidates[..., :3], cand)
    np.testing.assert_array_equal(got.distances[..., :3], dist)
    np.testing.assert_array_equal(got.candidates[..., 3], want)
    np.testing.assert_allclose(got.distances[..., 3], want_l.astype(np.float32), rtol=1e-6)
    assert got.extra.sum() == (want >= 0).sum() > 0     # the case exercises the extra state


def test_propagation_checks_its_inputs():
    frames, white, black, inv, scale, samples, xtab, cand, dist, error, a, beta, _ = _case(0, False)
    noise = Noise(a, beta, True, 0)
    with pytest.raises(ValueError, match="max_error"):
        propagate(frames, white, black, scale, ECC, cand, dist, error, noise, max_error=0.0, choices=ECC.size)
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        propagate(frames, white, black, scale, ECC, cand[..., :2], dist, error, noise, max_error=0.01, choices=10)


# -------------------------------------------------------------------------- behaviour

# measured (160 x 120, ambient 2; error = wrong or invalid over lit pixels): edge.sim seed 5: soft
#   5.8 %, top-3 floor 2.2 %, sgm 0.96 % (far among published 0.07 %); plane-box-sphere seed 6:
#   soft 12.3 %, floor 1.0 %, sgm 0.55 % (0.16 %)
@pytest.mark.parametrize("gen, seed", [(_sim, 5), (_pbs, 6)])
def test_sgm_reaches_pixels_without_a_near_candidate(gen, seed):
    f, w, b, col, lit = gen(2.0, seed)
    soft = decode(f, w, b, ECC, bit_depth=12)
    sgm = decode(f, w, b, ECC, bit_depth=12, method="sgm")
    n = lit.sum()
    floor = (~(np.abs(soft.candidates - col[..., None]) <= 1).any(-1) & lit).sum() / n
    err = (((sgm.column != col) | ~sgm.valid) & lit).sum() / n
    far = ((np.abs(sgm.column - col) > 1) & sgm.valid & lit).sum() / max((sgm.valid & lit).sum(), 1)
    soft_err = (((soft.column != col) | ~soft.valid) & lit).sum() / n
    print(f"{gen.__name__}: soft {soft_err:.4f}, top-3 floor {floor:.4f}, sgm {err:.4f}, far {far:.4f}")
    assert 0.02 <= soft_err <= 0.3
    assert err * 4.0 <= soft_err
    if gen is _sim:
        assert floor >= 0.02 and err < floor   # below what any choice among the top three can reach
    assert far <= 0.01
    assert sgm.candidates.shape == soft.candidates.shape
