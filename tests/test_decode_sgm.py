"""Method "sgm" (`edge.decode.sgm`): semi-global regularisation of the top-3 candidates.

Exactness: each directional path cost against a naive numpy implementation of the recurrence of
the module docstring, and the aggregated costs against the min-marginals of the energy over all
labellings of each pixel's row + column cross (brute force on 1 x 5 and 2 x 3 images).  A pixel
without neighbours gets exactly the posterior's error.  Behaviour, with `decode`'s defaults on
`edge.sim` and the independent `_plane_box_sphere` renderer (invalid pixels counted as errors):
sgm cuts soft's error rate by a clear factor, and the published pixels stay within the error
target.  Wiring: the settings, the "confidence" rule and the profile's method list.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from _plane_box_sphere import render, scene as pbs_scene
from edge.codes import get_code
from edge.decode import DecodeSettings, decode
from edge.decode.settings import METHODS
from edge.decode.sgm import (BIG, DIRECTIONS, aggregate, from_posterior, path_costs, penalties, posterior_unaries,
                             regularise, surface_steps)
from edge.decode.spatial import spatial_stage
from edge.sim import CameraModel, capture_code
from edge.sim.metrics import truth
from edge.sim.scenes import make_scene

ECC = get_code("ecc-22-10")


# -------------------------------------------------------------------------- references

def _v(prior, cand, steps, a, b, ka, kb):
    """V(ka -> kb) between pixel a = (y, x) (previous) and pixel b, from the module docstring."""
    kk = cand.shape[2]
    if ka == kk:
        return prior.none_none if kb == kk else prior.none_col
    if kb == kk:
        return prior.col_none
    da = a[1] * steps[0] + a[0] * steps[1] - cand[a[0], a[1], ka]   # disparity in rows
    db = b[1] * steps[0] + b[0] * steps[1] - cand[b[0], b[1], kb]
    u = abs(da - db)
    return 0.0 if u <= 1 else (prior.p1 if u <= 2 else prior.p2)


def _w(prior, k, kk):
    return prior.col_prior if k < kk else 0.0


def _naive_path(cand, unary, prior, steps, direction):
    """The recurrence L_r of the module docstring, written out pixel by pixel."""
    h, w, ns = unary.shape
    dy, dx = DIRECTIONS[direction]
    out = np.zeros((h, w, ns))
    ys = range(h) if dy >= 0 else range(h - 1, -1, -1)
    xs = range(w) if dx >= 0 else range(w - 1, -1, -1)
    for y in ys:
        for x in xs:
            yp, xp = y - dy, x - dx
            if not (0 <= yp < h and 0 <= xp < w):
                out[y, x] = [unary[y, x, k] + _w(prior, k, ns - 1) for k in range(ns)]
                continue
            prev = out[yp, xp]
            for k in range(ns):
                best = min(prev[j] + _v(prior, cand, steps, (yp, xp), (y, x), j, k) for j in range(ns))
                out[y, x, k] = unary[y, x, k] + best - prev.min()
    return out


def _cross_min_marginals(cand, unary, prior, steps, y0, x0):
    """min over all labellings of pixel (y0, x0)'s row + column of W(x_p) + sum U + sum V over the
    cross's edges oriented away from the pixel, for each state of the pixel."""
    h, w, ns = unary.shape
    arms = [[(y0, x) for x in range(x0 - 1, -1, -1)], [(y0, x) for x in range(x0 + 1, w)],
            [(y, x0) for y in range(y0 - 1, -1, -1)], [(y, x0) for y in range(y0 + 1, h)]]
    pixels = [p for arm in arms for p in arm]
    best = np.full(ns, np.inf)
    for k in range(ns):
        for labels in itertools.product(range(ns), repeat=len(pixels)):
            lab = dict(zip(pixels, labels))
            lab[(y0, x0)] = k
            e = _w(prior, k, ns - 1) + sum(unary[p][lab[p]] for p in lab)
            for arm in arms:
                prev = (y0, x0)
                for p in arm:
                    e += _v(prior, cand, steps, prev, p, lab[prev], lab[p])
                    prev = p
            best[k] = min(best[k], e)
    return best


