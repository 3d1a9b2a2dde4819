"""Spatial post-processing of decoded columns (paper section 3.2.4).

Disparity convention (docs/architecture.md): a pixel at camera column x decoded to codebook row c
(projector columns ``c * stripe .. c * stripe + stripe - 1``) has disparity ``x - c * stripe``
(projector pixels, stripe offset ignored).  Columns are codebook rows throughout.

* `order_prior`: list decoding with the order prior, along each image row (an epipolar line in
  the rectified setup).  *Anchors* are eligible pixels with confidence >= t_high whose disparity
  agrees (within ``max_slope * gap + tol`` projector pixels) with the nearest other such pixel
  (anchor or not) on its left or on its right at most `max_gap` pixels away; a high-confidence
  pixel that agrees with neither is kept as it is but does not anchor.  A pixel with confidence
  < t_high whose nearest anchors L (left) and R (right) are both at most `max_gap` pixels away
  and lie on one continuous surface (their disparities agree within ``max_slope * (x_R - x_L) +
  tol``, and col(L) <= col(R): with ``max_slope < 1`` the first implies it but for the slack
  `tol`) takes the best-ranked of its top-3 candidates
  c with ``col(L) <= c <= col(R)`` and ``|c - interp| <= tol / stripe``, where interp is the
  linear interpolation of the anchor columns at x (exact for a plane: disparity is affine in
  the image of a plane); if none of the three fits, it is invalid.  Every other pixel keeps
  its best candidate; below t_low it is invalid.  High-confidence pixels never change.
* `confidence_median`: median filter over a `window` x `window` patch in which only eligible
  pixels with confidence >= t_high vote (the pixel itself excluded).  Votes are disparities
  (``vote="disparity"``, the default: a surface slanted along the row has a constant column
  step, so a column median would be biased where the voters are unevenly spread) or columns
  (``vote="column"``).  A pixel with confidence < t_high and at least `min_votes` votes gets the
  prediction ``p = x - median`` (rounded, in rows) or ``p = median``: it takes its
  best-ranked candidate within `tol` rows of p (its own column when no `candidates` are given),
  else p itself (``fill=True``, the paper's filter, where p is a codebook row in use: ``0 <= p <
  columns``) or nothing: invalid (``fill=False``, the
  error rule's: a pixel is published only on its own data's support, so a shadow between lit
  neighbours stays a hole).  With fewer votes it keeps its column, valid iff confidence >= t_low.
  High-confidence pixels never change.
* `spatial_outliers`: the evaluation test for smooth scenes: a valid column differing by more
  than `tol` from the median of the valid columns in its `window` x `window` neighbourhood.
* `spatial_support`: whether a pixel's column agrees with the median of its high-confidence
  neighbours (used by `decode`'s valid mask; columns unchanged).

`spatial_stage` is stage 4 of `edge.decode.decode`: it runs the filters the settings' method asks
for on the candidate search's output, with the pattern's stripe width (method "sgm":
`edge.decode.sgm`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .kernels import sort_small as _sort_small
from .settings import DecodeSettings
from .sgm import from_search as sgm_from_search


@njit(cache=True)
def _nearest_marked(marked, prev_out, next_out):
    """For every x of a row: the nearest marked x strictly left (prev_out) and right (next_out), -1 if none."""
    width = marked.size
    last = -1
    for xx in range(width):
        prev_out[xx] = last
        if marked[xx]:
            last = xx
    last = -1
    for xx in range(width - 1, -1, -1):
        next_out[xx] = last
        if marked[xx]:
            last = xx


@njit(cache=True)
def _median_sorted(buf, m):
    _sort_small(buf, m)
    if m % 2 == 1:
        return buf[m // 2]
    return (buf[m // 2 - 1] + buf[m // 2]) // 2


@njit(cache=True)
def _median_float(buf, m):
    _sort_small(buf, m)
    if m % 2 == 1:
        return buf[m // 2]
    return 0.5 * (buf[m // 2 - 1] + buf[m // 2])


@njit(cache=True)
def _same_surface(x1, c1, x2, c2, stripe, max_slope, tol):
    d1 = x1 - c1 * stripe
    d2 = x2 - c2 * stripe
    return abs(d1 - d2) <= max_slope * abs(x2 - x1) + tol


@njit(cache=True, parallel=True)
def _order_prior(cand, conf, ok, t_high, t_low, max_gap, max_slope, tol, stripe, out_col, out_valid):
    height, width, k = cand.shape
    for yy in prange(height):
        high = np.zeros(width, np.bool_)
        anchor = np.zeros(width, np.bool_)
        prev_high = np.full(width, -1, np.int64)
        next_high = np.full(width, -1, np.int64)
        for xx in range(width):
            high[xx] = ok[yy, xx] and conf[yy, xx] >= t_high and cand[yy, xx, 0] >= 0
        _nearest_marked(high, prev_high, next_high)
        # anchors: high-confidence pixels that agree with a neighbouring high-confidence pixel
        for xx in range(width):
            if not high[xx]:
                continue
            c = cand[yy, xx, 0]
            for x2 in (prev_high[xx], next_high[xx]):
                if x2 >= 0 and abs(x2 - xx) <= max_gap and _same_surface(
                        xx, c, x2, cand[yy, x2, 0], stripe, max_slope, tol):
                    anchor[xx] = True
                    break
        left_x = np.full(width, -1, np.int64)
        right_x = np.full(width, -1, np.int64)
        _nearest_marked(anchor, left_x, right_x)
        for xx in range(width):
            c0 = cand[yy, xx, 0]
            out_col[yy, xx] = c0
            if not ok[yy, xx] or c0 < 0:
                out_valid[yy, xx] = False
                continue
            if conf[yy, xx] >= t_high:
                out_valid[yy, xx] = True
                continue
            lx = left_x[xx]
            rx = right_x[xx]
            if lx >= 0 and rx >= 0 and xx - lx <= max_gap and rx - xx <= max_gap:
                cl = cand[yy, lx, 0]
                cr = cand[yy, rx, 0]
                if cl <= cr and _same_surface(lx, cl, rx, cr, stripe, max_slope, tol):
                    interp = cl + (cr - cl) * (xx - lx) / (rx - lx)
                    chosen = -1
                    for j in range(k):
                        c = cand[yy, xx, j]
                        if c >= 0 and cl <= c and c <= cr and abs(c - interp) * stripe <= tol:
                            chosen = c
                            break
                    out_valid[yy, xx] = chosen >= 0
                    if chosen >= 0:
                        out_col[yy, xx] = chosen
                    continue
            out_valid[yy, xx] = conf[yy, xx] >= t_low


def order_prior(
    candidates: np.ndarray,
    confidence: np.ndarray,
    ok: np.ndarray,
    *,
    t_high: float,
    t_low: float,
    max_gap: int = 32,
    max_slope: float = 0.5,
    tol: float = 2.0,
    stripe: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Order-prior list decoding (see module docstring).

    candidates: (H, W, K) int32 codebook rows best-first (K >= 1, -1 = none); confidence: (H, W)
    float32; ok: (H, W) bool pixels eligible at all (contrast).  max_gap: farthest anchor (camera
    pixels); max_slope: largest disparity change per camera pixel on one surface; tol: slack in
    projector pixels for the surface test and the interpolation.  Returns column (H, W) int32
    (the best candidate where invalid) and valid (H, W) bool.
    """
    cand = np.asarray(candidates)
    if cand.ndim != 3 or cand.shape[2] < 1:
        raise ValueError(f"candidates: expected an (H, W, K) array, got shape {cand.shape}")
    h, w, _ = cand.shape
    for name, a in (("confidence", confidence), ("ok", ok)):
        if np.shape(a) != (h, w):
            raise ValueError(f"{name}: expected shape {(h, w)} to match candidates, got {np.shape(a)}")
    if max_gap < 1 or max_slope < 0 or tol < 0 or stripe < 1:
        raise ValueError(f"order_prior: expected max_gap >= 1, max_slope >= 0, tol >= 0, stripe >= 1, "
                         f"got {max_gap}, {max_slope}, {tol}, {stripe}")
    cand = np.ascontiguousarray(cand, dtype=np.int32)
    col = np.empty((h, w), np.int32)
    valid = np.empty((h, w), np.bool_)
    _order_prior(cand, np.ascontiguousarray(confidence, np.float32), np.ascontiguousarray(ok, np.bool_),
                 float(t_high), float(t_low), int(max_gap), float(max_slope), float(tol), int(stripe), col, valid)
    return col, valid


