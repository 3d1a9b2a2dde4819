"""The goodness-of-fit test of the error rule (edge.decode.misfit): its statistic against a plain
numpy reference, its rate on right pixels, and the surfaces outside a disparity band it keeps
from being published."""

from __future__ import annotations

import numpy as np
import pytest

from _plane_box_sphere import render, scene as pbs_scene
from edge.codes import get_code
from edge.decode import decode
from edge.decode.misfit import MISFIT_LEVEL, misfit_statistic, misfit_threshold


def _reference(frames, white, black, scale, code, best, a, beta, inverse=None):
    """sum (r - mu)**2 / v(mu) of each pixel's best row, least-squares levels with c >= 0 (numpy)."""
    r = np.concatenate([frames] + ([inverse] if inverse is not None else []) + [white[None], black[None]]) * scale
    r = r.astype(np.float64).reshape(r.shape[0], -1).T
    tab = code.codebook.astype(np.float64) / (code.q - 1)
    if inverse is not None:
        tab = np.concatenate([tab, 1 - tab], 1)
    x = np.concatenate([tab, np.ones((code.size, 1)), np.zeros((code.size, 1))], 1)[best.ravel()]
    out = np.empty(len(r))
    for i in range(len(r)):
        c, b = np.polyfit(x[i], r[i], 1) if np.ptp(x[i]) > 0 else (0.0, r[i].mean())
        if c < 0:
            c, b = 0.0, r[i].mean()
        mu = b + c * x[i]
        out[i] = (((r[i] - mu) ** 2) / (a + beta * np.maximum(mu, 0))).sum()
    return out.reshape(best.shape)


@pytest.mark.parametrize("inverse", [False, True])
def test_statistic_matches_the_numpy_reference(inverse):
    code = get_code("ecc-22-10")
    col, albedo = pbs_scene(24, 16, seed=5)
    f, w, b = render(code.codebook, col, albedo, ambient=0.1, projector=0.12, seed=6, bits=12)
    inv = render(1 - code.codebook, col, albedo, ambient=0.1, projector=0.12, seed=7, bits=12)[0] if inverse else None
    rng = np.random.default_rng(0)
    best = np.where(rng.random(col.shape) < 0.7, col, rng.integers(0, code.size, col.shape)).astype(np.int32)
    got = misfit_statistic(f, w, b, 1 / 4095, code, best, (4e-6, 1.6e-3), inverse=inv)
    want = _reference(f, w, b, 1 / 4095, code, best, 4e-6, 1.6e-3, inverse=inv)
    np.testing.assert_allclose(got, want, rtol=2e-7)  # float32 values of float64 sums
    best[0, 0] = -1
    f[3, 0, 1] = 4095  # a sample at full scale: not tested
    got = misfit_statistic(f, w, b, 1 / 4095, code, best, (4e-6, 1.6e-3), inverse=inv)
    assert np.isnan(got[0, 0]) and np.isnan(got[0, 1]) and np.isfinite(got[1:]).all()


@pytest.mark.parametrize("name, inverse, dtype", [("ecc-22-10", False, np.uint16), ("gray-10", True, np.uint8),
                                                  ("ecc-31-10", True, np.float32), ("ecc-63-10", False, np.float64)])
