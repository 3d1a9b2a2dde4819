"""Exactness of method "sgm"'s decision and unaries (`edge.decode.sgm`), against naive references
written here from the module docstring (tests/test_decode_sgm.py checks the path costs and the
aggregation; this file what is computed from them):

* `regularise`'s decision from the aggregated costs S (`aggregate`, the same passes): the best
  candidate state (ties to the better-ranked, absent candidates never), the candidates
  re-ordered by S with their distances, the costs ``S - min S``, the none flag, the error
  ``E = sum_far exp(-(S_j - S_b)) / sum_j exp(-(S_j - S_b))`` and validity ``S_b <= S_none and E
  < max_error``; on random problems with duplicated candidates (exact ties), absent ones, pixels
  with no candidate, images of 1 x 1, 1 x 7 and 5 x 3;
* `posterior_unaries`: ``(L_k - L_1) / 2``, BIG where absent, and the none state's ``-log e0 +
  log N`` with e0 recovered from the published error, checked against e0 chosen first;
* `surface_steps`: the lower median of the neighbours' column differences (|d| <= STEP_SPAN),
  defaults below MIN_STEP_VOTES pairs.

Tolerances: S and the unaries are float32, so values derived from them are compared to float32
rounding (rtol 1e-5); the error's exp(-60) cut of the kernel adds at most 1e-26 absolute.
Orders, flags and columns are compared exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from edge.decode.sgm import (BIG, MIN_STEP_VOTES, NONE_CLIP, STEP_SPAN, aggregate, penalties, posterior_unaries,
                             regularise, surface_steps)


def _problem(h, w, seed):
    rng = np.random.default_rng(seed)
    cand = (np.arange(w)[None, :, None] + rng.integers(-3, 4, (h, w, 3)) + 4).astype(np.int32)
    dup = rng.random((h, w)) < 0.25
    cand[..., 1][dup] = cand[..., 0][dup]             # a duplicated candidate: its S ties exactly
    unary = np.concatenate([rng.integers(0, 8, (h, w, 3)) * 0.5, rng.uniform(-3, 12, (h, w, 1))], axis=2)
    unary[..., 1][dup] = unary[..., 0][dup]
    absent = rng.random((h, w, 3)) < 0.2
    cand[absent] = -1
    unary[..., :3][absent] = np.inf
    none_only = rng.random((h, w)) < 0.1             # no candidate at all
    cand[none_only] = -1
    unary[..., :3][none_only] = np.inf
    return cand, unary.astype(np.float32)


def _decide_reference(cand, dist, total, max_error):
    h, w, kk = cand.shape
    col = np.full((h, w), -1, np.int32)
    valid = np.zeros((h, w), bool)
    err = np.ones((h, w))
    none = np.zeros((h, w), bool)
    ocand = np.empty_like(cand)
    odist = np.empty_like(dist)
    ocost = np.empty(total.shape)
    for y in range(h):
        for x in range(w):
            s = [float(v) for v in total[y, x]]
            s = [BIG if k < kk and cand[y, x, k] < 0 else s[k] for k in range(kk)] + [s[kk]]
            order = sorted(range(kk), key=lambda k: (s[k], k))   # ties: the better-ranked first
            b, sn = order[0], s[kk]
            present = [k for k in range(kk) if cand[y, x, k] >= 0]
            smin = min([s[k] for k in present] + [sn])
            ocand[y, x] = cand[y, x, order]
            odist[y, x] = dist[y, x, order]
            ocost[y, x] = [s[k] - smin for k in order] + [sn - smin]
            if not present:
                none[y, x] = True
                continue
            cb = int(cand[y, x, b])
            terms = [(math.exp(-(s[j] - s[b])), abs(int(cand[y, x, j]) - cb) > 1) for j in present]
            terms.append((math.exp(-(sn - s[b])), True))
            err[y, x] = sum(e for e, far in terms if far) / sum(e for e, _ in terms)
            none[y, x] = sn < s[b]
            valid[y, x] = not none[y, x] and err[y, x] < max_error
            col[y, x] = cb if valid[y, x] else -1
    return col, valid, err, none, ocand, odist, ocost


@pytest.mark.parametrize("shape, seed", [((1, 1), 0), ((1, 1), 1), ((1, 7), 2), ((5, 3), 3), ((4, 9), 4)])
@pytest.mark.parametrize("max_error", [0.01, 0.3])
def test_decision_matches_the_naive_rule_on_the_aggregated_costs(shape, seed, max_error):
    prior = penalties(64)
    for trial in range(4):
        cand, unary = _problem(*shape, seed=100 * seed + trial)
        dist = np.where(np.isfinite(unary[..., :3]), 2 * unary[..., :3] + 7.0, np.inf).astype(np.float32)
        total = aggregate(cand, unary, prior=prior)
        got = regularise(cand, unary, max_error=max_error, prior=prior, distances=dist)
        col, valid, err, none, ocand, odist, ocost = _decide_reference(cand, dist, total, max_error)
        assert np.array_equal(got.candidates, ocand) and np.array_equal(got.distances, odist)
        assert np.array_equal(got.none, none) and np.array_equal(got.valid, valid)
        assert np.array_equal(got.column, col)
        np.testing.assert_allclose(got.error, err, rtol=1e-5, atol=1e-25)
        finite = ocost < BIG / 4
        assert np.array_equal(got.costs < BIG / 4, finite)
        np.testing.assert_allclose(got.costs[finite], ocost[finite], rtol=1e-5, atol=1e-4)
        assert (got.column >= 0).tolist() == got.valid.tolist()


def test_exact_ties_go_to_the_better_ranked_candidate():
    """Two candidates with equal costs everywhere on a 1-pixel image: the first-ranked is chosen,
    the order kept; a far twin at equal cost makes E = 1/2 + the none share."""
    cand = np.array([[[10, 40, -1]]], np.int32)
    unary = np.array([[[0.0, 0.0, np.inf, 5.0]]], np.float32)
    got = regularise(cand, unary, max_error=0.01, prior=penalties(64))
    assert got.candidates[0, 0].tolist() == [10, 40, -1]
    total = aggregate(cand, unary, prior=penalties(64))[0, 0]   # one pixel: S = U + W (W = log N on columns)
    assert total[0] == total[1] == pytest.approx(math.log(64))
    s_none = float(total[3] - total[0])
    want = (1.0 + math.exp(-s_none)) / (2.0 + math.exp(-s_none))
    assert got.error[0, 0] == pytest.approx(want, rel=1e-6) and not got.valid[0, 0] and got.column[0, 0] == -1


# ----------------------------------------------------------------------- posterior_unaries

def test_posterior_unaries_recover_the_not_lit_odds():
    """For chosen likelihoods L_k and not-lit odds e0, the published error E = (far + e0) / (1 +
    every + e0) (`edge.decode.posterior`'s rule, far: rows more than one from the best) gives back
    U_k = (L_k - L_1) / 2 and U_none = -log(e0) + log N (clipped to +-NONE_CLIP before log N);
    absent candidates and a pixel without a best candidate as documented; a 4th, unscored state
    gets its unary but stays out of e0."""
    rng = np.random.default_rng(7)
    n_pix, choices = 400, 1024
    cand = rng.integers(0, 50, (n_pix, 4)).astype(np.int32)
    cand[::7, 1] = cand[::7, 0] + 1                    # near rows (not far)
    l1 = rng.uniform(0, 100, n_pix)
    dist = np.c_[l1, l1[:, None] + np.sort(rng.uniform(0, 20, (n_pix, 3)), axis=1)]
    dist[::11, 2] = np.inf                             # absent by distance
    cand[::13, 1] = -1                                 # absent by row
    log_e0 = rng.uniform(-6, 2, n_pix)
    log_e0[::17] = -200.0                              # beyond the clip
    cand[::34, 1:3] = cand[::34, :1] + 1               # ... on pixels without a far state too
    err = np.empty(n_pix)
    far_of = np.empty(n_pix)
    for p in range(n_pix):
        every = far = 0.0
        for j in (1, 2):                               # the scored states
            if cand[p, j] >= 0 and np.isfinite(dist[p, j]):
                e = math.exp(-(dist[p, j] - dist[p, 0]) / 2)
                every += e
                far += e if abs(int(cand[p, j]) - int(cand[p, 0])) > 1 else 0.0
        e0 = math.exp(log_e0[p])
        err[p] = (far + e0) / (1 + every + e0)
        far_of[p] = far
    cand[5, 0] = -1                                    # no best candidate
    dist[6, 0] = np.inf
    got = posterior_unaries(cand.reshape(1, n_pix, 4), dist.reshape(1, n_pix, 4).astype(np.float32),
                            err.reshape(1, n_pix).astype(np.float32), choices=choices, scored=3)[0]
    checked = clipped = 0
    for p in range(n_pix):
        if p in (5, 6):
            assert got[p, :4].tolist() == [float(BIG)] * 4 and got[p, 4] == 0.0
            continue
        for j in range(4):
            if cand[p, j] < 0 or not np.isfinite(dist[p, j]):
                assert got[p, j] == BIG
            else:
                assert got[p, j] == pytest.approx((np.float32(dist[p, j]) - np.float32(dist[p, 0])) / 2,
                                                  rel=1e-5, abs=1e-4)
        want = min(max(-log_e0[p], -NONE_CLIP), NONE_CLIP) + math.log(choices)
        # e0 comes back through a float32 error: its relative precision is about 6e-8 / share,
        # share = e0 / (far + e0) its part of E, large only where e0 is a sliver of E; where the
        # share is above 1 % that is under 1e-5 nats, and 1e-3 leaves room for the clip's edges
        share = math.exp(log_e0[p]) / (far_of[p] + math.exp(log_e0[p]))
        # (an e0 below float32's resolution of E reads as what that resolution leaves, unless
        # no far state shares E: then E underflows to 0 and the clip applies)
        if share > 1e-2 or (log_e0[p] < -NONE_CLIP and far_of[p] == 0.0):
            checked += 1
            clipped += log_e0[p] < -NONE_CLIP
            assert got[p, 4] == pytest.approx(want, abs=1e-3), p
    assert checked > 300 and clipped >= 1, (checked, clipped)


# ----------------------------------------------------------------------- surface_steps

def _steps_reference(col, ok, stripe):
    h, w = col.shape
    out = []
    for (dy, dx), default in (((0, 1), 1.0 / stripe), ((1, 0), 0.0)):
        diffs = sorted(int(col[y + dy, x + dx]) - int(col[y, x]) for y in range(h - dy) for x in range(w - dx)
                       if ok[y, x] and ok[y + dy, x + dx] and col[y, x] >= 0 and col[y + dy, x + dx] >= 0
                       and abs(int(col[y + dy, x + dx]) - int(col[y, x])) <= STEP_SPAN)
        out.append(float(diffs[(len(diffs) - 1) // 2]) if len(diffs) >= MIN_STEP_VOTES else default)
    return tuple(out)


@pytest.mark.parametrize("shape, seed, stripe", [((1, 1), 0, 1), ((1, 300), 1, 2), ((20, 21), 2, 1), ((30, 30), 3, 3),
                                                 ((15, 14), 4, 1)])
def test_surface_steps_are_the_lower_medians_of_neighbour_differences(shape, seed, stripe):
    """Even vote counts (lower median), depth edges beyond STEP_SPAN, pixels without a column,
    the MIN_STEP_VOTES boundary (15 x 14 pixels: 195 horizontal pairs, 196 vertical ones at
    most)."""
    rng = np.random.default_rng(seed)
    h, w = shape
    col = (np.arange(w)[None, :] * rng.integers(1, 3) + np.arange(h)[:, None] * rng.integers(0, 2)
           + rng.integers(-1, 2, shape)).astype(np.int64)
    col[rng.random(shape) < 0.05] += 200               # depth edges
    col[rng.random(shape) < 0.05] = -1
    ok = rng.random(shape) < (0.9 if seed != 4 else 1.0)
    assert surface_steps(col, ok, stripe=stripe) == _steps_reference(col, ok, stripe)