def _random_problem(h, w, seed, *, steps=(1.0, 0.0)):
    """Candidates near a ramp (transitions of every kind: 0, P1, P2, none), some absent."""
    rng = np.random.default_rng(seed)
    ramp = np.arange(w)[None, :, None] * steps[0] + np.arange(h)[:, None, None] * steps[1]
    cand = (np.round(ramp) + rng.integers(-3, 4, (h, w, 3))).astype(np.int32) + 5
    unary = np.concatenate([rng.uniform(0, 6, (h, w, 3)), rng.uniform(-3, 12, (h, w, 1))], axis=2)
    unary[..., 0] = 0.0
    absent = rng.random((h, w)) < 0.2
    cand[..., 2][absent] = -1
    unary[..., 2][absent] = np.inf
    return cand, unary.astype(np.float32)


@pytest.mark.parametrize("steps", [(1.0, 0.0), (0.5, 0.0), (4.8, 0.4)])
@pytest.mark.parametrize("direction", list(DIRECTIONS))
def test_path_costs_match_the_naive_recurrence(direction, steps):
    cand, unary = _random_problem(4, 5, seed=int(10 * steps[0]), steps=steps)
    prior = penalties(64)
    got = path_costs(cand, unary, direction=direction, prior=prior, steps=steps)
    ref = _naive_path(cand, np.minimum(unary, BIG).astype(np.float64), prior, steps, direction)
    present = np.isfinite(unary)
    np.testing.assert_allclose(got[present], ref[present], rtol=1e-5, atol=1e-4)
    assert (got[~present] >= BIG).all()


@pytest.mark.parametrize("shape, seed", [((1, 5), 0), ((1, 5), 1), ((2, 3), 2), ((2, 3), 3)])
def test_aggregated_costs_are_the_cross_min_marginals(shape, seed):
    h, w = shape
    cand, unary = _random_problem(h, w, seed)
    prior = penalties(100)
    total = aggregate(cand, unary, prior=prior)
    u = np.minimum(unary, BIG).astype(np.float64)
    for y in range(h):
        for x in range(w):
            ref = _cross_min_marginals(cand, u, prior, (1.0, 0.0), y, x)
            present = np.isfinite(unary[y, x])
            got = total[y, x][present] - total[y, x][present].min()
            np.testing.assert_allclose(got, ref[present] - ref[present].min(), rtol=1e-5, atol=1e-3)


def test_aggregate_is_the_sum_of_the_paths_minus_three_unaries():
    cand, unary = _random_problem(6, 7, seed=5)
    prior = penalties(1024)
    paths = sum(path_costs(cand, unary, direction=d, prior=prior).astype(np.float64) for d in DIRECTIONS)
    u = np.minimum(unary, BIG).astype(np.float64)
    w = np.r_[np.full(3, prior.col_prior), 0.0]
    present = np.isfinite(unary)
    np.testing.assert_allclose(aggregate(cand, unary, prior=prior)[present], (paths - 3 * (u + w))[present],
                               rtol=1e-5, atol=1e-3)


def test_penalties_are_the_log_ratios_of_the_prior():
    p = penalties(1024)
    assert p.p1 == pytest.approx(np.log(6.0))                     # 2 (1 - 0.1) / (3 * 0.1)
    assert p.p2 == pytest.approx(np.log(0.98 * 0.9 / 3 / (0.02 / 2048)))
    assert p.col_none == pytest.approx(p.p2 - np.log(1024)) and p.none_col == p.p2
    assert p.none_none < 0 < p.p1 < p.col_none < p.p2
    assert penalties(112).p2 < p.p2  # a disparity band: fewer columns to jump to
    with pytest.raises(ValueError, match="choices"):
        penalties(0)


def test_a_pixel_alone_gets_the_posterior_error():
    """No neighbours: the regularised error equals the posterior's P(wrong) (built here as
    `edge.decode.posterior` does, from the likelihoods and a not-lit odds e0), for every kind of
    pixel."""
    cases = [([10, 11, 300], [0.0, 3.0, 6.0], 1e-3), ([10, 400, 300], [0.0, 1.0, 2.0], 0.5),
             ([10, 400, -1], [0.0, 0.5, np.inf], 20.0), ([7, 8, 9], [0.0, 0.1, 0.2], 1e-4),
             ([7, 8, 9], [0.0, 30.0, 40.0], 1e-9)]
    for rows, dist, e0 in cases:
        ek = np.exp(-(np.array(dist[1:]) - dist[0]) / 2)
        far = sum(e for r, e in zip(rows[1:], ek) if r >= 0 and abs(r - rows[0]) > 1)
        err = (far + e0) / (1 + ek.sum() + e0)
        cand = np.array(rows, np.int32).reshape(1, 1, 3)
        d = np.array(dist, np.float32).reshape(1, 1, 3)
        out = from_posterior(cand, d, np.array([[err]], np.float32), choices=1024, stripe=1, max_error=0.01)
        assert out.error[0, 0] == pytest.approx(err, rel=1e-3), (rows, dist, e0)
        assert out.valid[0, 0] == (err < 0.01)


