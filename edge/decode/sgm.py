"""Semi-global regularisation of each pixel's top-K candidate columns (method "sgm").

Beyond the paper: the candidates of a pixel are re-ranked by a smoothness prior on disparity
along four scan directions, in the probability units of the decoder's likelihoods (nats; no
per-scene or per-code tuning: the only parameters are two prior probabilities).

States.  Pixel p has K candidate states (its codebook rows ``c_k``, best-first from the
posterior or the search; absent where ``c_k < 0``) and one *none* state (index K: the pixel is
not lit by the pattern; it also absorbs "the column is none of these").

Model.  Along any scan line the true state is a reversible Markov chain over the N candidate
columns (``choices``: codebook rows in use, or the disparity band's) and "none", with
stationary prior ``pi(column) = 1 / (2 N)``, ``pi(none) = 1 / 2`` (the posterior's even odds
of lit / not lit and uniform column prior).  From a column, the next pixel lies across a depth
edge with probability ``p_edge`` (`P_EDGE` = 0.02: one edge in 50 pixels), where it is not lit
with probability 1/2 or takes any of the N columns; otherwise it is on the same surface: one of
the three nearest rows (``u <= 1``) with probability ``1 - f_steep`` or one of the two rows at
``1 < u <= 2`` with probability ``f_steep`` (`F_STEEP` = 0.1), where ``u = |d_p - d_q|`` and
``d = x s_x + y s_y - c`` is a candidate's disparity in codebook rows.  The steps (s_x, s_y)
are the column change per camera pixel on a fronto-parallel surface: `edge.decode.spatial`'s
convention (``d = x - c * stripe`` projector pixels) is ``(1 / stripe, 0)``; `from_posterior` /
`from_search` measure them on the capture (`surface_steps`: the median column step of
confidently decoded neighbours), so a camera that samples the projector coarser or finer, or
is not rectified with it, still sees its surfaces as smooth.  From none, the next pixel is lit (any column) with
probability ``p_edge / 2``.  Costs are negative log probabilities relative to the nearest-row
transition ``(1 - p_edge)(1 - f_steep) / 3`` (`penalties`, a `Prior`), previous pixel first:

    column -> column, u <= 1:      0
    column -> column, u <= 2:      P1        = log(2 (1 - f_steep) / (3 f_steep))   (1.79)
    column -> column, u > 2:       P2        = log(2 N (1 - p_edge)(1 - f_steep) / (3 p_edge))
    none -> column:                P2                                          (10.3 for N = 1024)
    column -> none:                col_none  = P2 - log N                              (3.38)
    none -> none:                  none_none = log((1 - p_edge)(1 - f_steep) / (3 (1 - p_edge / 2)))  (-1.21)
    node prior W: column log N, none 0   (``-log pi`` up to a constant)

Unary costs U (nats, likelihood ratios against the best candidate):

* candidate k: ``(L_k - L_1) / 2`` with ``L_k`` the posterior's distance of candidate k (its
  -2 log-likelihood plus the level prior's cost)
  (`edge.decode.posterior`'s ``distances``; under the "confidence" rule the search's ML
  distances, equal up to a per-pixel constant); absent: `BIG`;
* none: ``-log(e0 / N)``, with e0 the posterior odds of its "not lit" hypothesis against the
  best candidate (which include the 1 / N column prior), recovered from the published error
  ``E = (far + e0) / (1 + every + e0)`` (`posterior_unaries`).  Under the "confidence" rule
  there is no such hypothesis: ``P2 + log N`` where the pixel is eligible, and only the none
  state where it is not (`search_unaries`).

Aggregation (SGM, Hirschmueller 2008) on four directions r (`DIRECTIONS`: left-right,
right-left, top-bottom, bottom-top), with ``p - r`` the previous pixel of the scan line:

    L_r(p, k) = U(p, k) + W(k)                                        (first pixel of a line)
    L_r(p, k) = U(p, k) + min_j [L_r(p - r, j) + V(j -> k)] - min_j L_r(p - r, j)
    S(p, k)   = sum_r L_r(p, k) - 3 (U(p, k) + W(k))

By reversibility (``W(a) + V(a -> b) = W(b) + V(b -> a)``), ``S(p, k) - min_k S(p, k)`` is
exactly the min-marginal of the energy ``W(x_p) + sum U + sum V`` (edges oriented away from p)
over the labellings of the cross made of p's image row and column (a tree), the node prior
and the unary counted once (`tests/test_decode_sgm.py` checks this by brute force).  One pixel
without neighbours gets ``S = U + W``: exactly the posterior's odds.

Decision.  Per pixel: b = the candidate state of least S (ties: the better-ranked); the
regularised error probability of its column, the aggregated costs read as posterior odds,

    E(p) = sum_{j far from b} exp(-(S_j - S_b)) / sum_j exp(-(S_j - S_b))

over the present states j (far: the none state, or a row more than one from b's, as in
`edge.decode.posterior`); the column is b's row, valid where ``S_b <= S_none`` and ``E <
max_error`` (Chow's reject rule at the decoder's one error target; max_error is the only
threshold).  Candidates come back re-ordered by S (``candidates[..., 0]`` is b), their
distances alongside.

Shapes: candidates (H, W, K) int32, K >= 1 (3 in the decoder); unary (H, W, K + 1) float32 (the
none state last); outputs (H, W) unless stated.  Cost: four passes of (K + 1)**2 transitions
per pixel, rows in parallel (columns in blocks of `_BLOCK`); about 40 ms for 600 x 700 on 2
cores (unloaded; `tools/eval_posterior.py` compares the methods).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

#: Prior probability that two neighbouring pixels lie across a depth edge (see `penalties`).
P_EDGE = 0.02
#: Share of same-surface neighbours whose rows differ by two (a steep surface).
F_STEEP = 0.1
#: Cost of an absent candidate state (never chosen; far above every finite path cost).
BIG = np.float32(1e6)
#: Largest |U_none| (nats): the odds the float32 error can still resolve are far inside it.
NONE_CLIP = 80.0
#: Fewer neighbour pairs than this: `surface_steps` keeps the disparity convention.
MIN_STEP_VOTES = 200
#: Largest |column step| between neighbours `surface_steps` counts (larger: depth edges).
STEP_SPAN = 64
#: Odds below exp(-_EXP_CUT) (1e-26) are counted as 0 (far below any error target).
_EXP_CUT = 60.0
_E_CLIP = math.exp(-NONE_CLIP)
#: Directions of `path_costs`: (dy, dx) of the step from the previous pixel of a scan line.
DIRECTIONS = {"left-right": (0, 1), "right-left": (0, -1), "top-bottom": (1, 0), "bottom-top": (-1, 0)}
#: Column-block width of the vertical passes (each thread runs whole blocks, rows in order).
_BLOCK = 32


class Regularised(NamedTuple):
    """Output of `regularise` (all (H, W) unless stated).

    column: int32 the chosen row, -1 where invalid; valid: bool; error: float32 E of the module
    docstring (1 where no candidate); none: bool where the none state won; candidates /
    distances: (H, W, K) re-ordered by aggregated cost (the distances are the input's, e.g. the
    posterior's ``L_k``); costs: (H, W, K + 1) float32 ``S - min S`` in the re-ordered state
    order (the none state last).
    """

    column: np.ndarray
    valid: np.ndarray
    error: np.ndarray
    none: np.ndarray
    candidates: np.ndarray
    distances: np.ndarray
    costs: np.ndarray


class Prior(NamedTuple):
    """Costs of the scan-line prior in nats (`penalties`): ``p1`` / ``p2`` between candidate
    states (steep surface / depth edge), ``col_none`` / ``none_col`` / ``none_none`` the
    transitions into, out of and within the none state (previous pixel first), ``col_prior``
    the node prior of a column state against the none state (``log N``)."""

    p1: float
    p2: float
    col_none: float
    none_col: float
    none_none: float
    col_prior: float


def penalties(choices: int, *, p_edge: float = P_EDGE, f_steep: float = F_STEEP) -> Prior:
    """The `Prior` of the module docstring for N = `choices` candidate columns (>= 1)."""
    if choices < 1:
        raise ValueError(f"choices: expected >= 1 candidate columns, got {choices}")
    if not (0 < p_edge < 1 and 0 < f_steep < 1):
        raise ValueError(f"p_edge, f_steep: expected probabilities in (0, 1), got {p_edge}, {f_steep}")
    near = (1.0 - p_edge) * (1.0 - f_steep) / 3.0  # per row, the reference (cost 0)
    log_n = math.log(choices)
    p1 = max(math.log(near / ((1.0 - p_edge) * f_steep / 2.0)), 0.0)
    p2 = max(math.log(near / (p_edge / (2.0 * choices))), p1)
    return Prior(p1=p1, p2=p2, col_none=math.log(near / (p_edge / 2.0)), none_col=p2,
                 none_none=math.log(near / (1.0 - p_edge / 2.0)), col_prior=log_n)


@njit(cache=True)
def _advance(disp, unary, y, x, dprev, prev, cur, pr, top):
    """One recurrence step of the module docstring: cur (the K + 1 costs of pixel (y, x)) from
    prev, the previous pixel's, whose candidates' disparities (rows) are dprev.  pr: (p1, p2,
    col_none, none_col, none_none); top: the largest of them."""
    ns = prev.shape[0]
    kk = ns - 1
    mprev = prev[0]
    for j in range(1, ns):
        mprev = min(mprev, prev[j])
    lnone = prev[kk]
    # into a column state k: from a column j (0 / P1 / P2 by disparity) or from none
    step2 = pr[1] - pr[0]
    for k in range(kk):
        dk = disp[y, x, k]
        best = min(mprev + top, lnone + pr[3])
        for j in range(kk):
            du = abs(dprev[j] - dk)
            # 0 (du <= 1), P1 (du <= 2), P2: arithmetic, not branches (neighbours differ at random)
            c = prev[j] + pr[0] * np.float64(du > 1.0) + step2 * np.float64(du > 2.0)
            best = min(best, c)
        cur[k] = unary[y, x, k] + (best - mprev)
    best = lnone + pr[4]
    for j in range(kk):
        best = min(best, prev[j] + pr[2])
    cur[kk] = unary[y, x, kk] + (best - mprev)


@njit(cache=True)
def _begin(unary, y, x, col_prior, cur):
    """First pixel of a scan line: L = U + the node prior (col_prior on the column states)."""
    ns = cur.shape[0]
    for k in range(ns - 1):
        cur[k] = unary[y, x, k] + col_prior
    cur[ns - 1] = unary[y, x, ns - 1]


@njit(cache=True, parallel=True)
def _rows(disp, unary, pr, col_prior, passes, init, total):
    """Row passes into total: ``passes`` bit 0 left-right, bit 1 right-left; init: first set
    total = -3 (U + node prior)."""
    height, width, ns = unary.shape
    kk = ns - 1
    top = max(pr[1], max(pr[2], max(pr[3], pr[4])))  # no transition costs more
    for y in prange(height):
        prev = np.empty(ns, np.float64)
        cur = np.empty(ns, np.float64)
        dprev = np.empty(kk, np.float64)
        if init:
            for x in range(width):
                for k in range(ns):
                    total[y, x, k] = -3.0 * (unary[y, x, k] + (col_prior if k < kk else 0.0))
        for rev in range(2):
            if not (passes >> rev) & 1:
                continue
            for i in range(width):
                x = width - 1 - i if rev else i
                if i == 0:
                    _begin(unary, y, x, col_prior, cur)
                else:
                    _advance(disp, unary, y, x, dprev, prev, cur, pr, top)
                for k in range(ns):
                    total[y, x, k] += cur[k]
                    prev[k] = cur[k]
                for k in range(kk):
                    dprev[k] = disp[y, x, k]


@njit(cache=True, parallel=True)
def _cols(disp, unary, pr, col_prior, passes, total):
    """Column passes into total (blocks of `_BLOCK` columns per thread, rows in order):
    ``passes`` bit 0 top-bottom, bit 1 bottom-top."""
    height, width, ns = unary.shape
    kk = ns - 1
    top = max(pr[1], max(pr[2], max(pr[3], pr[4])))
    blocks = (width + _BLOCK - 1) // _BLOCK
    for b in prange(blocks):
        xa = b * _BLOCK
        xb = min(width, xa + _BLOCK)
        prev = np.empty((_BLOCK, ns), np.float64)
        cur = np.empty(ns, np.float64)
        dprev = np.empty((_BLOCK, kk), np.float64)
        for rev in range(2):
            if not (passes >> rev) & 1:
                continue
            for i in range(height):
                y = height - 1 - i if rev else i
                for x in range(xa, xb):
                    c = x - xa
                    if i == 0:
                        _begin(unary, y, x, col_prior, cur)
                    else:
                        _advance(disp, unary, y, x, dprev[c], prev[c], cur, pr, top)
                    for k in range(ns):
                        total[y, x, k] += cur[k]
                        prev[c, k] = cur[k]
                    for k in range(kk):
                        dprev[c, k] = disp[y, x, k]


@njit(cache=True, parallel=True)
def _disparities(cand, step_x, step_y, out):
    """out[y, x, k] = x step_x + y step_y - cand[y, x, k]: the candidates' disparities in rows."""
    height, width, k = cand.shape
    for y in prange(height):
        for x in range(width):
            for j in range(k):
                out[y, x, j] = x * step_x + y * step_y - cand[y, x, j]


@njit(cache=True)
def _step_votes(col, ok, span, hist_x, hist_y):
    """Histograms (offset `span`) of the column differences of horizontally / vertically
    neighbouring `ok` pixels with ``|difference| <= span``."""
    height, width = col.shape
    for y in range(height):
        for x in range(width):
            if not ok[y, x]:
                continue
            if x + 1 < width and ok[y, x + 1]:
                d = col[y, x + 1] - col[y, x]
                if -span <= d <= span:
                    hist_x[d + span] += 1
            if y + 1 < height and ok[y + 1, x]:
                d = col[y + 1, x] - col[y, x]
                if -span <= d <= span:
                    hist_y[d + span] += 1


@njit(cache=True, parallel=True)
def _decide(cand, dist, total, max_error, out_col, out_valid, out_err, out_none, out_cand, out_dist, out_cost):
    height, width, ns = total.shape
    kk = ns - 1
    half = BIG * 0.5
    for y in prange(height):
        order = np.empty(kk, np.int64)
        sv = np.empty(ns, np.float64)
        cv = np.empty(kk, np.int64)
        for x in range(width):
            for k in range(ns):
                sv[k] = total[y, x, k]
            # candidate states by aggregated cost (absent last; ties keep the input order)
            for k in range(kk):
                cv[k] = cand[y, x, k]
                if cv[k] < 0:
                    sv[k] = BIG  # absent whatever its cost
                j = k
                while j > 0 and sv[order[j - 1]] > sv[k]:
                    order[j] = order[j - 1]
                    j -= 1
                order[j] = k
            b = order[0]
            sb = sv[b]
            sn = sv[kk]
            present_best = sb < half
            ref = min(sb, sn) if present_best else sn
            for i in range(kk):
                k = order[i]
                out_cand[y, x, i] = cv[k]
                out_dist[y, x, i] = dist[y, x, k]
                out_cost[y, x, i] = sv[k] - ref
            out_cost[y, x, kk] = sn - ref
            if not present_best:
                out_col[y, x] = -1
                out_valid[y, x] = False
                out_err[y, x] = 1.0
                out_none[y, x] = True
                continue
            cb = cv[b]
            den = 0.0
            far = 0.0
            for j in range(ns):
                gap = sv[j] - ref
                if gap < _EXP_CUT:  # absent states (>= BIG / 2) are far beyond the cut
                    e = math.exp(-gap)
                    den += e
                    if j == kk or abs(cv[j] - cb) > 1:
                        far += e
            err = far / den
            is_none = sn < sb
            out_err[y, x] = err
            out_none[y, x] = is_none
            ok = (not is_none) and err < max_error
            out_valid[y, x] = ok
            out_col[y, x] = cb if ok else -1


def _check(candidates: np.ndarray, unary: np.ndarray, steps: tuple[float, float],
           prior: Prior) -> tuple[np.ndarray, np.ndarray]:
    cand = np.asarray(candidates)
    if cand.ndim != 3 or cand.shape[2] < 1:
        raise ValueError(f"candidates: expected an (H, W, K) array, got shape {cand.shape}")
    h, w, k = cand.shape
    if h < 1 or w < 1:
        raise ValueError(f"candidates: expected a non-empty image, got shape {cand.shape}")
    if np.shape(unary) != (h, w, k + 1):
        raise ValueError(f"unary: expected shape {(h, w, k + 1)} (K candidates + none), got {np.shape(unary)}")
    if len(steps) != 2 or not all(math.isfinite(float(v)) for v in steps):
        raise ValueError(f"steps: expected two finite column steps (x, y), got {steps!r}")
    if not isinstance(prior, Prior) or not all(math.isfinite(v) for v in prior):
        raise ValueError(f"prior: expected a Prior of finite costs (see penalties), got {prior!r}")
    u = np.ascontiguousarray(unary, np.float32)
    if np.isnan(u).any():
        raise ValueError("unary: expected no NaN")
    u = np.minimum(u, BIG)  # inf -> BIG: absent
    return np.ascontiguousarray(cand, np.int32), u


def path_costs(candidates: np.ndarray, unary: np.ndarray, *, direction: str, prior: Prior,
               steps: tuple[float, float] = (1.0, 0.0)) -> np.ndarray:
    """(H, W, K + 1) float32 ``L_r`` of the module docstring along `direction` (a key of
    `DIRECTIONS`).  candidates (H, W, K) int32 rows (-1 absent); unary (H, W, K + 1) costs in
    nats (inf or >= `BIG`: absent), the none state last; steps: the column steps (s_x, s_y) of
    the disparity ``x s_x + y s_y - c`` (rows; default the convention's ``(1 / stripe, 0)`` for
    stripe 1; `surface_steps`)."""
    if direction not in DIRECTIONS:
        raise ValueError(f"direction: expected one of {', '.join(DIRECTIONS)}, got {direction!r}")
    cand, u = _check(candidates, unary, steps, prior)
    out = np.zeros(u.shape, np.float32)
    _passes(cand, u, steps, prior, {direction}, False, out)
    return out.astype(np.float32)


def _passes(cand, u, steps, prior, directions, init, total) -> None:
    disp = np.empty(cand.shape, np.float32)
    _disparities(cand, float(steps[0]), float(steps[1]), disp)
    pr = np.array(prior[:5], np.float64)
    rows = int("left-right" in directions) | (int("right-left" in directions) << 1)
    cols = int("top-bottom" in directions) | (int("bottom-top" in directions) << 1)
    if rows or init:
        _rows(disp, u, pr, float(prior.col_prior), rows, init, total)
    if cols:
        _cols(disp, u, pr, float(prior.col_prior), cols, total)


def aggregate(candidates: np.ndarray, unary: np.ndarray, *, prior: Prior,
              steps: tuple[float, float] = (1.0, 0.0)) -> np.ndarray:
    """(H, W, K + 1) float32 ``S = sum_r L_r - 3 (U + W)`` over the four `DIRECTIONS`
    (arguments as `path_costs`)."""
    cand, u = _check(candidates, unary, steps, prior)
    total = np.empty(u.shape, np.float32)
    _passes(cand, u, steps, prior, set(DIRECTIONS), True, total)
    return total.astype(np.float32)


def regularise(candidates: np.ndarray, unary: np.ndarray, *, max_error: float, prior: Prior,
               steps: tuple[float, float] = (1.0, 0.0), distances: np.ndarray | None = None) -> Regularised:
    """Aggregate (`aggregate`) and decide (module docstring): a `Regularised`.

    candidates (H, W, K) int32 rows best-first (-1 absent); unary (H, W, K + 1) float32 nats
    (none state last; `posterior_unaries` / `search_unaries`); max_error in (0, 1); prior:
    `penalties`; steps: as `path_costs` (`surface_steps`); distances: (H, W, K)
    carried along the re-ordering (default: the candidates' unaries)."""
    if not 0 < max_error < 1:
        raise ValueError(f"max_error: expected a probability in (0, 1), got {max_error}")
    cand, u = _check(candidates, unary, steps, prior)
    h, w, k = cand.shape
    dist = u[..., :k] if distances is None else np.ascontiguousarray(distances, np.float32)
    if dist.shape != cand.shape:
        raise ValueError(f"distances: expected shape {cand.shape}, got {dist.shape}")
    total = np.empty(u.shape, np.float32)
    _passes(cand, u, steps, prior, set(DIRECTIONS), True, total)
    col = np.empty((h, w), np.int32)
    valid = np.empty((h, w), np.bool_)
    err = np.empty((h, w), np.float32)
    none = np.empty((h, w), np.bool_)
    out_cand = np.empty((h, w, k), np.int32)
    out_dist = np.empty((h, w, k), np.float32)
    out_cost = np.empty((h, w, k + 1), np.float32)
    _decide(cand, dist, total, float(max_error), col, valid, err, none, out_cand, out_dist, out_cost)
    return Regularised(col, valid, err, none, out_cand, out_dist, out_cost)


@njit(cache=True, parallel=True)
def _posterior_unaries(cand, dist, error, log_n, scored, out):
    height, width, k = cand.shape
    for y in prange(height):
        for x in range(width):
            l1 = dist[y, x, 0]
            c0 = cand[y, x, 0]
            if c0 < 0 or not np.isfinite(l1):
                for j in range(k):
                    out[y, x, j] = BIG
                out[y, x, k] = 0.0
                continue
            out[y, x, 0] = 0.0
            every = 0.0
            far = 0.0
            for j in range(1, k):
                lj = dist[y, x, j]
                if cand[y, x, j] < 0 or not np.isfinite(lj):
                    out[y, x, j] = BIG
                    continue
                uj = max(0.5 * (lj - l1), 0.0)
                out[y, x, j] = uj
                if j >= scored:  # an added state (`edge.decode.propagate`): not in the published error
                    continue
                e = math.exp(-uj) if uj < _EXP_CUT else 0.0
                every += e
                if abs(cand[y, x, j] - c0) > 1:
                    far += e
            err = float(error[y, x])
            e0 = (err * (1.0 + every) - far) / max(1.0 - err, 2.0 ** -24)
            if e0 <= _E_CLIP:
                out[y, x, k] = NONE_CLIP + log_n
            else:
                out[y, x, k] = min(max(-math.log(e0), -NONE_CLIP), NONE_CLIP) + log_n


def posterior_unaries(candidates: np.ndarray, distances: np.ndarray, error: np.ndarray, *, choices: int,
                      scored: int | None = None) -> np.ndarray:
    """(H, W, K + 1) float32 unaries of the module docstring from `edge.decode.posterior`'s
    output: candidates (H, W, K) int32 best-first, distances (H, W, K) the -2 log-likelihoods
    ``L_k`` (inf absent), error (H, W) its P(wrong); choices: N.  The none state's ``-log e0`` is
    clipped to [-`NONE_CLIP`, `NONE_CLIP`] before ``log N`` is added.  scored: the first
    `scored` candidates are the ones the error was computed over (default K); e0 is recovered
    from those, and later ones (`edge.decode.propagate`'s extra state) only get their unary."""
    cand = np.ascontiguousarray(candidates, np.int32)
    if cand.ndim != 3 or np.shape(distances) != cand.shape or np.shape(error) != cand.shape[:2]:
        raise ValueError(f"posterior_unaries: expected candidates / distances (H, W, K) and error (H, W), got "
                         f"{cand.shape}, {np.shape(distances)}, {np.shape(error)}")
    out = np.empty(cand.shape[:2] + (cand.shape[2] + 1,), np.float32)
    if choices < 1:
        raise ValueError(f"choices: expected >= 1 candidate columns, got {choices}")
    k = cand.shape[2] if scored is None else int(scored)
    if not 1 <= k <= cand.shape[2]:
        raise ValueError(f"scored: expected 1..{cand.shape[2]} candidates, got {scored}")
    _posterior_unaries(cand, np.ascontiguousarray(distances, np.float32), np.ascontiguousarray(error, np.float32),
                       float(math.log(choices)), k, out)
    return out


def search_unaries(candidates: np.ndarray, distances: np.ndarray, eligible: np.ndarray, *,
                   none_cost: float) -> np.ndarray:
    """(H, W, K + 1) float32 unaries under the "confidence" rule: ``(d_k - d_1) / 2`` of the
    search's ML distances (inf absent) and ``none_cost`` (nats) for the none state where
    `eligible`; only the none state (cost 0) elsewhere."""
    cand = np.asarray(candidates)
    d = np.asarray(distances, np.float64)
    if cand.ndim != 3 or d.shape != cand.shape or np.shape(eligible) != cand.shape[:2]:
        raise ValueError(f"search_unaries: expected candidates / distances (H, W, K) and eligible (H, W), got "
                         f"{cand.shape}, {d.shape}, {np.shape(eligible)}")
    present = (cand >= 0) & np.isfinite(d) & np.asarray(eligible, bool)[..., None]
    d = np.where(present, d, 0.0)
    u = np.where(present, np.maximum(0.5 * (d - d[..., :1]), 0.0), float(BIG))
    none = np.where(present[..., 0], float(none_cost), 0.0)
    return np.concatenate([u, none[..., None]], axis=2).astype(np.float32)


def surface_steps(column: np.ndarray, ok: np.ndarray, *, stripe: int) -> tuple[float, float]:
    """(s_x, s_y): the column step per camera pixel along x and y on one surface, measured on
    this capture: the (lower) medians of the column differences of neighbouring `ok` pixels
    (rows; the confidently decoded ones; differences beyond `STEP_SPAN` are depth edges and do
    not vote), each where at least `MIN_STEP_VOTES` pairs vote, else the
    disparity convention's ``1 / stripe`` and 0 (a rectified camera and projector of equal
    resolution).  column (H, W) int rows, ok (H, W) bool."""
    if stripe < 1:
        raise ValueError(f"stripe: expected >= 1, got {stripe}")
    col = np.ascontiguousarray(column, np.int64)
    hx = np.zeros(2 * STEP_SPAN + 1, np.int64)
    hy = np.zeros(2 * STEP_SPAN + 1, np.int64)
    _step_votes(col, np.ascontiguousarray(ok, np.bool_) & (col >= 0), STEP_SPAN, hx, hy)
    out = []
    for hist, default in ((hx, 1.0 / stripe), (hy, 0.0)):
        total = int(hist.sum())
        # the lower median of the integer steps
        out.append(float(np.searchsorted(np.cumsum(hist), (total + 1) // 2) - STEP_SPAN)
                   if total >= MIN_STEP_VOTES else default)
    return out[0], out[1]


def from_posterior(candidates: np.ndarray, distances: np.ndarray, error: np.ndarray, *, choices: int, stripe: int,
                   max_error: float, scored: int | None = None) -> Regularised:
    """Method "sgm" under the "error" rule: `regularise` of `edge.decode.posterior`'s candidates
    (H, W, K), distances ``L_k`` (H, W, K) and error (H, W) with `posterior_unaries` (`scored`:
    as there; the decoder passes the top three plus `edge.decode.propagate`'s extra state), the
    default `penalties` for `choices` columns and the `surface_steps` of the pixels with
    ``error < max_error``."""
    prior = penalties(choices)
    steps = surface_steps(candidates[..., 0], np.asarray(error) < max_error, stripe=stripe)
    return regularise(candidates, posterior_unaries(candidates, distances, error, choices=choices, scored=scored),
                      max_error=max_error, steps=steps, prior=prior, distances=distances)


def from_search(candidates: np.ndarray, distances: np.ndarray, eligible: np.ndarray, *, choices: int, stripe: int,
                max_error: float) -> Regularised:
    """Method "sgm" under the "confidence" rule: `regularise` of the search's candidates and ML
    distances (H, W, K) with `search_unaries` (none state: ``P2 + log N`` where eligible), the
    default `penalties` for `choices` columns and the `surface_steps` of the eligible pixels
    whose runner-up is less than max_error as likely (``(d2 - d1) / 2 > log(1 / max_error)``).
    Ineligible pixels (contrast) are invalid."""
    prior = penalties(choices)
    unary = search_unaries(candidates, distances, eligible, none_cost=prior.p2 + prior.col_prior)
    steps = surface_steps(candidates[..., 0], np.asarray(eligible, bool) & (unary[..., 1] > math.log(1.0 / max_error)),
                          stripe=stripe)
    return regularise(candidates, unary, max_error=max_error, steps=steps, prior=prior, distances=distances)
