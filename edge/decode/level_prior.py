"""The capture's own prior over a pixel's levels: the empirical-Bayes term of the error rule.

Each candidate codeword k of a pixel is scored with its levels ``(b, c)`` (off level, on - off
contrast) fitted to that codeword (`edge.decode.posterior`).  Profiling the levels out like this
is a flat prior over them: a competitor whose best levels are ones no pixel of the capture has
counts as much, a priori, as the best candidate, whose levels are typical.  At a fixed total
exposure a far competitor fits a lower contrast and a higher off level than the truth, and where
the scene has no pixels that dim (albedo >= 0.25, say) the flat prior overstates it several
times.  The levels of the capture's pixels are known, though: the best candidates' fits of the
noise-fit pixels (`posterior.fit_noise`) are a sample of them.  Their density p is the prior,
and each candidate's ``-2 log-likelihood L_k`` gets ``-2 log p(b_k, c_k)`` added: the Laplace
approximation of marginalising the levels under p (the Hessian term, the same for every
codeword up to the log of the ratio of its counts of ones and zeros, O(0.1), is left out).

The estimate.  Coordinates ``u = log10(c')`` (contrast spans decades) and ``w = b' / (b' + c')``
(the off level's share of the on level, 0..1), ``b' = max(b, 0)``, ``c' = max(c, C_FLOOR)``, in
which the density is taken, not in (b, c) (the Jacobian between the two also varies by O(0.1)
between a pixel's candidates).  A binned Gaussian kernel density estimate (Wand 1994): the
sample's histogram on a `GRID` x `GRID` grid spanning its range widened by `REACH` bandwidths,
convolved with a Gaussian of the bandwidth per coordinate ``h = s * N**(-1/6)`` (Scott's rule
for two dimensions, with Silverman's robust scale ``s = min(sd, IQR / 1.349)``); then one
pseudo-pixel spread uniformly over the grid (additive smoothing: ``p = (N * kde + 1 / cells) /
(N + 1)`` per cell), so that levels nothing in the capture has get a small, finite density, the
same density as outside the grid.  Nothing here is tuned: the bandwidth rule is the textbook
one, and the floor is one pixel's worth.

Units: b, c in normalised intensity (1 = full scale); costs in -2 log units (the same as L).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

#: Grid cells per coordinate of the level density.
GRID = 64
#: Contrasts below this (normalised) count as this in u = log10(c) (the fit clamps c at 0).
C_FLOOR = 1e-6
#: The grid spans the sample's range widened by this many bandwidths on each side.
REACH = 3.0
#: Fewer pixels with levels than this: no prior (the flat one), as the noise fit's `MIN_FIT_PIXELS`.
MIN_PIXELS = 500


class LevelPrior(NamedTuple):
    """The capture's level prior as a table: ``cost[i, j] = -2 log p`` of grid cell (i, j), cell
    (i, j) covering ``u in [u0 + i du, u0 + (i + 1) du)``, ``w in [w0 + j dw, w0 + (j + 1) dw)``;
    ``outside`` the cost of levels off the grid; ``pixels`` the sample size."""

    cost: np.ndarray
    u0: float
    du: float
    w0: float
    dw: float
    outside: float
    pixels: int


def coordinates(b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, w) of levels b, c (arrays of one shape, normalised units), as the module docstring."""
    bp = np.maximum(np.asarray(b, np.float64), 0.0)
    cp = np.maximum(np.asarray(c, np.float64), C_FLOOR)
    return np.log10(cp), bp / (bp + cp)


def _robust_scale(v: np.ndarray) -> float:
    q75, q25 = np.percentile(v, [75.0, 25.0])
    s = min(float(np.std(v)), float(q75 - q25) / 1.349)
    return s if s > 0.0 else float(np.std(v))


def _gauss(cells: int, sigma_cells: float) -> np.ndarray:
    """(cells, cells) matrix of a Gaussian convolution along one axis, sigma (> 0) in cells (zero
    outside the grid: mass smoothed off the grid is lost, as it would be beyond the sample)."""
    t = np.arange(cells, dtype=np.float64)
    kern = np.exp(-0.5 * ((t[:, None] - t[None, :]) / sigma_cells) ** 2)
    return kern / (sigma_cells * np.sqrt(2.0 * np.pi))


