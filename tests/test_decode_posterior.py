"""The self-calibrated "error" validity rule (`edge.decode.posterior`), measured with `decode`'s defaults.

Exactness: `split_levels` and `posterior` against brute-force numpy references.  Behaviour, on two
scene generators (`edge.sim`'s flying scene and the independent `_plane_box_sphere` renderer),
at fixed total exposure (every frame, white and black included, at T / n), invalid pixels
counted as errors: the coding gain of ecc-22-10 over gray-10, the error rate among published
pixels, the spatial methods, 12-bit data in uint16 without `bit_depth`, and the noise fit.
Nothing here passes a threshold or a noise parameter: every decode runs the defaults.
"""

from __future__ import annotations

import numpy as np
import pytest

from _plane_box_sphere import render, scene as pbs_scene
from edge.codes import get_code
from edge.decode import decode
from edge.decode.level_prior import level_prior, prior_cost
from edge.decode.posterior import (FULL_SCALE_SAMPLE, Noise, _noise_from, _split_levels, fit_noise, fit_step, posterior,
                                   split_levels)
from edge.eval.report import calibration_verdict, poisson_interval
from edge.sim import CameraModel, capture_code
from edge.sim.metrics import truth
from edge.sim.scenes import make_scene

GRAY, ECC = get_code("gray-10"), get_code("ecc-22-10")


# -------------------------------------------------------------------------- brute-force references

def _split_reference(samples: np.ndarray, *, threshold: bool = False) -> tuple[float, ...]:
    """Lloyd's two-means as `split_levels` states it (samples: the n frames, then white, black),
    in its arithmetic: sums in the samples' order, the lower class's mean as (total - upper sum)
    / its count (a sample exactly at a threshold goes by those roundings).  (hi, lo), with
    ``threshold`` (hi, lo, the final threshold)."""
    s = samples.astype(np.float64)
    top, bottom = s.max(), s.min()
    total = sum(s.tolist())
    t = 0.5 * (s[-2] + s[-1]) if s[-2] > s[-1] else 0.5 * (top + bottom)
    hi, lo, last = top, bottom, -1
    for _ in range(4):
        up = s > t
        if up.all() or not up.any():
            t = 0.5 * (top + bottom)
            up = s > t
            if up.all() or not up.any():
                break
        upper = sum(s[up].tolist())
        hi, lo = upper / up.sum(), (total - upper) / (~up).sum()
        t = 0.5 * (hi + lo)
        if up.sum() == last:
            break
        last = up.sum()
    return (hi, lo, t) if threshold else (hi, lo)


def _split_residual_reference(samples: np.ndarray) -> tuple[float, float]:
    """(s2, mu) of one pixel as `split_levels` states it: the residuals of the samples about the
    level of their side of the final threshold, summed in the samples' order, over m - 2 (NaN where
    a sample is at 0 or full scale), and the samples' mean.  samples: raw * scale in float64, as
    the kernel normalises them (raw / 255 rounds differently, and a sample exactly at the
    threshold then changes sides)."""
    s = samples.astype(np.float64)
    hi, lo, t = _split_reference(s, threshold=True)
    ssr = 0.0
    for v in s.tolist():
        e = v - (hi if v > t else lo)
        ssr += e * e
    clipped = bool(((s <= 0.0) | (s >= FULL_SCALE_SAMPLE)).any())
    return (np.nan if clipped else ssr / (s.size - 2)), sum(s.tolist()) / s.size


def test_split_levels_matches_brute_force():
    """Random pixels, and (row 1, in one block of lanes with ordinary pixels) flat pixels, pixels
    whose calibration split leaves one class, white <= black; 70 columns: a partial lane block."""
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 256, (10, 5, 70)).astype(np.uint8)
    white = rng.integers(100, 256, (5, 70)).astype(np.uint8)
    black = rng.integers(0, 100, (5, 70)).astype(np.uint8)
    frames[:, 1, :6], white[1, :6], black[1, :6] = 9, 9, 9  # flat
    frames[:, 1, 6:12], white[1, 6:12], black[1, 6:12] = 200, 250, 180  # every code sample above the midpoint
    white[1, 12:20], black[1, 12:20] = black[1, 12:20], white[1, 12:20]  # white <= black
    hi, lo, _ = split_levels(frames, white, black, 1 / 255)
    for y in range(5):
        for x in range(70):
            ref_hi, ref_lo = _split_reference(np.r_[frames[:, y, x], white[y, x], black[y, x]] / 255)
            assert hi[y, x] == pytest.approx(max(ref_hi, ref_lo + 1e-6), rel=1e-5)
            assert lo[y, x] == pytest.approx(ref_lo, rel=1e-5, abs=1e-7)


