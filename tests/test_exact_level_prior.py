"""Exactness of the level prior (`edge.decode.level_prior`) against a brute-force reference written
here from the module docstring (plain numpy / python, none of the module's helpers):

* the table `level_prior` builds: levels mapped to ``u = log10(max(c, C_FLOOR))``, ``w = b' / (b' +
  c')`` (``b' = max(b, 0)``, ``c' = max(c, C_FLOOR)``), the grid spanning the sample's range widened
  by `REACH` bandwidths ``h = s N**(-1/6)``, ``s = min(sd, IQR / 1.349)`` (sd the population
  standard deviation), the histogram of the sample on that grid convolved with the Gaussian of the
  bandwidth and normalised to one, one pseudo-pixel spread over the cells, the cost ``-2 log`` of
  the density per unit (u, w), and the cost off the grid (the pseudo-pixel's density alone);
* the kernel lookup `cost_at`, fed by `kernel_args`: a level's cell is the one whose half-open
  interval ``[u0 + i du, u0 + (i + 1) du) x [w0 + j dw, w0 + (j + 1) dw)`` holds (u, w) (edges
  computed as written there), the `outside` cost off the grid.  On random levels of a real
  prior, cell edges, levels far off the grid, negative offsets, zero / negative contrast and
  contrasts at and under C_FLOOR, it agrees exactly except where (u, w) is within rounding of an
  edge (then it is one of the two cells at that edge).  On priors whose edges are dyadic (every
  coordinate exactly representable: powers of ten for u, ratios j / 64 for w) it agrees exactly
  on the edges too, C_FLOOR exactly on a u-edge included;
* `kernel_args`: the table, its geometry, the use flag and the table's least cost (the flat prior:
  not used);
* `contrast_edges`: the u-cell of a contrast counted from the edges (the count of edges at or
  below ``max(c, C_FLOOR)``, less one) is the reference cell of u, exactly on the dyadic priors
  and up to rounding at the edges on the real one; and it is `cost_at`'s own cell everywhere,
  on the edges and one double either side of each;
* `costs_at` (the lane lookup that counts edges instead of taking a log): `cost_at` bit for bit
  on every probe above, lane by lane;
* levels whose w is not a number (an infinite off level) are off the grid: the `outside` cost.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from edge.decode.level_prior import C_FLOOR, GRID, REACH, LevelPrior, contrast_edges, cost_at, kernel_args, level_prior


def _uw(b, c):
    bp = b if b > 0.0 else 0.0
    cp = c if c > C_FLOOR else C_FLOOR
    return math.log10(cp), bp / (bp + cp)


def _reference_table(b, c):
    """(cost (GRID, GRID), u0, du, w0, dw, outside, N) of the docstring's estimate."""
    ok = np.isfinite(b) & np.isfinite(c)
    uw = np.array([_uw(float(x), float(y)) for x, y in zip(b[ok], c[ok])])
    n = len(uw)

    def bandwidth(v):
        q25, q75 = np.quantile(v, [0.25, 0.75])
        return min(float(np.sqrt(np.mean((v - v.mean()) ** 2))), float(q75 - q25) / 1.349) * n ** (-1.0 / 6.0)

    geometry = []
    for v in uw.T:
        h = bandwidth(v)
        lo, hi = float(v.min()) - REACH * h, float(v.max()) + REACH * h
        geometry.append((lo, (hi - lo) / GRID, h))
    (u0, du, hu), (w0, dw, hw) = geometry
    hist = np.zeros((GRID, GRID))
    for u, w in uw:
        hist[min(int(math.floor((u - u0) / du)), GRID - 1), min(int(math.floor((w - w0) / dw)), GRID - 1)] += 1
    i = np.arange(GRID)
    gu = np.exp(-0.5 * (((i[:, None] - i[None, :]) * du) / hu) ** 2)
    gw = np.exp(-0.5 * (((i[:, None] - i[None, :]) * dw) / hw) ** 2)
    kde = np.einsum("ik,kl,jl->ij", gu, hist, gw)
    kde /= kde.sum()
    cells = GRID * GRID
    area = du * dw
    cost = -2.0 * np.log((n * kde + 1.0 / cells) / (n + 1.0) / area)
    outside = -2.0 * math.log(1.0 / cells / (n + 1.0) / area)
    return cost, u0, du, w0, dw, outside, n