def level_prior(b: np.ndarray, c: np.ndarray) -> LevelPrior | None:
    """The `LevelPrior` of a sample of levels: b, c any shape, float (NaN = no level, skipped).
    None (a flat prior) where fewer than `MIN_PIXELS` are finite."""
    b = np.ravel(np.asarray(b, np.float64))
    c = np.ravel(np.asarray(c, np.float64))
    ok = np.isfinite(b) & np.isfinite(c)
    count = int(ok.sum())
    if count < MIN_PIXELS:
        return None
    u, w = coordinates(b[ok], c[ok])
    factor = count ** (-1.0 / 6.0)
    hu = max(_robust_scale(u) * factor, 1e-6)
    hw = max(_robust_scale(w) * factor, 1e-6)
    u0, u1 = float(u.min()) - REACH * hu, float(u.max()) + REACH * hu
    w0, w1 = float(w.min()) - REACH * hw, float(w.max()) + REACH * hw
    du, dw = (u1 - u0) / GRID, (w1 - w0) / GRID
    iu = np.clip(((u - u0) / du).astype(np.int64), 0, GRID - 1)
    iw = np.clip(((w - w0) / dw).astype(np.int64), 0, GRID - 1)
    hist = np.bincount(iu * GRID + iw, minlength=GRID * GRID).reshape(GRID, GRID).astype(np.float64)
    kde = _gauss(GRID, hu / du) @ hist @ _gauss(GRID, hw / dw).T
    kde /= kde.sum()
    cells = GRID * GRID
    mass = (count * kde + 1.0 / cells) / (count + 1.0)  # one pseudo-pixel spread over the grid
    area = du * dw
    cost = -2.0 * np.log(mass / area)
    outside = -2.0 * np.log((1.0 / cells) / (count + 1.0) / area)
    return LevelPrior(np.ascontiguousarray(cost), u0, du, w0, dw, float(outside), count)