@njit(cache=True, parallel=True)
def _conf_median(col, conf, eligible, cand, t_low, t_high, radius, min_votes, tol, by_disparity, stripe, fill,
                 out_col, out_valid):
    height, width = col.shape
    k = cand.shape[2]
    for yy in prange(height):
        buf = np.empty((2 * radius + 1) ** 2, np.float64)
        for xx in range(width):
            c = col[yy, xx]
            out_col[yy, xx] = c
            if not eligible[yy, xx]:
                out_valid[yy, xx] = False
                continue
            cf = conf[yy, xx]
            if cf >= t_high and c >= 0:
                out_valid[yy, xx] = True
                continue
            m = 0
            for dy in range(-radius, radius + 1):
                y2 = yy + dy
                if y2 < 0 or y2 >= height:
                    continue
                for dx in range(-radius, radius + 1):
                    x2 = xx + dx
                    if x2 < 0 or x2 >= width or (dx == 0 and dy == 0):
                        continue
                    c2 = col[y2, x2]
                    if eligible[y2, x2] and conf[y2, x2] >= t_high and c2 >= 0:
                        buf[m] = (x2 - c2 * stripe) if by_disparity else c2
                        m += 1
            if m < min_votes:
                out_valid[yy, xx] = cf >= t_low and c >= 0
                continue
            med = _median_float(buf, m)
            pred = np.int64(np.round((xx - med) / stripe)) if by_disparity else np.int64(np.round(med))
            chosen = -1
            if k > 0:
                for j in range(k):
                    cj = cand[yy, xx, j]
                    if cj >= 0 and abs(cj - pred) <= tol:
                        chosen = cj
                        break
            elif c >= 0 and abs(c - pred) <= tol:
                chosen = c
            out_col[yy, xx] = chosen if chosen >= 0 else (pred if fill and pred >= 0 else -1)
            out_valid[yy, xx] = out_col[yy, xx] >= 0


