"""The capture's level prior (`edge.decode.level_prior`): the kernel lookup against the numpy one,
the density it estimates against a known one, its floor, and its absence on small samples."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from edge.decode.level_prior import C_FLOOR, MIN_PIXELS, coordinates, cost_at, level_prior, prior_cost


@njit(cache=True)
def _lookup_all(table, u0, du, w0, dw, outside, b, c, out):
    for i in range(b.size):
        out[i] = cost_at(table, u0, du, w0, dw, outside, b[i], c[i])


def _levels_from(u, w):
    """(b, c) with the given coordinates u = log10 c, w = b / (b + c)."""
    c = 10.0 ** u
    return w * c / (1.0 - w), c


def test_kernel_lookup_matches_numpy_inside_and_outside_the_grid():
    rng = np.random.default_rng(0)
    b, c = _levels_from(rng.normal(-1.0, 0.3, 5000), rng.uniform(0.1, 0.6, 5000))
    prior = level_prior(b, c)
    # probe levels on, near and far off the sample, negative offsets and zero contrast included
    pb = np.r_[rng.uniform(-0.05, 0.5, 3000), 0.0, -0.01, 2.0]
    pc = np.r_[10.0 ** rng.uniform(-4.0, 0.5, 3000), 0.0, 0.1, 1e-9]
    out = np.empty(pb.size)
    _lookup_all(prior.cost, prior.u0, prior.du, prior.w0, prior.dw, prior.outside, pb, pc, out)
    want = prior_cost(prior, pb, pc)
    np.testing.assert_array_equal(out, want)
    assert (out == prior.outside).sum() > 100 and (out < prior.outside).sum() > 500


def test_density_recovers_a_known_one_and_integrates_to_one():
    """Levels drawn with u, w independent Gaussians: over the cells within two standard
    deviations, the table is the analytic -2 log density of the sample's law widened by the
    kernel (variance s**2 + h**2, h Scott's bandwidth), up to a constant and the sample's noise."""
    rng = np.random.default_rng(1)
    su, sw, count = 0.25, 0.05, 20000
    b, c = _levels_from(rng.normal(-1.2, su, count), rng.normal(0.4, sw, count))
    prior = level_prior(b, c)
    iu, iw = np.meshgrid(np.arange(prior.cost.shape[0]), np.arange(prior.cost.shape[1]), indexing="ij")
    u = prior.u0 + (iu + 0.5) * prior.du
    w = prior.w0 + (iw + 0.5) * prior.dw
    factor = count ** (-1.0 / 3.0)  # h**2 / s**2
    want = (u + 1.2) ** 2 / (su ** 2 * (1 + factor)) + (w - 0.4) ** 2 / (sw ** 2 * (1 + factor))
    inner = (np.abs(u + 1.2) < 2 * su) & (np.abs(w - 0.4) < 2 * sw)
    # least squares: cost = k_u (u + 1.2)**2 + k_w (w - 0.4)**2 + const; analytic k = 1 / (s**2 (1 + N**(-1/3)))
    basis = np.stack([(u[inner] + 1.2) ** 2, (w[inner] - 0.4) ** 2, np.ones(inner.sum())], 1)
    k_u, k_w, const = np.linalg.lstsq(basis, prior.cost[inner], rcond=None)[0]
    assert inner.sum() > 500
    assert k_u * su ** 2 * (1 + factor) == pytest.approx(1.0, rel=0.1)
    assert k_w * sw ** 2 * (1 + factor) == pytest.approx(1.0, rel=0.1)
    resid = prior.cost[inner] - want[inner] - const
    assert np.sqrt(np.mean(resid ** 2)) < 0.2          # the estimate's own sampling noise
    # the density (per unit u, w) integrates to one, the mass the kernel pushes off the grid aside
    density = np.exp(-0.5 * prior.cost)
    assert density.sum() * prior.du * prior.dw == pytest.approx(1.0, abs=0.01)
    # one pseudo-pixel over the grid: off the sample the density is tiny but finite, the floor's
    assert np.isfinite(prior.cost).all() and prior.cost.max() <= prior.outside + 1e-9
    assert prior.outside - prior.cost.min() > 2.0 * np.log(1000.0)


def test_no_prior_below_the_minimum_sample_and_nans_skipped():
    rng = np.random.default_rng(2)
    b = rng.uniform(0.0, 0.1, MIN_PIXELS - 1)
    c = rng.uniform(0.1, 0.5, MIN_PIXELS - 1)
    assert level_prior(b, c) is None
    assert (prior_cost(None, b, c) == 0.0).all()
    with_nans = level_prior(np.r_[b, np.nan, 0.05], np.r_[c, 0.2, np.nan])
    assert with_nans is None                      # the NaN pixels do not count
    assert level_prior(np.r_[b, 0.05], np.r_[c, 0.2]).pixels == MIN_PIXELS


def test_coordinates_clamp_negative_offsets_and_zero_contrast():
    u, w = coordinates(np.array([-0.1, 0.2]), np.array([0.0, 0.2]))
    assert u[0] == np.log10(C_FLOOR) and w[0] == 0.0
    assert u[1] == pytest.approx(np.log10(0.2)) and w[1] == pytest.approx(0.5)


def test_contrast_edges_give_the_u_cells_of_the_lookup():
    """The tail's u-cell (the count of `contrast_edges` at or below c, less one) is the lookup's
    ``floor((log10 c - u0) / du)`` wherever c is not within rounding of an edge; below / above
    the grid it is off the grid on both."""
    from edge.decode.level_prior import contrast_edges

    rng = np.random.default_rng(3)
    prior = level_prior(*_levels_from(rng.normal(-1.0, 0.3, 5000), rng.uniform(0.1, 0.6, 5000)))
    edges = contrast_edges(prior)
    assert edges.shape == (prior.cost.shape[0] + 1,) and np.all(np.diff(edges) > 0)
    c = 10.0 ** rng.uniform(prior.u0 - 0.5, prior.u0 + prior.du * prior.cost.shape[0] + 0.5, 20000)
    away = np.abs((np.log10(c) - prior.u0) / prior.du - np.round((np.log10(c) - prior.u0) / prior.du)) > 1e-9
    counted = np.searchsorted(edges, c, side="right") - 1
    floor = np.floor((np.log10(c) - prior.u0) / prior.du)
    rows = prior.cost.shape[0]
    off = (floor < 0) | (floor >= rows)
    assert np.array_equal(counted[away & ~off], floor[away & ~off].astype(int))
    assert np.all((counted[off] < 0) | (counted[off] >= rows))
    assert off.any() and (~off).sum() > 10000
    assert contrast_edges(None).tolist() == [np.inf]