def prior_cost(prior: LevelPrior | None, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """-2 log p(b, c) (float64, the shape of b), 0 everywhere under the flat prior (None)."""
    b = np.asarray(b, np.float64)
    if prior is None:
        return np.zeros(b.shape)
    u, w = coordinates(b, c)
    fu = np.floor((u - prior.u0) / prior.du)
    fw = np.floor((w - prior.w0) / prior.dw)
    inside = (fu >= 0) & (fu < prior.cost.shape[0]) & (fw >= 0) & (fw < prior.cost.shape[1])
    iu = np.where(inside, fu, 0).astype(np.int64)
    iw = np.where(inside, fw, 0).astype(np.int64)
    return np.where(inside, prior.cost[iu, iw], prior.outside)


#: A flat prior in the kernels' argument form (`kernel_args`).
_FLAT = (np.zeros((1, 1), np.float64), 0.0, 1.0, 0.0, 1.0, 0.0, False, 0.0)


def kernel_args(prior: LevelPrior | None) -> tuple:
    """(cost, u0, du, w0, dw, outside, use, least) for the kernels: the first six are `cost_at`'s,
    use False for the flat prior, least the table's least cost (the tail mass's skip bound)."""
    if prior is None:
        return _FLAT
    return (prior.cost, float(prior.u0), float(prior.du), float(prior.w0), float(prior.dw), float(prior.outside), True,
            float(prior.cost.min()))


def contrast_edges(prior: LevelPrior | None) -> np.ndarray:
    """(rows + 1,) float64 edges of the prior's u-cells as contrasts, ascending: edge j is the least
    double ``c' >= C_FLOOR`` whose u-cell in `cost_at` (``floor((log10 c' - u0) / du)``) is at
    least j (inf where none is), found by bisection on the doubles with `cost_at`'s arithmetic.
    So the u-cell of any contrast is the number of edges at or below ``c' = max(c, C_FLOOR)``,
    less one (below 0 or from ``rows`` on: off the grid), exactly `cost_at`'s, with no log
    (`costs_at`).  (1,) [inf] for the flat prior."""
    if prior is None:
        return np.full(1, np.inf)
    out = np.empty(prior.cost.shape[0] + 1, np.float64)
    _cell_edges(float(prior.u0), float(prior.du), out)
    return out


@njit(cache=True)
def _u_cell(cp, u0, du):
    """The u-cell of a contrast cp >= C_FLOOR as a float (floor of its grid coordinate): the one
    place of this arithmetic, so that `contrast_edges` finds `cost_at`'s edges exactly."""
    return np.floor((np.log10(cp) - u0) / du)


@njit(cache=True)
def _cell_edges(u0, du, out):
    """`contrast_edges` into out (rows + 1,): per edge a bisection on the bit patterns of the
    positive doubles (ordered as the doubles), invariant u-cell(lo) < j <= u-cell(hi)."""
    bits = np.empty(3, np.float64)
    view = bits.view(np.int64)
    for j in range(out.size):
        if _u_cell(C_FLOOR, u0, du) >= j:
            out[j] = C_FLOOR
            continue
        bits[0] = C_FLOOR
        bits[1] = np.inf  # u-cell inf: at least every j
        lo = view[0]
        hi = view[1]
        while hi - lo > 1:
            view[2] = lo + (hi - lo) // 2
            if _u_cell(bits[2], u0, du) >= j:
                hi = view[2]
            else:
                lo = view[2]
        view[2] = hi
        out[j] = bits[2]


@njit(cache=True)
def cost_at(table, u0, du, w0, dw, outside, b, c):
    """`prior_cost` of one pixel's levels (b, c) in a kernel (table = `LevelPrior.cost`)."""
    bp = b if b > 0.0 else 0.0
    cp = c if c > C_FLOOR else C_FLOOR
    fu = _u_cell(cp, u0, du)
    fw = np.floor((bp / (bp + cp) - w0) / dw)
    if not (fu >= 0.0 and fu < table.shape[0] and fw >= 0.0 and fw < table.shape[1]):  # NaN (b = inf): off
        return outside
    return table[int(fu), int(fw)]


#: log10(2), and a quadratic in the mantissa m in [1, 2) within 0.005 of log2(m): `costs_at`'s
#: first guess of a contrast's cell (exact or next to it; the edges then settle it).
_LOG10_2 = 0.30102999566398120
_LOG2_QUAD = (-1.67487759, 2.02466578, -0.34484843)


@njit(cache=True)
def costs_at(table, u0, du, edges, w0, dw, outside, b, c, cp, iu, out):
    """`cost_at` of the levels (b[l], c[l]) of every lane l into out[l], bit for bit, without a
    log: the u-cell is the number of `contrast_edges` ``edges`` at or below ``c' = max(c,
    C_FLOOR)``, less one, found from a first guess (log2 c' from the exponent and a quadratic in
    the mantissa, `_LOG2_QUAD`) moved edge by edge until it holds: exact whatever the guess.
    b, c, out (L,) float64; scratch cp (L,) float64, iu (L,) int64, both C-contiguous."""
    L = out.shape[0]
    rows = table.shape[0]
    cols = table.shape[1]
    ne = edges.size
    bits = cp.view(np.int64)
    mant = iu.view(np.float64)
    q0, q1, q2 = _LOG2_QUAD
    for l in range(L):
        cl = c[l]
        cp[l] = cl if cl > C_FLOOR else C_FLOOR
    for l in range(L):  # cp > 0: sign bit 0; its mantissa as a double in [1, 2)
        iu[l] = (bits[l] & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000
    for l in range(L):  # the guess of the count, in 0..ne (branch-free: it vectorises)
        m = mant[l]
        u = (np.float64((bits[l] >> 52) - 1023) + q0 + m * (q1 + m * q2)) * _LOG10_2
        g = np.floor((u - u0) / du) + 1.0
        iu[l] = np.int64(min(max(g, 0.0), np.float64(ne)))
    for l in range(L):
        x = cp[l]
        k = iu[l]
        while k > 0 and x < edges[k - 1]:
            k -= 1
        while k < ne and x >= edges[k]:
            k += 1
        iu[l] = k
    for l in range(L):
        bl = b[l]
        bp = bl if bl > 0.0 else 0.0
        fw = np.floor((bp / (bp + cp[l]) - w0) / dw)
        fu = iu[l] - 1
        if fu >= 0 and fu < rows and fw >= 0.0 and fw < cols:  # NaN w (b = inf): off
            out[l] = table[fu, int(fw)]
        else:
            out[l] = outside