def test_neighbours_correct_a_pixel_and_invalidate_what_nothing_supports():
    """A fronto-parallel row (disparity 0: column = x); pixel 4's best is far, its second right;
    pixel 8 has nothing near (every candidate pays two depth edges: it stays invalid);
    everything else is confident."""
    w = 12
    x = np.arange(w)
    cand = np.stack([x + 0, x + 200, x + 400], -1)[None].astype(np.int32)
    dist = np.tile(np.array([0.0, 20.0, 30.0], np.float32), (1, w, 1))
    err = np.full((1, w), 1e-6, np.float32)
    cand[0, 4] = [500, 4, 700]
    dist[0, 4] = [0.0, 4.0, 8.0]      # alone: the second is e^-2 behind
    err[0, 4] = 0.12
    cand[0, 8] = [300, 600, 900]
    dist[0, 8] = [0.0, 1.0, 2.0]
    err[0, 8] = 0.6
    out = from_posterior(cand, dist, err, choices=1024, stripe=1, max_error=0.01)
    assert out.valid[0, 4] and out.column[0, 4] == 4 and out.candidates[0, 4, 0] == 4
    assert out.error[0, 4] < 0.01
    assert not out.valid[0, 8] and out.column[0, 8] == -1 and out.error[0, 8] > 0.5
    others = np.r_[0:4, 5:8, 9:w]
    assert out.valid[0, others].all() and (out.column[0, others] == others).all()


def test_surface_steps_are_measured_from_confident_neighbours():
    """A camera that samples the projector 4.8x coarser, on a plane tilted along y; a few wrong
    pixels do not move the medians; too few votes fall back to the disparity convention."""
    h, w = 40, 50
    y, x = np.mgrid[0:h, 0:w]
    col = np.round(4.8 * x + 0.4 * y + 10).astype(np.int32)
    ok = np.ones((h, w), bool)
    noisy = col.copy()
    noisy[::7, ::5] = 900
    sx, sy = surface_steps(noisy, ok, stripe=1)
    assert sx in (4.0, 5.0) and sy in (0.0, 1.0)  # medians of integer steps (4.8 and 0.4 on average)
    assert surface_steps(col, np.zeros((h, w), bool), stripe=2) == (0.5, 0.0)
    # the steps make a correct 4.8x ramp cost-free: no candidate state pays a transition
    cand = np.stack([col, col + 300, col + 600], -1)
    unary = np.zeros((h, w, 4), np.float32)
    unary[..., 1:3] = 5.0
    unary[..., 3] = 30.0
    reg = regularise(cand, unary, max_error=0.01, prior=penalties(1024), steps=(sx, sy))
    assert reg.valid.all() and (reg.column == col).all()
    naive = regularise(cand, unary, max_error=0.01, prior=penalties(1024))
    assert naive.costs[..., 3].mean() < reg.costs[..., 3].mean()  # without: every pair is a "depth edge"


def test_regularise_validates_its_inputs():
    cand, unary = _random_problem(2, 3, seed=0)
    prior = penalties(10)
    with pytest.raises(ValueError, match="unary"):
        regularise(cand, unary[..., :3], max_error=0.01, prior=prior)
    with pytest.raises(ValueError, match="max_error"):
        regularise(cand, unary, max_error=1.5, prior=prior)
    with pytest.raises(ValueError, match="steps"):
        regularise(cand, unary, max_error=0.01, prior=prior, steps=(np.nan, 0.0))
    with pytest.raises(ValueError, match="direction"):
        path_costs(cand, unary, direction="diagonal", prior=prior)
    with pytest.raises(ValueError, match="choices"):
        posterior_unaries(cand, unary[..., :3], unary[..., 0], choices=0)


# ------------------------------------------------------------------------ behaviour, defaults

def _sim(ratio: float, seed: int = 0):
    scene = make_scene("flying", 160, 120, seed=seed)
    a = 0.8 * ratio / (1 + ratio)
    cam = CameraModel(bits=12, sigma_r=0.002, sigma_s=0.04, ambient=a, projector=0.8 - a)
    cap = capture_code(scene, ECC, cam, rng=np.random.default_rng([seed, 7]))
    col, lit = truth(scene)
    return cap.frames, cap.white, cap.black, col, lit


def _pbs(ratio: float, seed: int = 3):
    col, albedo = pbs_scene(160, 120, seed=seed)
    f, w, b = render(ECC.codebook, col, albedo, ambient=0.12 * ratio, projector=0.12, bits=12, seed=seed + 1)
    return f, w, b, col, np.ones(col.shape, bool)