def test_the_binary_kernel_is_the_general_one_bit_for_bit(name, inverse, dtype):
    """`misfit_statistic` reads a binary code's symbols as packed bits (`_misfit_stat_binary`); the
    general kernel (`_misfit_stat`, the one q-ary codes and binary codes of more than 64 samples
    use) gives the same values bit for bit: random samples, rows (-1 included), full-scale samples."""
    from edge.decode import misfit as M
    from edge.decode.posterior import _samples, _xtab, packed_symbols

    code = get_code(name)
    rng = np.random.default_rng(3)
    h, w = 7, 45
    top = 1.0 if np.issubdtype(dtype, np.floating) else np.iinfo(dtype).max
    scale = 1.0 if top == 1.0 else 1.0 / top
    draw = lambda *shape: (rng.random(shape) * top).astype(dtype)  # noqa: E731
    f, wh, bl = draw(code.n, h, w), draw(h, w), draw(h, w)
    inv = draw(code.n, h, w) if inverse else None
    f[2, 3, 4] = dtype(top)  # a sample at full scale
    best = rng.integers(-1, code.size, (h, w)).astype(np.int32)
    xtab = _xtab(code, inverse)
    packed = packed_symbols(xtab)
    unpacked = (packed[:, None] >> np.arange(xtab.shape[1], dtype=np.uint64)) & np.uint64(1)
    assert packed.size == code.size and (unpacked == xtab).all()
    assert np.array_equal(M._packed(code, inverse), packed)  # the table misfit_statistic reads
    got = misfit_statistic(f, wh, bl, scale, code, best, (4e-6, 1.6e-3), inverse=inv)
    want = np.empty((h, w), np.float32)
    M._misfit_stat(_samples(f, inv), wh, bl, np.float64(scale), xtab, best, 4e-6, 1.6e-3, want)
    assert np.array_equal(got, want, equal_nan=True) and np.isnan(got[3, 4]) and np.isnan(got[best < 0]).all()
    assert packed_symbols(_xtab(get_code("ecc-63-10"), True)).size == 0  # 126 samples: the general kernel
    assert packed_symbols(_xtab(get_code("nary3-6"), False)).size == 0  # q-ary symbols
    assert M._packed(get_code("ecc-63-10"), True).size == 0 and M._packed(get_code("nary3-6"), False).size == 0


def test_threshold_is_the_scaled_chi2_tail():
    """On chi2 draws of the right degrees of freedom the threshold is their 1 - MISFIT_LEVEL
    quantile (scale 1), and it scales with the draws (up to MAX_SCALE)."""
    rng = np.random.default_rng(1)
    k = 22
    draws = rng.chisquare(k, 2_000_000)
    t = misfit_threshold(draws, k + 2)
    assert (draws > t).sum() <= 10  # 2 expected (2e6 draws at 1e-6)
    assert abs(misfit_threshold(2.0 * draws, k + 2) / t - 2.0) < 0.01
    assert MISFIT_LEVEL == 1e-6 and misfit_threshold(np.array([np.nan]), k + 2) == np.inf


@pytest.mark.parametrize("shape", [(300, 400), (7, 9), (0, 5)])
def test_check_fit_takes_misfit_thresholds_sample(shape):
    """`check_fit`'s one-kernel sample of the published pixels (`_published_sample`) is
    `misfit_threshold`'s over ``stat[published]`` exactly: the same threshold and P(wrong) as the
    numpy form, with NaN statistics, unpublished pixels and more than SCALE_PIXELS published."""
    from types import SimpleNamespace

    from edge.decode import misfit as M

    stack = SimpleNamespace(frames=np.zeros((20, 1, 1)), inverse=None)  # m = 22 samples per pixel
    rng = np.random.default_rng(3)
    stat = rng.chisquare(20, shape).astype(np.float32)
    stat[rng.random(shape) < 0.05] = np.nan
    column0 = np.where(rng.random(shape) < 0.1, -1, rng.integers(0, 1024, shape)).astype(np.int32)
    error = (rng.random(shape) ** 4).astype(np.float32)
    target = 0.01 if shape[0] < 100 else 0.5
    published = (column0 >= 0) & (error < np.float32(target))
    if shape == (300, 400):
        assert np.isfinite(stat[published]).sum() > M.SCALE_PIXELS  # the subsample is taken
    seen, threshold = M.check_fit(stack, None, (1e-4, 1e-3), column0, error, target, stat)
    want = misfit_threshold(stat[published], 22)
    assert threshold == want or (np.isinf(threshold) and np.isinf(want))
    with np.errstate(invalid="ignore"):
        assert np.array_equal(seen, np.where(stat > want, np.float32(1.0), error))
    assert seen.dtype == np.float32