def _split_capture(h: int, w: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random uint8 frames (10, h, w), white and black (some samples at 0 and 255: clipped)."""
    rng = np.random.default_rng(seed)
    return (rng.integers(0, 256, (10, h, w)).astype(np.uint8), rng.integers(100, 256, (h, w)).astype(np.uint8),
            rng.integers(0, 100, (h, w)).astype(np.uint8))


@pytest.mark.parametrize("step", [1, 3, 64, 67])
def test_split_levels_residuals_of_every_step_th_pixel_match_brute_force(step):
    """The kernel's residual variance and mean level of pixel p (row-major) where p % step == 0,
    at index p // step (lane blocks that start at any phase of the step, a partial last block)."""
    frames, white, black = _split_capture(5, 70, 1)
    k = -(-(5 * 70) // step)
    hi, lo = np.empty((5, 70), np.float32), np.empty((5, 70), np.float32)
    s2, mu = np.full(k, -1.0), np.full(k, -1.0)
    _split_levels(frames, white, black, np.float64(1 / 255), step, hi, lo, s2, mu)
    for p in range(0, 5 * 70, step):
        y, x = divmod(p, 70)
        ref_s2, ref_mu = _split_residual_reference(np.r_[frames[:, y, x], white[y, x], black[y, x]] * (1 / 255))
        assert mu[p // step] == ref_mu  # bit for bit: the same operations in the same order
        if np.isnan(ref_s2):
            assert np.isnan(s2[p // step])
        else:
            assert s2[p // step] == ref_s2


def test_split_levels_fits_the_noise_to_the_pixels_the_fit_samples():
    """Above `FIT_PIXELS` pixels the noise model is `_noise_from`'s fit of the full grid's
    residuals, which takes every `fit_step`-th pixel: the split levels compute just those."""
    h, w = 205, 200
    assert fit_step(h * w) == 2
    frames, white, black = _split_capture(h, w, 2)
    s2 = np.random.default_rng(3).random((h, w))  # pixels the fit must not read: noise
    mu = np.random.default_rng(4).random((h, w))
    for p in range(0, h * w, 2):
        y, x = divmod(p, w)
        s2[y, x], mu[y, x] = _split_residual_reference(np.r_[frames[:, y, x], white[y, x], black[y, x]] * (1 / 255))
    _, _, noise = split_levels(frames, white, black, 1 / 255)
    want = _noise_from(s2, mu, frames, 1 / 255, (0.01, 0.03))
    assert noise.fitted and want.fitted
    assert (noise.a, noise.beta) == (want.a, want.beta)


def _fit_reference(r: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """Least-squares (b, c) of r = b + c x with c >= 0 (c = 0: b = the mean)."""
    c, b = np.polyfit(x, r, 1)
    if c < 0:
        c, b = 0.0, r.mean()
    return float(b), float(c)


def _nll_at(r: np.ndarray, mu: np.ndarray, a: float, beta: float) -> float:
    """Gaussian -2 log-likelihood of samples r about means mu, variance a + beta * max(mu, 0)."""
    v = a + beta * np.maximum(mu, 0)
    return float(((r - mu) ** 2 / v + np.log(v)).sum())


def _nll_reference(r: np.ndarray, x: np.ndarray | None, a: float, beta: float) -> float:
    if x is None:
        return _nll_at(r, np.full_like(r, r.mean()), a, beta)
    b, c = _fit_reference(r, x)
    return _nll_at(r, b + c * x, a, beta)


def _posterior_reference(r: np.ndarray, x: np.ndarray, a: float, beta: float, prior) -> float:
    """-2 log-posterior of one codeword (up to a constant): its refitted likelihood plus the
    level prior's cost at its levels."""
    b, c = _fit_reference(r, x)
    return _nll_at(r, b + c * x, a, beta) + float(prior_cost(prior, b, c))


def _tail_reference(r: np.ndarray, code, best: int, scored: list[int], a: float, beta: float, prior) -> float:
    """The tail mass as `edge.decode.posterior` defines it: over the codewords c = best xor h, h
    of weight d_min .. d_min + 2 (an evenly spaced sample of at most 1024, scaled up to all of
    them), exp(-(P_c - P_best) / 2) with P each word's own refitted likelihood plus the level
    prior, minus the same term of the other scored candidates where they are such a word."""
    ends = np.array([1.0, 0.0])
    p_best = _posterior_reference(r, np.r_[code.codebook[best], ends], a, beta, prior)
    weights = code.codebook.sum(axis=1)
    dmin = weights[weights > 0].min()
    low = np.nonzero((weights > 0) & (weights <= dmin + 2))[0]
    sample = low[np.unique(np.linspace(0, low.size - 1, min(1024, low.size)).round().astype(int))]

    def term(word):
        return np.exp(-0.5 * (_posterior_reference(r, np.r_[word, ends].astype(np.float64), a, beta, prior) - p_best))

    own = code.codebook[best]
    total = low.size / sample.size * sum(term(own ^ code.codebook[h]) for h in sample)
    for k in scored[1:]:
        flip = code.codebook[best] ^ code.codebook[k]
        if dmin <= flip.sum() <= dmin + 2:
            total -= term(code.codebook[k])
    return max(total, 0.0)


@pytest.mark.parametrize("sigma, with_prior", [(0.05, False), (0.05, True), (0.12, True)])
def test_posterior_matches_brute_force(sigma, with_prior):
    """Candidates re-ordered by refitted likelihood plus level prior, the competitor and tail
    mass (every tail word refitted), and the not-lit probability (from the brute-force gains,
    which leave the prior out), at high and at low SNR."""
    from edge.decode.posterior import not_lit_probability

    code = get_code("ecc-15-10")
    rng = np.random.default_rng(1)
    h, w = 6, 8
    rows = rng.integers(0, code.size, (h, w))
    lit = rng.random((h, w)) > 0.2  # some pixels only see ambient light
    clean = 0.1 + 0.3 * code.codebook[rows].astype(np.float64) * lit[..., None]
    frames = np.moveaxis(clean + rng.normal(0, sigma, clean.shape), -1, 0).astype(np.float32)
    white = (0.1 + 0.3 * lit + rng.normal(0, sigma, (h, w))).astype(np.float32)
    black = (0.1 + rng.normal(0, sigma, (h, w))).astype(np.float32)
    cand = np.stack([rows, rng.integers(0, code.size, (h, w)), (rows + 1) % code.size], -1).astype(np.int32)
    cand[0, 0, 2] = -1
    # a prior of levels like the capture's: off 0.1, on - off 0.3 (lit) or 0 (not lit), with spread
    prior = level_prior(rng.normal(0.1, 0.02, 3000), np.where(rng.random(3000) > 0.2, rng.normal(0.3, 0.05, 3000),
                                                                 np.abs(rng.normal(0.0, 0.03, 3000)))) if with_prior else None
    assert (prior is not None) == with_prior
    noise = Noise(sigma ** 2, 0.001, True, h * w, prior)
    out = posterior(frames, white, black, 1.0, code, cand, noise, choices=code.size)
    weights = code.codebook.sum(axis=1)
    low_words = int(((weights > 0) & (weights <= weights[weights > 0].min() + 2)).sum())  # all, not the sample
    gains = np.full((h, w), np.nan)
    comp = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            r = np.r_[frames[:, y, x], white[y, x], black[y, x]].astype(np.float64)
            ks = [k for k in cand[y, x] if k >= 0]
            xk = {k: np.r_[code.codebook[k], 1, 0].astype(np.float64) for k in ks}
            ls = {k: _posterior_reference(r, xk[k], noise.a, noise.beta, prior) for k in ks}
            order = sorted(ks, key=lambda k: ls[k])
            assert list(out.candidates[y, x, :len(order)]) == order
            np.testing.assert_allclose(out.distances[y, x, :len(order)], [ls[k] for k in order], rtol=1e-5, atol=1e-3)
            best = order[0]
            e = {k: np.exp(-(ls[k] - ls[best]) / 2) for k in order[1:]}
            far = sum(v for k, v in e.items() if abs(k - best) > 1)
            every = sum(e.values())
            # the kernel's rule: a tail only behind a third candidate that is not negligible
            if len(order) == 3 and low_words * e[order[2]] > 1e-4 and far < 1 + every - far:
                tail = _tail_reference(r, code, best, order, noise.a, noise.beta, prior)
                far, every = far + tail, every + tail
            comp[y, x] = far / (1 + every)
            gains[y, x] = _nll_reference(r, None, noise.a, noise.beta) - min(_nll_reference(r, xk[k], noise.a, noise.beta)
                                                                             for k in ks)
    dark = not_lit_probability(gains, code, code.size)
    ref = 1 - (1 - dark) * (1 - comp)
    exact = comp < 0.5  # from P(confused) = 1/2 up the tail's sum may stop: a lower bound, at least 1/2
    np.testing.assert_allclose(out.error[exact], ref[exact], rtol=2e-3, atol=1e-6)
    half = 1 - (1 - dark[~exact]) * 0.5
    assert np.all(out.error[~exact] >= half - 1e-6) and np.all(out.error[~exact] <= ref[~exact] * (1 + 2e-3) + 1e-6)
    if sigma > 0.1:  # the terms this test is about matter at low SNR
        assert dark.max() > 0.5 and comp.max() > 0.05
        assert 0.05 < comp[exact].max() < 0.5  # the exact range holds tail-mass pixels too


@pytest.mark.parametrize("name, inverse", [("ecc-63-10", True), ("ecc-63-10", False), ("gray-10", True)])
def test_lane_nll_equals_the_per_pixel_nll(name, inverse):
    """The posterior kernel's lane-parallel likelihoods of a binary code (`_lane_nll`, symbols read
    from packed words: two words for the 126 samples of ecc-63-10 with inverse frames) give every
    output bit for bit as its per-pixel route (`_nll`, which reads `_xtab`), which the kernel
    takes for codes of more than two symbols; rows of a lane block with and without candidates."""
    import edge.decode.posterior as P
    from edge.decode.level_prior import contrast_edges, kernel_args
    from edge.decode.synthetic import make_capture

    code = get_code(name)
    rng = np.random.default_rng(3)
    h, w = 4, 40
    cap = make_capture(code, rng.integers(0, code.size, (h, w)), rng=rng, albedo=rng.uniform(0.05, 0.6, (h, w)),
                       sigma_s=0.05, inverse=inverse)
    samples = P._samples(cap.frames, cap.inverse)
    cand = rng.integers(0, code.size, (h, w, 3)).astype(np.int32)
    cand[1, :5] = -1
    prior = level_prior(rng.normal(0.1, 0.02, 3000), np.abs(rng.normal(0.3, 0.1, 3000)))
    outs = []
    for binary in (True, False):
        out = [np.empty((h, w, 3), np.int32), np.empty((h, w, 3), np.float32), np.empty((h, w)), np.empty((h, w)),
               np.empty((h, w), np.float32), np.empty((h, w), np.float32), np.zeros((h, w)), np.zeros((h, w)),
               np.zeros((h, w)), np.empty((h, w), np.uint8), np.empty((h, w), np.float32)]
        tail = P._flips(code)
        P._posterior(samples, cap.white, cap.black, np.float64(1 / 255), P._xtab(code, inverse),
                     P._words(code, inverse), cand, np.zeros((h, w, 3), np.float32), 4e-4, 0.002, tail.flips,
                     float(tail.weight), binary, 1, *kernel_args(prior)[:7], contrast_edges(prior), *out)
        outs.append(out)
    assert P._words(code, inverse)[1].any() == (samples.shape[0] > 64)
    for i, (a, b) in enumerate(zip(*outs)):
        np.testing.assert_array_equal(a, b, err_msg=f"output {i}")


def test_not_lit_probability_follows_the_share_of_unlit_pixels():
    """Gains of unlit pixels drawn from the null law get P(not lit) near 1; strongly lit ones 0;
    with no unlit pixels in the capture, the mid-range gains are not called unlit."""
    from edge.decode.posterior import _null, not_lit_probability

    code = get_code("ecc-22-10")
    sample = _null(code, code.size)[0]
    rng = np.random.default_rng(5)
    unlit = rng.choice(sample, 5000)
    lit = rng.uniform(60.0, 400.0, 5000)
    mixed = not_lit_probability(np.r_[unlit, lit][None, :], code, code.size)[0]
    assert np.median(mixed[:5000]) > 0.9 and mixed[5000:].max() < 1e-3
    only_lit = not_lit_probability(rng.uniform(25.0, 400.0, 10000)[None, :], code, code.size)[0]
    assert only_lit.max() < 0.05


# ------------------------------------------------------------------------------ scene generators

def _sim(code, ratio: float, *, seed: int = 0):
    """edge.sim flying scene, 12-bit, ambient = ratio x projector, shot-noise dominated."""
    scene = make_scene("flying", 160, 120, seed=seed)
    a = 0.8 * ratio / (1 + ratio)
    cam = CameraModel(bits=12, sigma_r=0.002, sigma_s=0.04, ambient=a, projector=0.8 - a)
    cap = capture_code(scene, code, cam, rng=np.random.default_rng([seed, 7]))
    col, lit = truth(scene)
    return cap.frames, cap.white, cap.black, 12, col, lit


def _pbs(code, ratio: float, *, bits: int | None = 12, seed: int = 3):
    """The independent renderer: projector 0.12, ambient = ratio x projector."""
    col, albedo = pbs_scene(160, 120, seed=seed)
    f, w, b = render(code.codebook, col, albedo, ambient=0.12 * ratio, projector=0.12, bits=bits, seed=seed + 1)
    return f, w, b, (bits if bits not in (None, 8) else None), col, np.ones(col.shape, bool)


def _errors(gen, code, ratio, **kw) -> tuple[float, float]:
    """(error rate: wrong or invalid over lit pixels, off-by->1 rate among valid lit pixels)."""
    f, w, b, bit_depth, col, lit = gen(code, ratio, **kw)
    d = decode(f, w, b, code, bit_depth=bit_depth)
    err = (((d.column != col) | ~d.valid) & lit).sum() / lit.sum()
    far = ((np.abs(d.column - col) > 1) & d.valid & lit).sum() / max((d.valid & lit).sum(), 1)
    return float(err), float(far)


@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0])
def test_coding_gain_with_defaults_edge_sim(ratio):
    g, g_far = _errors(_sim, GRAY, ratio)
    e, e_far = _errors(_sim, ECC, ratio)
    print(f"edge.sim ambient {ratio}: gray-10 {g:.4f}, ecc-22-10 {e:.4f} ({g / e:.1f}x)")
    assert 0.05 <= g <= 0.6  # the regime of the claim
    assert g >= 2.0 * e      # measured 81x / 2.7x / 2.5x (tools/eval_posterior.py)
    assert max(g_far, e_far) <= 0.02  # published pixels meet the 1 % target within 2x


@pytest.mark.parametrize("bits", [12, 8, None])
@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0])
def test_coding_gain_with_defaults_independent_renderer(ratio, bits):
    g, g_far = _errors(_pbs, GRAY, ratio, bits=bits)
    e, e_far = _errors(_pbs, ECC, ratio, bits=bits)
    print(f"plane-box-sphere ambient {ratio} bits {bits}: gray-10 {g:.4f}, ecc-22-10 {e:.4f} ({g / e:.1f}x)")
    assert g >= 0.05
    assert g >= 3.0 * e      # measured 31-45x / 16-18x / 5x
    assert max(g_far, e_far) <= 0.02


@pytest.mark.parametrize("gen, ratio", [(_sim, 0.25), (_sim, 2.0), (_pbs, 0.25), (_pbs, 2.0)],
                         ids=["edge.sim-0.25", "edge.sim-2", "plane-box-sphere-0.25", "plane-box-sphere-2"])
@pytest.mark.parametrize("name, method", [("ecc-22-10", "soft"), ("ecc-63-10", "soft"), ("gray-10", "soft"),
                                          ("ecc-22-10", "sgm"), ("gray-10", "sgm")])
def test_soft_search_margin_leaves_every_output_as_the_exact_search_does(monkeypatch, gen, ratio, name, method):
    """`decode()`'s soft search locates the second and third candidates only within the
    posterior's skip margin (`SKIP_MARGIN`), for methods "soft" and "sgm" (whose propagation and
    unaries take a candidate of distance inf as absent): column, valid, error, confidence and
    distances equal those of a decode whose search returns the exact top three, and a candidate
    differs only where the exact decode's distance is inf (not rescored) and the margin's is -1."""
    import edge.decode.decoder as decoder

    code = get_code(name)
    f, w, b, bd, _, _ = gen(code, ratio)
    fast = decode(f, w, b, code, bit_depth=bd, method=method)
    search = decoder.search_candidates
    monkeypatch.setattr(decoder, "search_candidates", lambda *a, **k: search(*a, **dict(k, margin=None)))
    exact = decode(f, w, b, code, bit_depth=bd, method=method)
    for field in ("column", "valid", "error", "confidence", "distances"):
        np.testing.assert_array_equal(getattr(fast, field), getattr(exact, field), err_msg=field)
    moved = fast.candidates != exact.candidates
    assert (fast.candidates[moved] == -1).all() and np.isinf(exact.distances[moved]).all()
    assert exact.stats["margin_pixels"] == 0
    if gen is _sim and ratio < 1:  # bright enough that the margin finishes pixels and skips blocks
        assert fast.stats["margin_pixels"] > 0 and fast.stats["margin_blocks"] > 0


@pytest.mark.parametrize("name, method", [("ecc-22-10", "soft"), ("gray-10", "soft"), ("ecc-22-10", "sgm")])
def test_soft_search_margin_in_a_band_leaves_every_output_as_the_exact_search_does(monkeypatch, name, method):
    """As above, with a disparity band (the band search, whose blocks the lane search's first
    step finishes where every pixel is beyond the margin): bright and dim rows."""
    import edge.decode.decoder as decoder
    from edge.decode.synthetic import make_capture

    code = get_code(name)
    rng = np.random.default_rng(12)
    h, w = 12, 200
    cols = np.clip(np.arange(w)[None, :] - rng.integers(0, 40, (h, w)), 0, code.size - 1)
    albedo = np.where(np.arange(h)[:, None] < 8, rng.uniform(0.5, 0.9, (h, w)), rng.uniform(0.02, 0.2, (h, w)))
    cap = make_capture(code, cols, rng=rng, albedo=albedo, ambient=0.05, sigma_r=0.01, sigma_s=0.03)
    kw = dict(min_disparity=0, max_disparity=40, method=method)
    fast = decode(cap.frames, cap.white, cap.black, code, **kw)
    search = decoder.search_candidates
    monkeypatch.setattr(decoder, "search_candidates", lambda *a, **k: search(*a, **dict(k, margin=None)))
    exact = decode(cap.frames, cap.white, cap.black, code, **kw)
    assert fast.stats["path"] == "band" and fast.stats["margin_blocks"] > 0 and exact.stats["margin_blocks"] == 0
    for field in ("column", "valid", "error", "confidence", "distances"):
        np.testing.assert_array_equal(getattr(fast, field), getattr(exact, field), err_msg=field)
    moved = fast.candidates != exact.candidates
    assert moved.any() and (fast.candidates[moved] == -1).all() and np.isinf(exact.distances[moved]).all()


@pytest.mark.parametrize("validity", ["error", "confidence"])
def test_refit_levels_search_only_the_best_and_decode_as_before(monkeypatch, validity):
    """`levels="refit"` reads only the best candidate of its first searches, which run with no
    margin (`decoder.TOP1_MARGIN`): its decode equals one whose searches are all exact."""
    import edge.decode.decoder as decoder

    f, w, b, bd, _, _ = _sim(ECC, 0.25)
    calls = []
    search = decoder.search_candidates

    def spy(*a, **k):
        out = search(*a, **k)
        calls.append(out.stats.get("margin_pixels", 0))
        return out

    monkeypatch.setattr(decoder, "search_candidates", spy)
    fast = decode(f, w, b, ECC, bit_depth=bd, levels="refit", validity=validity)
    assert max(calls) > 0  # a first search finished pixels by the margin
    monkeypatch.setattr(decoder, "search_candidates", lambda *a, **k: search(*a, **dict(k, margin=None)))
    exact = decode(f, w, b, ECC, bit_depth=bd, levels="refit", validity=validity)
    for field in ("column", "valid", "confidence", "distances", "error"):
        np.testing.assert_array_equal(getattr(fast, field), getattr(exact, field), err_msg=field)
    moved = fast.candidates != exact.candidates  # the error rule's own final search: its margin, as above
    assert (validity == "error" or not moved.any()) and (fast.candidates[moved] == -1).all()
    assert np.isinf(exact.distances[moved]).all()


def test_spatial_methods_correct_instead_of_discard():
    f, w, b, bd, col, lit = _sim(ECC, 1.0)
    err = {}
    for method in ("soft", "list", "median"):
        d = decode(f, w, b, ECC, bit_depth=bd, method=method)
        err[method] = (((d.column != col) | ~d.valid) & lit).sum() / lit.sum()
    assert 0.02 <= err["soft"] <= 0.3
    assert min(err["list"], err["median"]) * 2 <= err["soft"], err


def test_twelve_bit_data_without_bit_depth_is_not_lost():
    f, w, b, bd, col, lit = _pbs(ECC, 1.0, bits=12)
    with_depth = decode(f, w, b, ECC, bit_depth=12)
    without = decode(f, w, b, ECC)  # 12-bit values in uint16, read as 16-bit: 1/16 of full scale
    assert with_depth.valid.mean() > 0.9
    assert abs(without.valid.mean() - with_depth.valid.mean()) < 0.01
    assert (without.column == with_depth.column).mean() > 0.99


def test_noise_fit_recovers_the_camera():
    f, w, b, bd, col, lit = _sim(ECC, 1.0)
    d = decode(f, w, b, ECC, bit_depth=bd)
    assert d.stats["noise_fitted"] and d.error is not None
    # the simulator's shot-noise coefficient sigma_s**2 = 0.0016 and read-noise variance 4e-6
    # (measured 1.58e-3 and 3.95e-6; before the fit left the unlit pixels out, a sat at its floor)
    assert d.stats["noise_beta"] == pytest.approx(0.04 ** 2, rel=0.15)
    assert 0.002 ** 2 / 3 <= d.stats["noise_a"] <= 3 * 0.002 ** 2
    scale = 1 / 4095
    n = fit_noise(f, w, b, scale, ECC, np.full(w.shape, -1, np.int32), prior=(0.01, 0.03))
    assert not n.fitted and n.beta == pytest.approx(0.03 ** 2)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noise_fit_leaves_out_pixels_the_pattern_does_not_reach(seed):
    """A third of the pixels in shadow (ambient only): their best candidates fit their noise, so
    their residuals understate it, and a fit over all pixels puts the read noise at its floor
    and overstates the shot noise; `lit_noise` (decode's fit) leaves them out and recovers both
    (measured: a 5.9-8.6e-6 for 4e-6, beta -5 %; all pixels: a at the floor, beta +17 %)."""
    from edge.decode import posterior as P
    from edge.decode.synthetic import make_capture

    rng = np.random.default_rng(seed)
    h, w = 120, 160
    cols = np.clip(np.arange(w)[None, :] + rng.integers(0, 4, (h, w)), 0, ECC.size - 1)
    albedo = rng.uniform(0.02, 0.3, (h, w))
    albedo[:, :48] = 0.0
    cap = make_capture(ECC, cols, rng=rng, albedo=albedo, ambient=0.05, sigma_r=0.002, sigma_s=0.04,
                       dtype=np.uint16, bit_depth=12)
    d = decode(cap.frames, cap.white, cap.black, ECC, bit_depth=12)
    a, beta = 0.002 ** 2, 0.04 ** 2
    assert a / 3 <= d.stats["noise_a"] <= 3 * a and d.stats["noise_beta"] == pytest.approx(beta, rel=0.1)
    samples = P._samples(cap.frames, None)
    s2, mu, fb, fc = (np.empty((h, w)) for _ in range(4))
    P._fit_stats(samples, cap.white, cap.black, np.float64(1 / 4095), P._xtab(ECC, False),
                 np.ascontiguousarray(d.candidates[..., 0]), 1, 1, s2, mu, fb, fc)
    every = P._noise_from(s2, mu, samples, 1 / 4095, (0.01, 0.03))
    assert every.a < a / 10 and every.beta > 1.1 * beta  # what the shadows did to the fit


def _sim_qary(code, sigma_s: float, *, seed: int = 0):
    """edge.sim flying scene for a q-ary code: stripe = projector width / codebook rows (rounded
    up), total exposure n (every frame at exposure 1: the 3-frame codes do not saturate),
    ambient 0.5 x projector; truth as codebook rows."""
    scene = make_scene("flying", 160, 120, seed=seed)
    stripe = -(-int(scene.geometry.projector_width) // code.size)
    a = 0.8 * 0.5 / 1.5
    cam = CameraModel(bits=12, sigma_r=0.002, sigma_s=sigma_s, ambient=a, projector=0.8 - a,
                      total_exposure=float(code.n))
    cap = capture_code(scene, code, cam, rng=np.random.default_rng([seed, 7]), stripe=stripe)
    col, lit = truth(scene)
    return cap.frames, cap.white, cap.black, stripe, col // stripe, lit


def _pbs_qary(code, sigma_s: float, *, seed: int = 0):
    col, albedo = pbs_scene(160, 120, seed=seed + 3, columns=min(1024, code.size))
    f, w, b = render(code.codebook, col, albedo, ambient=0.06, projector=0.12, shot=sigma_s, bits=12,
                     seed=seed + 4, q=code.q)
    return f, w, b, 1, col, np.ones(col.shape, bool)


@pytest.mark.parametrize("gen", [_sim_qary, _pbs_qary], ids=["edge.sim", "plane-box-sphere"])
@pytest.mark.parametrize("name, target", [("nary8-3", 0.4), ("nary3-6", 0.02)])
def test_qary_codes_with_defaults(gen, name, target):
    """q-ary codes decode with the defaults: the error rule on the calibration levels (the
    two-level split misfits q levels: nary8-3 was 99-100 % wrong or unpublished, nary3-6 17-19 %;
    measured 16-33 % and 0-0.7 % now on seed 0, tools/eval_nary.py, sigma_s 0.01)."""
    code = get_code(name)
    f, w, b, stripe, row, lit = gen(code, 0.01)
    d = decode(f, w, b, code, bit_depth=12, stripe=stripe)
    assert d.stats["rule"] == "error" and d.stats["level_source"] == "calibration"
    off = np.abs(d.column.astype(np.int64) - row) > 1
    err = ((off | ~d.valid) & lit).sum() / lit.sum()
    far = (off & d.valid & lit).sum() / max((d.valid & lit).sum(), 1)
    print(f"{gen.__name__} {name}: error rate {err:.4f}, published off by > 1 row {far:.4f}")
    assert err <= target
    assert far <= 0.02  # the published pixels meet the 1 % target within 2x


def test_error_rule_takes_inverse_frames_and_auto_keeps_the_confidence_rule_for_them():
    f, w, b, bd, col, lit = _pbs(GRAY, 0.5, bits=8)
    column, albedo = pbs_scene(160, 120, seed=3)
    inv = render(1 - GRAY.codebook, column, albedo, ambient=0.06, projector=0.12, bits=8, seed=9)[0]
    explicit = decode(f, w, b, GRAY, inverse=inv, validity="error")
    plain = decode(f, w, b, GRAY)
    assert explicit.error is not None
    # twice the samples: fewer errors than the same capture without its inverse frames
    err = lambda d: (((d.column != col) | ~d.valid) & lit).mean()  # noqa: E731
    assert err(explicit) < err(plain)
    auto = decode(f, w, b, GRAY, inverse=inv)
    assert auto.error is None and auto.valid.mean() > 0.5


@pytest.mark.parametrize("gen", ["edge.sim", "plane-box-sphere"])
@pytest.mark.parametrize("name", ["gray-10", "ecc-22-10"])
def test_error_probability_is_calibrated(gen, name):
    """Predicted P(wrong) against the observed rate of columns more than one row off, pooled over
    ambient 0.5 / 1 / 2 and two seeds (7 and 8: neither the level prior's design nor
    tools/eval_posterior.py used them), per bin from 0.5 % to 20 % with >= 200 pixels: within
    the issue's factor 2, at 99 % confidence on the bin's error count (tools/eval_posterior.py,
    seeds 0 and 1: gray-10 within 1.2x, ecc-22-10 within 1.5x on both generators from 0.5 %;
    here edge.sim's ecc-22-10 [1 %, 2 %) bin sees 15 errors for 6.7 expected, 2.2x, whose 99 %
    interval 6.7-28 still reaches 2x)."""
    code = get_code(name)
    pred, obs = [], []
    for ratio in (0.5, 1.0, 2.0):
        for seed in (7, 8):
            if gen == "edge.sim":
                f, w, b, bd, col, lit = _sim(code, ratio, seed=seed)
            else:
                f, w, b, bd, col, lit = _pbs(code, ratio, seed=seed)
            d = decode(f, w, b, code, bit_depth=bd)
            pred.append(d.error[lit])
            obs.append((np.abs(d.candidates[..., 0] - col) > 1)[lit])
    p, o = np.concatenate(pred), np.concatenate(obs)
    checked = 0
    for lo, hi in ((0.005, 0.01), (0.01, 0.02), (0.02, 0.05), (0.05, 0.1), (0.1, 0.2)):
        s = (p >= lo) & (p < hi)
        if s.sum() >= 200:
            expected, seen = float(p[s].sum()), int(o[s].sum())
            low, high = poisson_interval(seen)
            print(f"{gen} {name} [{lo}, {hi}): predicted {p[s].mean():.4f} observed {o[s].mean():.4f} ({s.sum()}), "
                  f"errors {seen} (99 %: {low:.1f}-{high:.1f}) against {expected:.1f} expected")
            # within a factor 2 unless the count says otherwise at 99 % (a bin of 400 pixels at 1 %
            # expects 4 errors: its observed ratio alone scatters by more than 2x)
            assert calibration_verdict(expected, seen) != "off", (lo, expected, seen)
            checked += 1
    assert checked >= 3


@pytest.mark.parametrize("with_prior, reference", [(True, 1.0), (False, 1.0), (True, 4.0)])
def test_tail_words_match_the_exact_sum_over_words(with_prior, reference):
    """`posterior._tail_words` (vectorised passes, series logs, prior cells by edge counting, words
    beyond the skip left out) against the plain sum of `_word_cost` over every word: within
    what the skip may leave out (words x exp(-skip / 2)) plus 1e-9 relative.  ``reference`` 4:
    the series' reference variances are 4x off, so that the words go by the exact path."""
    from edge.decode import posterior as P
    from edge.decode.level_prior import contrast_edges, kernel_args

    code = ECC
    tail = P._flips(code)
    columns, weight = tail.columns, tail.weight
    words = columns.shape[1]
    rng = np.random.default_rng(11)
    prior = level_prior(rng.normal(0.1, 0.03, 4000), np.abs(rng.normal(0.25, 0.08, 4000))) if with_prior else None
    ptab, pu0, pdu, pw0, pdw, pout, use, _ = kernel_args(prior)
    edges = contrast_edges(prior)
    a, beta = 1e-4, 2e-3
    skip = P._skip_cost(words * weight)
    work = np.empty((8, words))
    exact_path = 0
    stopped = 0
    for trial in range(40):
        best = rng.integers(0, code.size)
        x = np.r_[code.codebook[best], 1, 0].astype(np.float64)
        sigma = (0.01, 0.05, 0.12)[trial % 3]
        r = np.abs(0.1 + 0.25 * x + rng.normal(0, sigma, x.size))
        m = x.size
        n1, s1, q1, tot, sq = x.sum(), (x * r).sum(), (x * r * r).sum(), r.sum(), (r * r).sum()
        sign = np.where(x[:code.n] != 0, -1.0, 1.0)
        dn, ds, dq = sign, sign * r[:code.n], sign * r[:code.n] ** 2
        c1 = max((m * s1 - n1 * tot) / (m * n1 - n1 * n1), 0.0)
        b1 = (tot - c1 * n1) / m
        vr0, vr1 = (a + beta * max(b1, 0.0)) * reference, (a + beta * max(b1 + c1, 0.0)) * reference
        lbest = P._word_cost(m, n1, tot, s1, sq, q1, a, beta, ptab, pu0, pdu, pw0, pdw, pout, use)
        got = P._tail_words(m, columns, dn, ds, dq, n1, s1, q1, tot, sq, a, beta, vr0, vr1, np.log(vr0), np.log(vr1),
                            ptab, pu0, pdu, pw0, pdw, pout, use, edges, lbest, skip, np.inf, work)
        exact_path += int(work[6].sum())
        terms = np.zeros(words)
        for j in range(words):
            bits = columns[:, j]
            d = P._word_cost(m, n1 + bits @ dn, tot, s1 + bits @ ds, sq, q1 + bits @ dq, a, beta, ptab, pu0, pdu,
                             pw0, pdw, pout, use) - lbest
            terms[j] = np.exp(-0.5 * max(d, -700.0))
        want = terms.sum()
        assert abs(got - want) <= words * np.exp(-skip / 2) + 1e-9 * want, (trial, got, want)
        if got > 0:  # stopped after the first block whose running sum reaches `enough`: that sum
            part = P._tail_words(m, columns, dn, ds, dq, n1, s1, q1, tot, sq, a, beta, vr0, vr1, np.log(vr0),
                                 np.log(vr1), ptab, pu0, pdu, pw0, pdw, pout, use, edges, lbest, skip, got / 3, work)
            running = np.cumsum(np.add.reduceat(terms, np.arange(0, words, P.TAIL_BLOCK)))
            k = int(np.argmax(running >= got / 3 * (1 - 1e-9)))
            assert abs(part - running[k]) <= words * np.exp(-skip / 2) + 1e-9 * want, (trial, part, running[k])
            assert got / 3 <= part <= got
            stopped += k < running.size - 1
    if reference > 1.0:
        assert exact_path > 0.5 * 40 * words  # the exact path was taken, and agrees
    if with_prior:
        assert stopped > 0  # some sums stopped before the last block


def test_stable_order_is_numpys_stable_argsort():
    """`posterior.stable_order` (the noise fit's sort) gives np.argsort(kind="stable")'s indices:
    distinct values, a few runs of ties (-0.0 and 0.0 among them), many runs, NaN; signed values
    over the whole float64 range with infinities and NaNs of both signs; float32 input; empty."""
    from edge.decode.posterior import stable_order

    rng = np.random.default_rng(3)
    for trial in range(250):
        n = int(rng.integers(1, 3000))
        kind = trial % 5
        x = rng.random(n)
        if kind == 1:
            x = rng.integers(0, 200, n).astype(np.float64)
        elif kind == 2:
            x[rng.integers(0, n, 10)] = 0.5
            x[:3] = -0.0
            x[3:5] = 0.0
        elif kind == 3:
            x[rng.integers(0, n, 5)] = np.nan
            x[rng.integers(0, n, 5)] = 0.25
        elif kind == 4:
            x = rng.standard_normal(n) * 10.0 ** rng.integers(-300, 300, n)
            x[rng.integers(0, n, 3)] = -np.inf
            x[rng.integers(0, n, 3)] = np.inf
            x[rng.integers(0, n, 3)] = -np.nan
            x[rng.integers(0, n, 3)] = -0.0
        assert np.array_equal(stable_order(x), np.argsort(x, kind="stable")), trial
    y = rng.random(500).astype(np.float32)
    assert np.array_equal(stable_order(y), np.argsort(y, kind="stable"))
    assert stable_order(np.zeros(0)).shape == (0,)


def test_bin_medians_are_numpys():
    """`posterior._bin_medians` (the noise fit's binned medians) gives, bin for bin, what
    ``np.array_split`` into NOISE_BINS slices and ``np.median`` of each give: sizes below, at and
    above the bin count, bins under the least size left out, odd and even bin sizes, ties."""
    from edge.decode.posterior import NOISE_BINS, _bin_medians

    rng = np.random.default_rng(5)
    for trial, n in enumerate([0, 5, 16, 17, 319, 320, 321, 333, 1000, 40000]):
        mu = np.sort(rng.random(n))
        s2 = rng.gamma(2.0, 1e-4, n)
        if trial % 2:
            mu = np.round(mu, 2)  # ties of the level
            s2[: n // 3] = 1e-4  # ties of the variance
        xs, ys, ws = [], [], []
        for chunk in np.array_split(np.arange(n), NOISE_BINS):
            if chunk.size >= 20:
                lo, hi = int(chunk[0]), int(chunk[-1]) + 1
                xs.append(float(np.median(mu[lo:hi])))
                ys.append(float(np.median(s2[lo:hi])))
                ws.append(float(hi - lo))
        got = _bin_medians(mu, s2, NOISE_BINS, 20)
        for g, want in zip(got, (xs, ys, ws)):
            assert g.dtype == np.float64 and np.array_equal(g, np.array(want, np.float64)), (n, g, want)