def _rates(gen, ratio):
    """{method: (error rate (wrong or invalid over lit pixels), off-by->1 rate among valid lit
    pixels)} and the share of lit pixels whose column is not within one row of any top-3 candidate."""
    f, w, b, col, lit = gen(ratio)
    out = {}
    for method in ("soft", "sgm"):
        d = decode(f, w, b, ECC, bit_depth=12, method=method)
        err = (((d.column != col) | ~d.valid) & lit).sum() / lit.sum()
        far = ((np.abs(d.column - col) > 1) & d.valid & lit).sum() / max((d.valid & lit).sum(), 1)
        out[method] = (float(err), float(far))
        if method == "soft":
            reach = (np.abs(d.candidates - col[..., None]) <= 1).any(-1)
            out["unreachable"] = float((~reach & lit).sum() / lit.sum())
    return out


# measured (160 x 120, one seed): soft -> sgm error rate; off-by->1 among valid pixels of sgm
#   edge.sim ambient 1: 8.21 % -> 0.93 % (8.8x), 0.06 %;  ambient 2: 22.0 % -> 13.5 %, 0.10 %
#     (8.8 % of its lit pixels have no top-3 candidate within one row: 13.2 -> 4.7 points above that)
#   (figures before candidate propagation, `edge.decode.propagate`; the test prints today's)
#   plane-box-sphere ambient 1: 2.13 % -> 0.18 % (11.8x), 0.02 %;  ambient 2: 16.6 % -> 1.91 % (8.7x), 0.08 %
#   (ambient 1.25 since the posterior's tail term: soft errs on just under 2 % at ambient 1)
@pytest.mark.parametrize("gen, ratio, factor", [(_sim, 1.0, 4.0), (_pbs, 1.25, 4.0), (_pbs, 2.0, 3.0)])
def test_sgm_cuts_soft_errors_with_defaults(gen, ratio, factor):
    r = _rates(gen, ratio)
    (soft, _), (sgm, sgm_far) = r["soft"], r["sgm"]
    print(f"{gen.__name__} ambient {ratio}: soft {soft:.4f}, sgm {sgm:.4f} ({soft / sgm:.1f}x), far {sgm_far:.4f}")
    assert 0.02 <= soft <= 0.3   # the regime of the claim
    assert sgm * factor <= soft
    assert sgm_far <= 0.02       # the published pixels meet the 1 % target within 2x


def test_sgm_goes_below_the_floor_of_its_top_three_where_many_are_missing():
    """edge.sim at ambient 2: many lit pixels have no top-3 candidate within one row of the truth;
    with the neighbours' columns as one more state (`edge.decode.propagate`) sgm errs on fewer
    pixels than that floor, and cuts soft's error rate by a clear factor."""
    r = _rates(_sim, 2.0)
    (soft, _), (sgm, sgm_far), floor = r["soft"], r["sgm"], r["unreachable"]
    assert 0.02 <= soft <= 0.3 and floor >= 0.02
    assert sgm < floor and sgm * 4.0 <= soft
    assert sgm_far <= 0.02


# ----------------------------------------------------------------------------------- wiring

def test_sgm_is_a_method_everywhere():
    from edge.profiles.settings import decoder_methods

    assert "sgm" in METHODS and "sgm" in decoder_methods("columns")
    assert DecodeSettings(method="sgm").rule(False) == "error"


def test_sgm_under_the_confidence_rule_uses_the_search_distances():
    f, w, b, col, lit = _pbs(1.0)
    soft = decode(f, w, b, ECC, bit_depth=12, method="soft", validity="confidence", min_contrast=0.0,
                  min_confidence=0.0)
    d = decode(f, w, b, ECC, bit_depth=12, method="sgm", validity="confidence", min_contrast=0.0)
    assert d.error is None and d.valid.any()
    assert (d.column[d.valid] >= 0).all() and (d.column[~d.valid] == -1).all()
    far = (np.abs(d.column - col) > 1) & d.valid
    far_soft = (np.abs(soft.column - col) > 1) & soft.valid
    assert far.sum() < far_soft.sum()
    # the stage needs the distances
    s = DecodeSettings(method="sgm")
    z = np.zeros((2, 2, 3), np.int32)
    with pytest.raises(ValueError, match="distances"):
        spatial_stage(s, z, np.zeros((2, 2), np.float32), z[..., 0], np.ones((2, 2), bool), stripe=1)
