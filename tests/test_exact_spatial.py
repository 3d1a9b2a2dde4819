"""Exactness of the spatial methods' kernels (`edge.decode.spatial`): `confidence_median` (method
"median"), `order_prior` (method "list") and `spatial_outliers`, each against a naive pixel-by-pixel
reference written here from the module docstring (plain python / numpy, none of the module's
helpers), on small random images that hit the edge cases: image borders and 1-pixel images, even
vote counts (the median of two middle values), ties in the ranking, absent candidates (-1),
confidences exactly at the thresholds, pixels that are ineligible or have no column, stripes 1
and 3.  Integer outputs are compared exactly (the kernels promise the rule, not an
approximation of it); the only floating comparisons are ones whose operands are exact in binary
(max_slope 0.5 / 0.25, integer tolerances), or exact rationals (`Fraction`) in the reference.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from edge.decode.spatial import confidence_median, order_prior, spatial_outliers

SHAPES = [(1, 1), (1, 7), (5, 1), (6, 9), (7, 17)]


def _random_map(shape, rng, *, columns=12, absent=0.15, levels=(0.2, 0.5, 0.7, 0.75, 0.9, 1.0)):
    """Columns near a ramp with noise, some -1; confidences on a few float32 levels, two of them
    exactly the thresholds the tests use (0.5, 0.75) and one (0.9) that float32 rounds below a
    float64 0.9 threshold; eligibility random."""
    h, w = shape
    ramp = (np.arange(w)[None, :] // 2 + np.arange(h)[:, None] // 3) % columns
    col = (ramp + rng.integers(-2, 3, shape)).clip(0, columns - 1).astype(np.int32)
    col[rng.random(shape) < absent] = -1
    conf = rng.choice(np.array(levels, np.float32), shape)
    eligible = rng.random(shape) < 0.85
    return col, conf, eligible


# ----------------------------------------------------------------------- confidence_median

def _median_reference(col, conf, eligible, *, t_low, t_high, window, min_votes, tol, cand, vote, stripe, fill,
                      columns):
    h, w = col.shape
    conf = conf.astype(np.float64)                         # thresholds compare exact values (float32 0.9 < 0.9)
    r = window // 2
    out_col = col.copy()
    out_valid = np.zeros((h, w), bool)
    for y in range(h):
        for x in range(w):
            c = int(col[y, x])
            if not eligible[y, x]:
                continue                                   # keeps its column, invalid
            if conf[y, x] >= t_high and c >= 0:
                out_valid[y, x] = True                     # high confidence never changes
                continue
            votes = []
            for y2 in range(y - r, y + r + 1):
                for x2 in range(x - r, x + r + 1):
                    if (y2, x2) == (y, x) or not (0 <= y2 < h and 0 <= x2 < w):
                        continue
                    c2 = int(col[y2, x2])
                    if eligible[y2, x2] and conf[y2, x2] >= t_high and c2 >= 0:
                        votes.append(Fraction(x2 - c2 * stripe) if vote == "disparity" else Fraction(c2))
            if len(votes) < min_votes:
                out_valid[y, x] = bool(conf[y, x] >= t_low and c >= 0)
                continue
            votes.sort()
            m = len(votes)
            med = votes[m // 2] if m % 2 else (votes[m // 2 - 1] + votes[m // 2]) / 2
            p_exact = (x - med) / stripe if vote == "disparity" else med
            p = round(p_exact)                             # python's round: half to even, like np.round
            options = list(cand[y, x]) if cand is not None else [c]
            chosen = next((int(cj) for cj in options if cj >= 0 and abs(int(cj) - p) <= tol), -1)
            if chosen >= 0:
                out_col[y, x], out_valid[y, x] = chosen, True
            elif fill and p >= 0 and (columns is None or p < columns):
                out_col[y, x], out_valid[y, x] = p, True
            else:
                out_col[y, x], out_valid[y, x] = -1, False
    return out_col, out_valid


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("vote, stripe", [("disparity", 1), ("disparity", 3), ("column", 1)])
def test_confidence_median_matches_the_naive_filter(shape, vote, stripe):
    """Every combination of window (1, 3, 5), min_votes, tol, fill, a row bound and candidates
    (with absent ones and duplicates, so ties in the ranking) against the reference, exactly."""
    rng = np.random.default_rng([*shape, stripe, vote == "column"])
    for trial in range(6):
        col, conf, eligible = _random_map(shape, rng)
        if vote == "disparity" and stripe > 1:             # columns near x / stripe, so votes are near 0
            col = np.where(col >= 0, (np.arange(shape[1]) // stripe)[None, :] + col % 3 - 1, -1).clip(-1, None)
            col = col.astype(np.int32)
        cand = np.stack([col, col + rng.integers(-3, 4, shape), col + rng.integers(-1, 2, shape)], axis=2)
        cand[rng.random(cand.shape) < 0.2] = -1
        cand = cand.astype(np.int32)
        for window, min_votes, tol, fill, columns, use_cand in [
                (3, 1, 0, True, None, True), (3, 2, 1, False, None, True), (5, 3, 0, True, 0, True),
                (5, 4, 2, True, None, False), (1, 1, 0, True, None, True), (3, 3, 1, True, 0, False)]:
            if columns is not None:  # rows in use: above every input row (only predictions go beyond)
                columns = int(max(col.max(), cand.max())) + 1
            kw = dict(t_low=0.5, t_high=0.75 if trial % 2 else 0.9, window=window, min_votes=min_votes, tol=tol,
                      vote=vote, stripe=stripe, fill=fill, columns=columns)
            got_col, got_valid = confidence_median(col, conf, eligible, candidates=cand if use_cand else None, **kw)
            ref_col, ref_valid = _median_reference(col, conf, eligible, cand=cand if use_cand else None, **kw)
            assert np.array_equal(got_valid, ref_valid), (trial, window, min_votes, tol, fill, columns, use_cand)
            assert np.array_equal(got_col, ref_col), (trial, window, min_votes, tol, fill, columns, use_cand)
            assert np.array_equal(got_col >= 0, got_valid | ((got_col >= 0) & ~got_valid)), "column -1 or a row"


def test_confidence_median_fills_no_prediction_before_row_0():
    """A prediction below row 0 (neighbours' disparity larger than the pixel's x) is not filled:
    the column is -1 as the docstring states (it was the negative prediction itself, -2 here;
    `decode` was not affected: its valid mask sets every invalid column to -1)."""
    col = np.array([[5, 0, 0]], np.int32)
    conf = np.array([[0.1, 1.0, 1.0]], np.float32)
    for columns in (None, 10):
        got_col, got_valid = confidence_median(col, conf, np.ones((1, 3), bool), t_low=0.5, t_high=0.9, window=5,
                                               min_votes=2, fill=True, columns=columns)
        assert got_col.tolist() == [[-1, 0, 0]] and got_valid.tolist() == [[False, True, True]]


# ----------------------------------------------------------------------- order_prior

def _same_surface(x1, c1, x2, c2, stripe, max_slope, tol):
    return abs((x1 - c1 * stripe) - (x2 - c2 * stripe)) <= Fraction(max_slope) * abs(x2 - x1) + Fraction(tol)


def _order_reference(cand, conf, ok, *, t_high, t_low, max_gap, max_slope, tol, stripe):
    h, w, k = cand.shape
    conf = conf.astype(np.float64)                         # thresholds compare exact values
    out_col = cand[..., 0].copy()
    out_valid = np.zeros((h, w), bool)
    for y in range(h):
        c0 = [int(v) for v in cand[y, :, 0]]
        high = [bool(ok[y, x] and conf[y, x] >= t_high and c0[x] >= 0) for x in range(w)]
        anchor = [False] * w
        for x in range(w):
            if not high[x]:
                continue
            left = [x2 for x2 in range(x) if high[x2]]
            right = [x2 for x2 in range(x + 1, w) if high[x2]]
            for x2 in ([left[-1]] if left else []) + ([right[0]] if right else []):
                if abs(x2 - x) <= max_gap and _same_surface(x, c0[x], x2, c0[x2], stripe, max_slope, tol):
                    anchor[x] = True
        for x in range(w):
            if not ok[y, x] or c0[x] < 0:
                continue
            if conf[y, x] >= t_high:
                out_valid[y, x] = True
                continue
            lefts = [x2 for x2 in range(x) if anchor[x2]]
            rights = [x2 for x2 in range(x + 1, w) if anchor[x2]]
            if lefts and rights and x - lefts[-1] <= max_gap and rights[0] - x <= max_gap:
                lx, rx = lefts[-1], rights[0]
                cl, cr = c0[lx], c0[rx]
                if cl <= cr and _same_surface(lx, cl, rx, cr, stripe, max_slope, tol):
                    interp = cl + Fraction((cr - cl) * (x - lx), rx - lx)
                    chosen = next((int(c) for c in cand[y, x] if c >= 0 and cl <= c <= cr
                                   and abs(int(c) - interp) * stripe <= tol), -1)
                    if chosen >= 0:
                        out_col[y, x], out_valid[y, x] = chosen, True
                    continue
            out_valid[y, x] = bool(conf[y, x] >= t_low)
    return out_col, out_valid


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("stripe, max_slope, tol, max_gap", [(1, 0.5, 2.0, 32), (1, 0.25, 1.0, 3), (3, 0.5, 3.0, 4),
                                                             (1, 0.0, 0.0, 1)])
def test_order_prior_matches_the_naive_list_decoder(shape, stripe, max_slope, tol, max_gap):
    """Anchors (high-confidence pixels agreeing with the nearest other high-confidence pixel on
    either side within max_gap), the surface test between the nearest anchors, the interpolated
    candidate within tol / stripe and the low-confidence rule, exactly."""
    rng = np.random.default_rng([*shape, stripe, max_gap])
    h, w = shape
    for _ in range(8):
        base = (np.arange(w)[None, :] // stripe + rng.integers(0, 2, (h, 1)) * 5).astype(np.int64)
        base = np.broadcast_to(base, shape) + rng.integers(-1, 2, shape) * (rng.random(shape) < 0.3)
        jump = rng.random(shape) < 0.1                    # a few wrong top-1 columns
        c0 = np.where(jump, base + rng.integers(-20, 21, shape), base)
        cand = np.stack([c0, base, base + rng.integers(-2, 3, shape)], axis=2)
        cand[rng.random(cand.shape) < 0.15] = -1
        cand = cand.clip(-1, None).astype(np.int32)
        conf = rng.choice(np.array([0.1, 0.3, 0.5, 0.75, 0.8, 0.9, 0.95], np.float32), shape)
        ok = rng.random(shape) < 0.9
        kw = dict(t_high=0.75 if _ % 2 else 0.8, t_low=0.5 if _ % 2 else 0.3, max_gap=max_gap, max_slope=max_slope, tol=tol, stripe=stripe)
        got_col, got_valid = order_prior(cand, conf, ok, **kw)
        ref_col, ref_valid = _order_reference(cand, conf, ok, **kw)
        assert np.array_equal(got_valid, ref_valid)
        assert np.array_equal(got_col, ref_col)


# ----------------------------------------------------------------------- spatial_outliers

def _outlier_reference(col, valid, window, tol):
    h, w = col.shape
    r = window // 2
    out = np.zeros((h, w), bool)
    for y in range(h):
        for x in range(w):
            if not valid[y, x]:
                continue
            vals = sorted(int(col[y2, x2]) for y2 in range(max(0, y - r), min(h, y + r + 1))
                          for x2 in range(max(0, x - r), min(w, x + r + 1)) if valid[y2, x2])
            m = len(vals)
            med = vals[m // 2] if m % 2 else (vals[m // 2 - 1] + vals[m // 2]) // 2   # rounded down
            out[y, x] = abs(int(col[y, x]) - med) > tol
    return out


@pytest.mark.parametrize("shape", SHAPES)
def test_spatial_outliers_match_the_naive_window_median(shape):
    """Valid columns against the floor-rounded median of the valid window (itself included; even
    counts at borders and with invalid neighbours), negative columns included, exactly."""
    rng = np.random.default_rng(sum(shape))
    for window, tol in [(1, 0), (3, 0), (3, 2), (7, 2), (5, 1)]:
        col = (np.arange(shape[1])[None, :] + rng.integers(-3, 4, shape)).astype(np.int32)
        col[rng.random(shape) < 0.1] -= 40                # outliers, some negative
        valid = rng.random(shape) < 0.7
        assert np.array_equal(spatial_outliers(col, valid, window=window, tol=tol),
                              _outlier_reference(col, valid, window, tol)), (window, tol)