def _cell(v, v0, dv, cells):
    """The i with v in [v0 + i dv, v0 + (i + 1) dv), the edges as written; None off the grid."""
    if not v0 + 0 * dv <= v < v0 + cells * dv:
        return None
    for i in range(cells):
        if v0 + i * dv <= v < v0 + (i + 1) * dv:
            return i
    return None  # (v within rounding of an edge whose two neighbours' bounds disagree: not hit here)


def _reference_cost(table, u0, du, w0, dw, outside, b, c):
    """(cost, (cell u, cell w) or None) of levels (b, c)."""
    u, w = _uw(b, c)
    iu, iw = _cell(u, u0, du, table.shape[0]), _cell(w, w0, dw, table.shape[1])
    if iu is None or iw is None:
        return outside, None
    return table[iu, iw], (iu, iw)


def _near_edge(v, v0, dv):
    t = (v - v0) / dv
    return abs(t - round(t)) < 1e-9


def _sample(seed, count=3000):
    rng = np.random.default_rng(seed)
    c = 10.0 ** rng.normal(-1.0, 0.3, count)
    w = rng.uniform(0.1, 0.6, count)
    b = w * c / (1.0 - w)
    b[:40] = -rng.uniform(0, 0.01, 40)              # negative offsets: w = 0
    c[40:60] = 0.0                                   # zero contrast: u = log10(C_FLOOR)
    b[60:70] = np.nan                                # skipped
    return b, c


def _probes(prior, rng):
    """Levels on, near and far off the grid; on the u- and w-edges; at and under the floor."""
    rows = prior.cost.shape[0]
    u_end, w_end = prior.u0 + rows * prior.du, prior.w0 + prior.cost.shape[1] * prior.dw
    n = 4000
    c = 10.0 ** rng.uniform(prior.u0 - 0.5, u_end + 0.5, n)
    w = rng.uniform(max(prior.w0 - 0.1, 0.0), min(w_end + 0.1, 0.999), n)
    b = w * c / (1.0 - w)
    ue = prior.u0 + prior.du * np.arange(rows + 1)                 # u exactly (as computed) on the edges
    ce = 10.0 ** ue
    we = np.clip(prior.w0 + prior.dw * np.arange(prior.cost.shape[1] + 1), 0.0, 0.999)
    cw = np.full(we.size, 10.0 ** (prior.u0 + 0.5 * rows * prior.du))
    b = np.r_[b, 0.3 * ce, we * cw / (1.0 - we), 0.0, -0.2, 0.05, 0.05, 0.05, 0.05, 1e30, 0.0, 5.0]
    c = np.r_[c, ce, cw, 0.0, 0.1, 0.0, -0.3, C_FLOOR, 1e-9, 0.01, np.inf, 1e-300]
    return b, c