def confidence_median(
    column: np.ndarray,
    confidence: np.ndarray,
    eligible: np.ndarray,
    *,
    t_low: float,
    t_high: float,
    window: int = 5,
    min_votes: int = 3,
    tol: int = 0,
    candidates: np.ndarray | None = None,
    vote: str = "disparity",
    stripe: int = 1,
    fill: bool = True,
    columns: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Confidence-based median filter (see module docstring; ``fill``: a pixel none of whose
    candidates is near the prediction takes the prediction (True) or is invalid (False)).

    column: (H, W) int32 codebook rows (-1 = none); confidence (H, W) float32; eligible (H, W)
    bool pixels that may vote or be filled; candidates: optional (H, W, K) int32 rows best-first;
    columns: the codebook rows in use (None: no upper bound): a prediction outside ``0 ..
    columns - 1`` is not filled (at the edge of the projector the neighbours' disparity
    predicted rows the code does not have).  Returns column (H, W) int32 (-1 where a
    prediction was not filled) and valid (H, W) bool.
    """
    if window < 1 or window % 2 == 0:
        raise ValueError(f"window: expected an odd size >= 1, got {window}")
    if vote not in ("disparity", "column"):
        raise ValueError(f"vote: expected 'disparity' or 'column', got {vote!r}")
    if stripe < 1 or tol < 0 or min_votes < 1:
        raise ValueError(f"confidence_median: expected stripe >= 1, tol >= 0, min_votes >= 1, got {stripe}, {tol}, {min_votes}")
    col = np.ascontiguousarray(column, dtype=np.int32)
    h, w = col.shape
    if candidates is None:
        cand = np.full((1, 1, 0), -1, np.int32)
    else:
        cand = np.ascontiguousarray(candidates, dtype=np.int32)
        if cand.ndim != 3 or cand.shape[:2] != (h, w):
            raise ValueError(f"candidates: expected shape ({h}, {w}, K), got {cand.shape}")
    for name, a in (("confidence", confidence), ("eligible", eligible)):
        if np.shape(a) != (h, w):
            raise ValueError(f"{name}: expected shape {(h, w)} to match column, got {np.shape(a)}")
    out_col = np.empty_like(col)
    out_valid = np.empty(col.shape, np.bool_)
    _conf_median(col, np.ascontiguousarray(confidence, np.float32), np.ascontiguousarray(eligible, np.bool_), cand,
                 float(t_low), float(t_high), window // 2, int(min_votes), int(tol), vote == "disparity", int(stripe),
                 bool(fill), out_col, out_valid)
    if fill and columns is not None:  # a filled prediction beyond the rows in use (candidates never are)
        beyond = out_col >= int(columns)
        out_col[beyond] = -1
        out_valid[beyond] = False
    return out_col, out_valid


@njit(cache=True, parallel=True)
def _outliers(col, valid, radius, tol, out):
    height, width = col.shape
    for yy in prange(height):
        buf = np.empty((2 * radius + 1) ** 2, np.int64)
        for xx in range(width):
            out[yy, xx] = False
            if not valid[yy, xx]:
                continue
            m = 0
            for y2 in range(max(0, yy - radius), min(height, yy + radius + 1)):
                for x2 in range(max(0, xx - radius), min(width, xx + radius + 1)):
                    if valid[y2, x2]:
                        buf[m] = col[y2, x2]
                        m += 1
            med = _median_sorted(buf, m)
            out[yy, xx] = abs(col[yy, xx] - med) > tol


def spatial_outliers(column: np.ndarray, valid: np.ndarray, *, window: int = 7, tol: int = 2) -> np.ndarray:
    """(H, W) bool: valid pixels whose column differs by > tol from the median of the valid
    columns in their window x window neighbourhood (itself included; even counts take the mean
    of the two middle values, rounded down)."""
    col = np.ascontiguousarray(column, dtype=np.int32)
    out = np.empty(col.shape, np.bool_)
    _outliers(col, np.ascontiguousarray(valid, np.bool_), window // 2, int(tol), out)
    return out


#: Column value of a non-voter in `_support` (far from every real column).
_NO_VOTE = np.int32(-(1 << 30))
#: Bit offsets of the packed counters of `_support`: voters, voters below, voters above.
_LO_SHIFT = 10
_HI_SHIFT = 20


@njit(cache=True)
def _straddle_sum(vcol, c, yy, xx, radius, tol, nlo_is_p, nhi_is_p):
    """da + db of the middle voter pair of pixel (yy, xx) when one side holds half the voters:
    the extreme values next to that side (see `_support`)."""
    height, width = vcol.shape
    big = 1 << 30
    maxlo = -big
    minmid = big
    maxmid = -big
    minhi = big
    # branch-free (selects): non-voters have d <= -2**30 <= maxlo, so they change nothing; the
    # pixel itself is masked out
    for y2 in range(max(0, yy - radius), min(height, yy + radius + 1)):
        for x2 in range(max(0, xx - radius), min(width, xx + radius + 1)):
            d = np.int64(vcol[y2, x2]) - c
            other = (y2 != yy) | (x2 != xx)
            lo = d < -tol
            hi = d > tol
            mid = other & ~lo & ~hi
            maxlo = max(maxlo, d if lo & other else -big)
            minhi = min(minhi, d if hi & other else big)
            minmid = min(minmid, d if mid else big)
            maxmid = max(maxmid, d if mid else -big)
    if nlo_is_p and nhi_is_p:
        return maxlo + minhi
    if nlo_is_p:
        return maxlo + minmid
    return maxmid + minhi


@njit(cache=True, parallel=True)
def _support(col, conf, eligible, t_vote, radius, min_votes, tol, vcol, out):
    """Median test by counting: no sort, no per-pixel allocation, one row per prange step.

    With d = (voter column) - c over the m voters of a pixel with column c: for odd m the
    median lies in [c - tol, c + tol] iff at most m // 2 of the d are < -tol and at most m // 2
    are > tol.  For even m = 2p the median is floor((a + b) / 2) of the middle pair, and
    |median - c| <= tol iff -2 tol <= da + db <= 2 tol + 1; both are in [-tol, tol] (pass)
    unless more than p of the d lie on one side (fail) or exactly p do: then a and b are the
    extreme values next to that side, found by a rescan of that pixel's window (rare).
    The counts of voters / below / above are packed into one int32 per pixel and accumulated
    over whole rows per window offset (vectorised over x); non-voters count as "below" there and
    are subtracted afterwards.  vcol: (H, W) int32 scratch.
    """
    height, width = col.shape
    for yy in prange(height):
        for xx in range(width):
            c = col[yy, xx]
            vote = eligible[yy, xx] and conf[yy, xx] >= t_vote and c >= 0
            vcol[yy, xx] = c if vote else _NO_VOTE
    cmask = (1 << _LO_SHIFT) - 1
    ntol = np.int32(-tol)
    ptol = np.int32(tol)
    one = np.int32(1)
    lo_one = np.int32(1 << _LO_SHIFT)
    hi_one = np.int32(1 << _HI_SHIFT)
    zero = np.int32(0)
    for yy in prange(height):
        acc = np.zeros(width, np.int32)
        lt = np.empty(width, np.int32)
        ht = np.empty(width, np.int32)
        c = col[yy]
        for xx in range(width):
            # v - c < -tol  <=>  v < c - tol (no overflow: |columns| < 2**16, _NO_VOTE = -2**30)
            lt[xx] = c[xx] + ntol
            ht[xx] = c[xx] + ptol
        for y2 in range(max(0, yy - radius), min(height, yy + radius + 1)):
            vr = vcol[y2]
            for dx in range(-radius, radius + 1):
                if y2 == yy and dx == 0:
                    continue
                # non-voters (_NO_VOTE) count as "below"; corrected with the voter count below
                x_lo = max(0, -dx)
                x_hi = min(width, width - dx)
                vs = vr[x_lo + dx:x_hi + dx]
                ls = lt[x_lo:x_hi]
                hs = ht[x_lo:x_hi]
                ac = acc[x_lo:x_hi]
                for j in range(x_hi - x_lo):
                    v = vs[j]
                    a = ac[j] + (one if v != _NO_VOTE else zero)
                    a += lo_one if v < ls[j] else zero
                    a += hi_one if v > hs[j] else zero
                    ac[j] = np.int32(a)
        ny = min(height, yy + radius + 1) - max(0, yy - radius)
        for xx in range(width):
            a = acc[xx]
            mm = a & cmask
            nwin = ny * (min(width, xx + radius + 1) - max(0, xx - radius)) - 1
            nlo = ((a >> _LO_SHIFT) & cmask) - (nwin - mm)
            nhi = a >> _HI_SHIFT
            ok = eligible[yy, xx] and c[xx] >= 0 and mm >= min_votes
            if ok:
                p = mm // 2
                if mm % 2 == 1:
                    ok = nlo <= p and nhi <= p
                elif nlo > p or nhi > p:
                    ok = False
                elif nlo == p or nhi == p:
                    s = _straddle_sum(vcol, c[xx], yy, xx, radius, tol, nlo == p, nhi == p)
                    ok = -2 * tol <= s and s <= 2 * tol + 1
            out[yy, xx] = ok


def spatial_support(
    column: np.ndarray,
    confidence: np.ndarray,
    eligible: np.ndarray,
    *,
    t_vote: float,
    window: int = 5,
    min_votes: int = 3,
    tol: int = 1,
) -> np.ndarray:
    """(H, W) bool: the pixel's column is within `tol` of the median of the columns of the
    high-confidence (>= t_vote) eligible pixels in its window x window neighbourhood (itself
    excluded), with at least `min_votes` voters (an even count takes the mean of the two middle
    columns, rounded down).  Columns are not changed.  window: odd, at most 31 (packed counters)."""
    if window < 1 or window % 2 == 0 or window > 31:
        raise ValueError(f"window: expected an odd size 1..31, got {window}")
    if min_votes < 1 or tol < 0:
        raise ValueError(f"spatial_support: expected min_votes >= 1, tol >= 0, got {min_votes}, {tol}")
    col = np.ascontiguousarray(column, dtype=np.int32)
    for name, a in (("confidence", confidence), ("eligible", eligible)):
        if np.shape(a) != col.shape:
            raise ValueError(f"{name}: expected shape {col.shape} to match column, got {np.shape(a)}")
    out = np.empty(col.shape, np.bool_)
    vcol = np.empty(col.shape, np.int32)
    _support(col, np.ascontiguousarray(confidence, np.float32), np.ascontiguousarray(eligible, np.bool_),
             float(t_vote), window // 2, int(min_votes), int(tol), vcol, out)
    return out


class Spatial(NamedTuple):
    """Output of `spatial_stage` (all (H, W)).

    column: int32 codebook rows after the method's filters (-1 = none; not yet masked).
    support: bool `spatial_support` of the columns ("soft" / "hard" with ``spatial_check``), else None.
    valid: bool valid mask of the filters ("list", "median", "list+median"), else None (the
        decoder's validity rule, `edge.decode.validity.valid_mask`, decides).
    """

    column: np.ndarray
    support: np.ndarray | None
    valid: np.ndarray | None


def error_rule_spatial(settings: DecodeSettings, candidates: np.ndarray, error: np.ndarray, *,
                       stripe: int) -> tuple[np.ndarray, np.ndarray]:
    """Methods "list", "median", "list+median" under the "error" rule (every backend runs this on
    the host): `spatial_stage` on P(right) = 1 - error, with t_high = t_low = 1 - max_error, so
    that anchors and voters meet the target and a pixel that does not is corrected from its
    candidates where neighbours support one, and invalid where none is (the median filter does not
    fill it with the neighbours' column: ``fill=False``).  candidates (H, W, 3) int32 best-first,
    error (H, W) float32 P(wrong) of candidates[..., 0].  Returns (column (H, W) int32, -1 where
    invalid; valid (H, W) bool)."""
    target = settings.max_error
    column0 = np.ascontiguousarray(candidates[..., 0])
    spatial = spatial_stage(settings.replace(t_high=1.0 - target, t_low=1.0 - target), candidates,
                            (1.0 - error).astype(np.float32), column0, column0 >= 0, stripe=stripe, fill=False)
    column = np.where(spatial.valid, spatial.column, -1).astype(np.int32)
    return column, column >= 0


def published_error(candidates: np.ndarray, distances: np.ndarray, error: np.ndarray,
                    column: np.ndarray) -> np.ndarray:
    """P(wrong) of the column a spatial method published (methods "list" / "median" under the
    "error" rule), from the pixel's own evidence: where ``column`` is one of the candidates other
    than the best, ``1 - (1 - error) * near_j / near_0``, with ``near_i`` the posterior mass
    ``sum exp(-(P_k - P_0) / 2)`` of the candidates k within one codebook row of candidate i
    (P_k the distances, -2 log-posterior; inf = not scored, no mass).  Since ``1 - error`` is
    the best candidate's near mass over the whole mass (the not-lit probability and the tail
    beyond the top three included), this is the chosen column's share of the same whole, so
    nothing the top three do not hold is assumed.  A column within one row of no candidate gets
    1.  Elsewhere ``error`` as given (the column is the best candidate's, or none).  The
    neighbours' support that made the method publish the column is not in the value: it is
    what the pixel alone says, so it may exceed ``max_error`` on published pixels.

    candidates (H, W, 3) int32 rows best-first (-1 absent), distances (H, W, 3), error (H, W)
    float32 P(wrong) of candidates[..., 0], column (H, W) int32 rows (-1 invalid) -> (H, W) float32.
    """
    moved = (column >= 0) & (column != candidates[..., 0])
    out = np.array(error, np.float32, copy=True)
    if not moved.any():
        return out
    cand = candidates[moved].astype(np.int64)
    d = np.asarray(distances, np.float64)[moved]
    with np.errstate(invalid="ignore", over="ignore"):
        mass = np.exp(-0.5 * np.minimum(d - d[:, :1], 1400.0))
    mass = np.where((cand >= 0) & np.isfinite(mass), mass, 0.0)
    mass[:, 0] = 1.0
    near_best = (mass * (np.abs(cand - cand[:, :1]) <= 1)).sum(1)
    near_chosen = (mass * (np.abs(cand - column[moved][:, None].astype(np.int64)) <= 1)).sum(1)
    p_right = (1.0 - out[moved].astype(np.float64)) * near_chosen / near_best
    out[moved] = np.clip(1.0 - p_right, 0.0, 1.0).astype(np.float32)
    return out


def spatial_stage(settings: DecodeSettings, candidates: np.ndarray, confidence: np.ndarray, column: np.ndarray,
                  eligible: np.ndarray, *, stripe: int, distances: np.ndarray | None = None,
                  choices: int | None = None, fill: bool = True, columns: int | None = None) -> Spatial:
    """The spatial methods of ``settings.method`` on a candidate search's output.

    candidates: (H, W, 3) int32 rows best-first; confidence: (H, W) float32; column: (H, W) int32
    top-1 rows; eligible: (H, W) bool (contrast and a column, `edge.decode.validity.eligibility`);
    stripe: projector columns per codebook row (the disparity of the filters is in projector
    pixels); columns: the codebook rows in use (the median filter fills no row beyond them).
    "soft" / "hard": the support test (t_vote = t_high) if ``spatial_check``;
    "list": `order_prior`; "median": `confidence_median` (with the candidates, ``fill`` and
    ``columns``); "list+median":
    both in turn; "sgm": `edge.decode.sgm.from_search` on the search's ML `distances` (H, W, 3)
    with N = `choices` candidate columns (both required), valid where eligible and its error
    probability < ``max_error``.
    """
    method, t_low, t_high = settings.method, settings.t_low, settings.t_high
    if method == "sgm":
        if distances is None or choices is None:
            raise ValueError("method 'sgm': expected the search's distances and choices (candidate columns), got None")
        reg = sgm_from_search(candidates, distances, eligible, choices=choices, stripe=stripe,
                              max_error=settings.max_error)
        return Spatial(reg.column, None, reg.valid)
    if method in ("soft", "hard"):
        support = spatial_support(column, confidence, eligible, t_vote=t_high) if settings.spatial_check else None
        return Spatial(column, support, None)
    valid = None
    if method in ("list", "list+median"):
        column, valid = order_prior(candidates, confidence, eligible, t_high=t_high, t_low=t_low, stripe=stripe)
    if method in ("median", "list+median"):
        column, valid = confidence_median(column, confidence, eligible & (column >= 0), t_low=t_low,
                                          t_high=t_high, candidates=candidates, stripe=stripe, fill=fill,
                                          columns=columns)
    if valid is None:
        raise ValueError(f"method: expected one of soft, hard, list, median, list+median, sgm, got {method!r}")
    return Spatial(column, None, valid)
