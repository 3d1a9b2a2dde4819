"""Candidate propagation: a confident neighbour's column proposed to an uncertain pixel (method "sgm").

The search keeps each pixel's three most likely codewords.  Where the noise is high the true
column is often none of them (at edge.sim's ambient = 2 x projector, 8.8 % of the lit pixels
have no candidate within one row of the truth), and no regularisation over those three can
recover it.  Its neighbours on the same surface usually did decode it, to within a row.
Propagation gives each uncertain pixel one more candidate state: the column of the surface its
neighbours lie on, scored with the pixel's own likelihood.  The spatial prior
(`edge.decode.sgm`) then decides whether that state, the top three or "none" wins.

Definitions.  A pixel is *confident* where its error probability is below ``max_error`` (the
decoder's one target), else *uncertain*.  Every pixel p carries a *track*: a codebook row t(p)
with its -2 log-posterior l(p) (`edge.decode.posterior`'s distance ``L``), and an *extra* candidate
e(p) with its l_e(p).

* Initially t(p) = the best candidate c1(p) with l(p) = L_1(p) where p is confident; elsewhere
  no track (l = inf) and no extra.
* Four sweeps, in this order: left to right along each row, right to left, top to bottom along
  each column, bottom to top.  Each visits the pixels in sweep order; at an uncertain pixel p
  whose previous pixel q (one step back along the sweep, inside the image) has a track c = t(q):

  - the proposals are the rows c - 1, c, c + 1 inside [0, rows); each is scored by its
    L at p: a top-3 candidate's posterior distance where it was scored, else
    `edge.decode.posterior`'s negative log-likelihood with levels refitted to that row plus the
    capture's level prior (`Noise.levels`), as the posterior's distances are;
  - the best proposal c* (least L; ties: the lower row) is *plausible* where
    ``(L(c*) - L_1(p)) / 2 <= bound``, with ``bound = 4 * P2`` (`edge.decode.sgm.penalties`): the
    most the smoothness prior can pay for a state, four neighbours each saving at most one
    depth-edge cost; beyond it no prior makes c* beat the best candidate;
  - if plausible and L(c*) < l(p): t(p) = c*, l(p) = L(c*) (the track moves on through p);
  - if plausible, c* is not one of p's scored top three (a finite distance) and L(c*) < l_e(p):
    e(p) = c*, l_e(p) = L(c*).

  Confident pixels keep their track and get no extra.  A track therefore runs from confident
  pixels through any stretch of uncertain ones for as long as the surface's column (to within a
  row per pixel, so slanted surfaces are followed) stays plausible at each pixel.

Output: candidates (H, W, 4) = the top three and e(p) (-1 where none), distances (H, W, 4)
their L (inf where absent).  Shapes: samples (m', H, W) raw frames (n code frames, with inverse
frames 2n), white / black (H, W); normalised units as `edge.decode.posterior`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..codes import Code
from .level_prior import cost_at, kernel_args
from .posterior import Noise, _nll, _pixel_samples, _samples, _xtab
from .sgm import penalties

#: Column-block width of the vertical sweeps (each thread runs whole blocks, rows in order).
_BLOCK = 32


class Propagated(NamedTuple):
    """Output of `propagate`: candidates (H, W, 4) int32 (the top three, then the extra
    candidate or -1), distances (H, W, 4) float32 (their L; inf where absent), extra (H, W) bool
    (where an extra candidate was added)."""

    candidates: np.ndarray
    distances: np.ndarray
    extra: np.ndarray


@njit(cache=True)
def _visit(frames, white, black, scale, xtab, cand, dist, a, beta, prior, bound, rows, y, x, c,
           track, track_l, extra, extra_l, buf, xs):
    """One visit of uncertain pixel (y, x) with its previous pixel's track c (module docstring)."""
    n = frames.shape[0]
    l1 = dist[y, x, 0]
    loaded = False
    best = -1
    best_l = np.inf
    for r in range(c - 1, c + 2):
        if r < 0 or r >= rows:
            continue
        lr = np.inf
        known = False
        for k in range(3):
            if cand[y, x, k] == r and np.isfinite(dist[y, x, k]):
                lr = dist[y, x, k]
                known = True
        if not known:
            if not loaded:
                _pixel_samples(frames, white, black, scale, y, x, buf)
                loaded = True
            lr, _, lc, lb = _nll(buf, xs, r, n, xtab, a, beta, True)
            if prior[6]:  # the level prior, as the posterior's distances include it
                lr += cost_at(prior[0], prior[1], prior[2], prior[3], prior[4], prior[5], lb, lc)
        if lr < best_l:
            best = r
            best_l = lr
    if best < 0 or 0.5 * (best_l - l1) > bound:
        return
    if best_l < track_l[y, x]:
        track[y, x] = best
        track_l[y, x] = best_l
    for k in range(3):
        if cand[y, x, k] == best and np.isfinite(dist[y, x, k]):
            return
    if best_l < extra_l[y, x]:
        extra[y, x] = best
        extra_l[y, x] = best_l