def test_table_is_the_docstring_estimate():
    b, c = _sample(0)
    prior = level_prior(b, c)
    cost, u0, du, w0, dw, outside, n = _reference_table(b, c)
    assert prior.pixels == n == 2990
    assert prior.cost.shape == (GRID, GRID)
    np.testing.assert_allclose([prior.u0, prior.du, prior.w0, prior.dw], [u0, du, w0, dw], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(prior.cost, cost, rtol=1e-9, atol=1e-9)
    assert prior.outside == pytest.approx(outside, rel=1e-12)


def test_lookup_is_the_reference_cell_on_a_real_prior():
    rng = np.random.default_rng(1)
    prior = level_prior(*_sample(1))
    args = kernel_args(prior)
    assert args[0] is prior.cost and args[6] is True
    assert args[1:6] == (prior.u0, prior.du, prior.w0, prior.dw, prior.outside)
    assert args[7] == prior.cost.min()
    b, c = _probes(prior, rng)
    exact = inside = near = 0
    for x, y in zip(b.tolist(), c.tolist()):
        got = cost_at(*args[:6], x, y)
        want, cell = _reference_cost(*args[:6], x, y)
        u, w = _uw(x, y)
        if got == want:
            exact += 1
            inside += cell is not None
            continue
        # only within rounding of an edge, and then a cell at that edge (or off the grid past it)
        assert _near_edge(u, prior.u0, prior.du) or _near_edge(w, prior.w0, prior.dw), (x, y, got, want)
        iu, iw = math.floor((u - prior.u0) / prior.du), math.floor((w - prior.w0) / prior.dw)
        options = {prior.cost[i, j] if 0 <= i < GRID and 0 <= j < GRID else prior.outside
                   for i in (iu - 1, iu, iu + 1) for j in (iw - 1, iw, iw + 1)}
        assert got in options
        near += 1
    assert exact > 4000 and inside > 1500 and near < 100


@pytest.mark.parametrize("u0, du, w0, dw", [(-8.0, 0.125, 0.0, 1.0 / 64.0), (-3.0, 1.0 / 32.0, 0.125, 1.0 / 128.0)])
def test_lookup_is_exact_on_dyadic_edges(u0, du, w0, dw):
    rng = np.random.default_rng(2)
    table = rng.uniform(0.0, 20.0, (GRID, GRID))
    prior = LevelPrior(table, u0, du, w0, dw, 50.0, 1000)
    args = kernel_args(prior)
    probes = []
    for k in range(-9, 2):                              # c = 10**k: u = k exactly, on a u-edge where on the grid
        for j in range(65):                             # w = j / 64 exactly
            c = 2.0 ** -10 * (64 - j) if j < 64 else 0.0
            cc = 10.0 ** k
            probes += [(cc, cc), (cc / 3.0, cc), (0.0, cc), (-1.0, cc), (2.0 ** -10 * j, c)]
    probes += [(0.5, C_FLOOR), (0.5, 0.0), (0.5, -1.0), (0.0, 0.0), (C_FLOOR, C_FLOOR), (1e30, 1e-3), (0.1, np.inf)]
    probes += [(float(x), float(y)) for x, y in zip(rng.uniform(-0.1, 1.0, 2000), 10.0 ** rng.uniform(-9, 1, 2000))]
    on_edges = cells = 0
    for x, y in probes:
        want, cell = _reference_cost(*args[:6], x, y)
        assert cost_at(*args[:6], x, y) == want, (x, y)
        u, w = _uw(x, y)
        on_edges += cell is not None and (_near_edge(u, u0, du) or _near_edge(w, w0, dw))
        cells += cell is not None
        # the tail's u-cell: edges at or below max(c, C_FLOOR), less one
        iu = _cell(u, u0, du, GRID)
        counted = int(np.count_nonzero(contrast_edges(prior) <= max(y, C_FLOOR))) - 1
        assert (counted == iu) if iu is not None else (counted < 0 or counted >= GRID), (x, y)
    assert on_edges > 200 and cells > 300
    # C_FLOOR lies exactly on a u-edge of the first grid: zero contrast goes to the cell above it
    if u0 == -8.0:
        assert _reference_cost(*args[:6], 0.0, 0.0)[1] == (16, 0) and cost_at(*args[:6], 0.0, 0.0) == table[16, 0]


def test_contrast_edges_count_to_the_reference_cell_on_a_real_prior():
    prior = level_prior(*_sample(3))
    edges = contrast_edges(prior)
    assert edges.shape == (GRID + 1,)
    rng = np.random.default_rng(3)
    c = np.r_[10.0 ** rng.uniform(prior.u0 - 0.3, prior.u0 + GRID * prior.du + 0.3, 3000), 0.0, 1e-9, C_FLOOR]
    for y in c.tolist():
        u = math.log10(max(y, C_FLOOR))
        iu = _cell(u, prior.u0, prior.du, GRID)
        counted = sum(1 for e in edges.tolist() if e <= max(y, C_FLOOR)) - 1
        if _near_edge(u, prior.u0, prior.du):
            continue
        assert (counted == iu) if iu is not None else (counted < 0 or counted >= GRID), y
    assert contrast_edges(None).tolist() == [math.inf]
    flat = kernel_args(None)
    assert flat[6] is False


def test_levels_without_a_w_are_off_the_grid():
    """An infinite off level has w = inf / inf (not a number): no cell holds it."""
    rng = np.random.default_rng(4)
    prior = LevelPrior(rng.uniform(0.0, 20.0, (GRID, GRID)), -8.0, 0.125, 0.0, 1.0 / 64.0, 50.0, 1000)
    args = kernel_args(prior)
    for k in range(-8, 0):
        assert _reference_cost(*args[:6], math.inf, 10.0 ** k) == (prior.outside, None)
        assert cost_at(*args[:6], math.inf, 10.0 ** k) == prior.outside, k


def _edge_probes(prior, rng):
    """Levels whose contrast is every edge of `contrast_edges` and the doubles either side of it,
    with offsets across the w-range, plus `_probes`."""
    edges = contrast_edges(prior)
    ce = edges[np.isfinite(edges)]
    c = np.concatenate([ce, np.nextafter(ce, 0.0), np.nextafter(ce, np.inf)])
    w = rng.uniform(0.0, 0.95, c.size)
    b, c2 = _probes(prior, rng)
    return np.r_[w * c / (1.0 - w), b], np.r_[c, c2]


@pytest.mark.parametrize("seed", [1, 5])
def test_edges_count_to_cost_at_cell_exactly(seed):
    """The count of edges at or below ``max(c, C_FLOOR)``, less one, is `cost_at`'s u-cell
    (``floor((log10 c' - u0) / du)``, computed as it is: numba's log10) on every probe, the
    edges and their neighbouring doubles included: the edges are the cells' least contrasts."""
    from numba import njit

    @njit
    def cells(c, u0, du):
        out = np.empty(c.size)
        for i in range(c.size):
            cp = c[i] if c[i] > C_FLOOR else C_FLOOR
            out[i] = np.floor((np.log10(cp) - u0) / du)
        return out

    prior = level_prior(*_sample(seed))
    edges = contrast_edges(prior)
    assert edges.shape == (GRID + 1,) and np.all(np.diff(edges) >= 0)  # cells below C_FLOOR: edges at it
    _, c = _edge_probes(prior, np.random.default_rng(seed))
    want = cells(c, prior.u0, prior.du)
    counted = np.searchsorted(edges, np.maximum(c, C_FLOOR), side="right") - 1
    inside = (want >= 0) & (want < GRID)
    np.testing.assert_array_equal(counted[inside], want[inside])
    assert np.all((counted[~inside] < 0) | (counted[~inside] >= GRID))
    assert inside.sum() > 1000 and (~inside).sum() > 100


@pytest.mark.parametrize("kind", ["real", "dyadic", "floor on an edge"])
def test_lane_lookup_is_cost_at_bit_for_bit(kind):
    """`costs_at` (16 lanes at a time, the posterior's) returns `cost_at`'s cost on every probe:
    random levels, the u-edges and the doubles beside them, the w-edges, off the grid, negative
    offsets, zero / negative / tiny / infinite contrast and an infinite offset."""
    from numba import njit

    from edge.decode.level_prior import costs_at

    rng = np.random.default_rng(7)
    if kind == "real":
        prior = level_prior(*_sample(2))
    else:
        u0 = -3.0 if kind == "dyadic" else -8.0  # C_FLOOR = 1e-6 is u-edge 16 of the second
        prior = LevelPrior(rng.uniform(0.0, 20.0, (GRID, GRID)), u0, 0.125, 0.0, 1.0 / 64.0, 50.0, 1000)
    b, c = _edge_probes(prior, rng)
    b, c = np.r_[b, np.inf, 0.1, 0.1], np.r_[c, 0.01, np.inf, -np.inf]
    pad = (-b.size) % 16
    b, c = np.r_[b, np.zeros(pad)], np.r_[c, np.ones(pad)]
    args = kernel_args(prior)
    edges = contrast_edges(prior)

    @njit
    def lanes(table, u0, du, edges, w0, dw, outside, b, c):
        out = np.empty(b.size)
        cp = np.empty(16)
        iu = np.empty(16, np.int64)
        for i in range(0, b.size, 16):
            costs_at(table, u0, du, edges, w0, dw, outside, b[i:i + 16], c[i:i + 16], cp, iu, out[i:i + 16])
        return out

    got = lanes(args[0], args[1], args[2], edges, args[3], args[4], args[5], b, c)
    want = np.array([cost_at(*args[:6], x, y) for x, y in zip(b.tolist(), c.tolist())])
    np.testing.assert_array_equal(got, want)
    assert (want != prior.outside).sum() > 500 and (want == prior.outside).sum() > 50