@pytest.mark.parametrize("gen", ["edge.sim", "plane-box-sphere"])
@pytest.mark.parametrize("name", ["gray-10", "ecc-22-10"])
def test_surfaces_outside_the_band_are_not_published(gen, name):
    """A disparity band that misses the nearest 30 % of the lit pixels: with the defaults their
    columns were published wrong at P(wrong) about 0 (ecc-22-10 14 %, gray-10 20 % of what was
    published); now ecc-22-10 publishes at most 1 % wrong and at most 3 % of the pixels outside,
    gray-10 1.5 % and 4.5 %.  Without a band what is published stays right."""
    code = get_code(name)
    if gen == "edge.sim":
        from edge.sim import CameraModel, capture_code, make_scene
        from edge.sim.metrics import truth

        scene = make_scene("flying", 160, 120, seed=9)
        cam = CameraModel(bits=12, sigma_r=0.004, sigma_s=0.015, ambient=0.4, projector=0.4)
        cap = capture_code(scene, code, cam, rng=np.random.default_rng([9, 7]))
        f, w, b = cap.frames, cap.white, cap.black
        col, lit = truth(scene)
    else:
        col, albedo = pbs_scene(160, 120, seed=11)
        f, w, b = render(code.codebook, col, albedo, ambient=0.06, projector=0.12, seed=12, bits=12)
        lit = np.ones(col.shape, bool)
    disp = np.arange(col.shape[1])[None, :] - col
    cut = int(np.quantile(disp[lit], 0.7))
    outside = lit & (disp > cut + 1)
    banded = decode(f, w, b, code, bit_depth=12, min_disparity=int(disp[lit].min()) - 2, max_disparity=cut)
    wrong = banded.valid & (~lit | (np.abs(banded.column - col) > 1))
    assert outside.sum() > 0.2 * lit.sum()
    # gray-10 (d_min 1) keeps 1.4-2.2 % of them and publishes 0.5-1.1 % wrong: just beyond the band
    # a column one or two bits from the band's last one misfits by less than a dim pixel's noise
    loose = 1.5 if name == "gray-10" else 1.0
    assert wrong.sum() <= 0.01 * loose * banded.valid.sum(), (wrong.sum(), banded.valid.sum())
    assert (banded.valid & outside).sum() <= 0.01 * 3 * loose * outside.sum()
    free = decode(f, w, b, code, bit_depth=12)
    assert free.valid.sum() > 0.5 * lit.sum()
    right = free.valid & lit & (np.abs(free.column - col) <= 1)
    assert right.sum() >= 0.999 * free.valid.sum() - 5


@pytest.mark.parametrize("name, inverse, bits", [("ecc-22-10", False, 10), ("ecc-22-10", True, 16), ("gray-10", False, 14),
                                                 ("nary3-6", False, 10)])
def test_the_posterior_returns_the_statistic_bit_for_bit(name, inverse, bits):
    """`Posterior.misfit` (the best candidate's Mahalanobis part, which the decode's test uses) is
    `misfit_statistic` of the posterior's best rows, bit for bit, with pixels at full scale left
    untested at every bit depth (the float32 scale puts full scale below 1.0 at 10, 14 and 16 bits)."""
    from edge.decode.inputs import validate
    from edge.decode.misfit import statistic_of
    from edge.decode.posterior import fit_noise, posterior

    code = get_code(name)
    col, albedo = pbs_scene(40, 24, seed=5)
    col = np.minimum(col, code.size - 1)
    kw = dict(ambient=0.1, projector=1.5, seed=6, bits=bits, q=code.q)  # the brightest pixels clip
    f, w, b = render(code.codebook, col, albedo * 1.6, **kw)
    inv = render((code.q - 1) - code.codebook, col, albedo * 1.6, **dict(kw, seed=7))[0] if inverse else None
    stack = validate(f, w, b, code, inverse=inv, bit_depth=bits)
    scale = float(np.float32(stack.scale))
    best = decode(f, w, b, code, inverse=inv, bit_depth=bits).candidates
    noise = fit_noise(stack.frames, stack.white, stack.black, scale, code, best[..., 0], prior=(0.01, 0.03),
                      inverse=inv)
    post = posterior(stack.frames, stack.white, stack.black, scale, code, best, noise, choices=code.size, inverse=inv)
    want = statistic_of(stack, code, (noise.a, noise.beta), post.candidates[..., 0])
    assert post.misfit.dtype == np.float32 and np.array_equal(post.misfit, want, equal_nan=True)
    top = 2**bits - 1
    full = (f == top).any(0) | (w == top) | (b == top) | ((inv == top).any(0) if inverse else False)
    assert full.any() and np.isnan(want[full]).all() and np.isfinite(want[~full & (post.candidates[..., 0] >= 0)]).all()