@njit(cache=True, parallel=True)
def _sweep_rows(frames, white, black, scale, xtab, cand, dist, uncertain, a, beta, prior, bound, rows, step,
                track, track_l, extra, extra_l):
    n = frames.shape[0]
    height, width = uncertain.shape
    for y in prange(height):
        buf = np.empty(n + 2, np.float64)
        xs = np.empty(n + 2, np.float64)
        for i in range(1, width):
            x = i if step > 0 else width - 1 - i
            q = x - step
            if uncertain[y, x] and cand[y, x, 0] >= 0 and track[y, q] >= 0:
                _visit(frames, white, black, scale, xtab, cand, dist, a, beta, prior, bound, rows, y, x, track[y, q],
                       track, track_l, extra, extra_l, buf, xs)


@njit(cache=True, parallel=True)
def _sweep_cols(frames, white, black, scale, xtab, cand, dist, uncertain, a, beta, prior, bound, rows, step,
                track, track_l, extra, extra_l):
    n = frames.shape[0]
    height, width = uncertain.shape
    blocks = (width + _BLOCK - 1) // _BLOCK
    for bx in prange(blocks):
        buf = np.empty(n + 2, np.float64)
        xs = np.empty(n + 2, np.float64)
        for i in range(1, height):
            y = i if step > 0 else height - 1 - i
            q = y - step
            for x in range(bx * _BLOCK, min(width, (bx + 1) * _BLOCK)):
                if uncertain[y, x] and cand[y, x, 0] >= 0 and track[q, x] >= 0:
                    _visit(frames, white, black, scale, xtab, cand, dist, a, beta, prior, bound, rows, y, x, track[q, x],
                           track, track_l, extra, extra_l, buf, xs)


def propagate(frames: np.ndarray, white: np.ndarray, black: np.ndarray, scale: float, code: Code,
              candidates: np.ndarray, distances: np.ndarray, error: np.ndarray, noise: Noise, *,
              max_error: float, choices: int, rows: int | None = None,
              inverse: np.ndarray | None = None) -> Propagated:
    """The four sweeps of the module docstring.

    frames (n, H, W), white / black (H, W), inverse (n, H, W) or None: the raw capture (`scale`
    to normalised units); candidates (H, W, 3) int32 / distances (H, W, 3) float32 / error (H, W)
    float32: `edge.decode.posterior.posterior`'s output with `noise`, its noise model;
    max_error: the confidence target in (0, 1); choices: N of the prior (`edge.decode.sgm`);
    rows: codebook rows in use (default ``code.size``).
    """
    if not 0 < max_error < 1:
        raise ValueError(f"max_error: expected a probability in (0, 1), got {max_error}")
    cand = np.ascontiguousarray(candidates, np.int32)
    h, w = np.shape(white)
    if cand.shape != (h, w, 3) or np.shape(distances) != cand.shape or np.shape(error) != (h, w):
        raise ValueError(f"propagate: expected candidates / distances (H, W, 3) and error (H, W) of a {h} x {w} "
                         f"capture, got {cand.shape}, {np.shape(distances)}, {np.shape(error)}")
    rows = code.size if rows is None else int(rows)
    dist = np.ascontiguousarray(distances, np.float32)
    err = np.asarray(error)
    confident = (err < max_error) & (cand[..., 0] >= 0)
    track = np.where(confident, cand[..., 0], -1).astype(np.int32)
    track_l = np.where(confident, dist[..., 0], np.inf).astype(np.float64)
    extra = np.full((h, w), -1, np.int32)
    extra_l = np.full((h, w), np.inf, np.float64)
    samples = _samples(frames, inverse)
    xtab = _xtab(code, inverse is not None)
    bound = 4.0 * penalties(choices).p2
    args = (samples, white, black, np.float64(scale), xtab, cand, dist, ~confident, float(noise.a),
            float(noise.beta), kernel_args(noise.levels), float(bound), rows)
    for sweep, step in ((_sweep_rows, 1), (_sweep_rows, -1), (_sweep_cols, 1), (_sweep_cols, -1)):
        sweep(*args, step, track, track_l, extra, extra_l)
    out_cand = np.concatenate([cand, extra[..., None]], axis=2)
    out_dist = np.concatenate([dist, np.where(extra >= 0, extra_l, np.inf).astype(np.float32)[..., None]], axis=2)
    return Propagated(out_cand, out_dist, extra >= 0)
