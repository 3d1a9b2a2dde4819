"""The "lanes" path: exact top-3 of a column-linear binary code, LANES pixels of a row at a time.

The c_ref / V decomposition of `edge.decode.kernels.scalar`, but LANES (= 64) consecutive pixels
of a row are decoded together with V stored (n, LANES), so the cost of c_ref ^ D for every lane
is |D| contiguous vector adds with positions shared by all lanes, the column is
col(c_ref) ^ col(D), and the top-3 update is a branch-free min/max network per lane.  Whole
weight classes are evaluated (D = 0 for the whole block, the lightest class for a queue of the
row's lanes that D = 0 did not finish); a lane is finished when its third-best cost is below the
class bound of the heavier classes (sum of the t smallest V, lanes sorted with a vectorised
odd-even network); the others are moved to a per-row pending queue that evaluates the next
classes.  On the issue-4 benchmark (ecc-22-10: classes 8,
12, 16) about 5e-6 of the pixels need class 12.  Tables: `edge.decode.tables.LaneTables`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .cost import LANES, _block_llr
from .top3 import BEYOND_KEY, IDX_BITS, NO_KEY, _write, _write_none


#: Larger than any cost bound (an empty weight class).
_NO_BOUND = np.int64(1) << np.int64(62)


@njit(cache=True)
def _eval_class(V, base, colref, lo, hi, k1, k2, k3, acc, dpos, dcol, e_start, e_stop, p_start, t):
    """Top-3 update of LANES lanes with every codeword c_ref ^ D, D in dcol[e_start:e_stop].

    D has weight t and positions dpos[p_start + (e - e_start) * t ...]; its cost in lane l is
    base[l] + sum of V[pos, l]; its column colref[l] ^ dcol[e].  Keys are
    (cost << IDX_BITS) | column; columns outside [lo[l], hi[l]] are skipped (a compare and a
    select per lane: cheaper to always do than to compile a second copy).
    """
    p = p_start
    t4 = t - t % 4
    for e in range(e_start, e_stop):
        # sums of 4 rows per pass: straight-line loop bodies over the lanes vectorise
        if t >= 4:
            r0 = dpos[p]
            r1 = dpos[p + 1]
            r2 = dpos[p + 2]
            r3 = dpos[p + 3]
            for l in range(LANES):
                acc[l] = base[l] + V[r0, l] + V[r1, l] + V[r2, l] + V[r3, l]
        else:
            for l in range(LANES):
                acc[l] = base[l]
        for j in range(4, t4, 4):
            r0 = dpos[p + j]
            r1 = dpos[p + j + 1]
            r2 = dpos[p + j + 2]
            r3 = dpos[p + j + 3]
            for l in range(LANES):
                acc[l] += V[r0, l] + V[r1, l] + V[r2, l] + V[r3, l]
        for j in range(t4, t):
            r0 = dpos[p + j]
            for l in range(LANES):
                acc[l] += V[r0, l]
        p += t
        md = dcol[e]
        for l in range(LANES):
            col = colref[l] ^ md
            key = (np.int64(acc[l]) << IDX_BITS) | np.int64(col)
            ok = (col >= lo[l]) & (col <= hi[l])
            key = key if ok else NO_KEY
            a = k1[l]
            k1[l] = min(a, key)
            key = max(a, key)
            a = k2[l]
            k2[l] = min(a, key)
            key = max(a, key)
            k3[l] = min(k3[l], key)


@njit(cache=True)
def _class_bounds(V, SV, run, lb, n, cls_weight, nclass):
    """lb[c, l] = min over classes c' >= c of (sum of the cls_weight[c'] smallest V of
    lane l): a lower bound of cost - base for every codeword c_ref ^ D, |D| >= cls_weight[c].
    lb[nclass, l] = _NO_BOUND.  Sorts each lane (odd-even transposition, lane-wise)."""
    for i in range(n):
        for l in range(LANES):
            SV[i, l] = V[i, l]
    for ps in range(n):
        for i in range(ps & 1, n - 1, 2):
            for l in range(LANES):
                a = SV[i, l]
                b = SV[i + 1, l]
                SV[i, l] = min(a, b)
                SV[i + 1, l] = max(a, b)
    for l in range(LANES):
        run[l] = 0
        lb[nclass, l] = _NO_BOUND
    c = 0
    for t in range(1, n + 1):
        for l in range(LANES):
            run[l] += SV[t - 1, l]
        if c < nclass and cls_weight[c] == t:
            for l in range(LANES):
                lb[c, l] = run[l]
            c += 1
    for c in range(nclass - 1, -1, -1):
        for l in range(LANES):
            lb[c, l] = min(lb[c, l], lb[c + 1, l])


@njit(cache=True)
def _lightest_floor(V, n, w0, lb):
    """lb[0, l] = a lower bound of `_class_bounds`' lb[0, l] without sorting: ``w0 * min_i V[i, l]``
    (w0 the lightest class's weight) where every V of lane l is >= 0 (then the sum of the t
    smallest V does not decrease with t, so lb[0, l] is the sum of the w0 smallest), else
    -`_NO_BOUND` (no bound)."""
    for l in range(LANES):
        lb[0, l] = _NO_BOUND
    for i in range(n):
        for l in range(LANES):
            lb[0, l] = min(lb[0, l], np.int64(V[i, l]))
    for l in range(LANES):
        v = lb[0, l]
        lb[0, l] = w0 * v if v >= 0 else -_NO_BOUND


@njit(cache=True)
def _first_bounds(V, SV, run, lb, n, cls_weight, nclass, k1, base, active, x0, width, margin_q, margin, dmin,
                  q_scale):
    """The block's class bounds after D = 0 and whether every lane is beyond the margin with them
    (`_block_beyond`: then no other codeword needs evaluating).  With a margin it first tries
    `_lightest_floor` (a lane beyond the margin with a lower bound is beyond it with the exact
    one): where that settles the block, lb[0] holds those floors, which is all a block beyond
    the margin reads; otherwise lb is `_class_bounds`' and the test is made with it."""
    if margin_q >= 0:
        _lightest_floor(V, n, np.int64(cls_weight[0]), lb)
        if _block_beyond(k1, base, lb, active, x0, width, margin_q, margin, dmin, q_scale):
            return True
    _class_bounds(V, SV, run, lb, n, cls_weight, nclass)
    return _block_beyond(k1, base, lb, active, x0, width, margin_q, margin, dmin, q_scale)


@njit(cache=True)
def _run_classes(V, lb, base, colref, lo, hi, k1, k2, k3, acc, nlanes, c_first, c_stop, nclass,
                 cls_weight, cls_start, cls_pstart, dpos, dcol):
    """Evaluate classes c_first, c_first + 1, ... (before c_stop) for a whole lane block, until
    the bounds lb prove the top-3 of lanes 0..nlanes-1; return the codeword evaluations per lane."""
    evaluated = 0
    c = c_first
    while c < c_stop:
        _eval_class(V, base, colref, lo, hi, k1, k2, k3, acc, dpos, dcol, cls_start[c],
                    cls_start[c + 1], cls_pstart[c], cls_weight[c])
        evaluated += cls_start[c + 1] - cls_start[c]
        c += 1
        if c >= c_stop:
            break
        done = True
        for l in range(nlanes):
            if (k3[l] >> IDX_BITS) >= base[l] + lb[c, l]:
                done = False
        if done:
            break
    return evaluated


@njit(cache=True)
def _zero_set_top3(V, l, n, colref, col_bit, basis, leads, keys):
    """Exact top-3 keys of lane l of a full-space code (every n-bit word a codeword: all V >= 0,
    base 0) whose V has at least two zeros; False (keys untouched) otherwise.

    The words c_ref ^ D, D a subset of the zero positions Z, cost 0, and every other word costs
    >= 1: with |Z| >= 2 the top three are the three least columns of the affine space
    colref ^ span(col_bit[i], i in Z) (the columns of a full-space column-linear code are its
    words' images under an invertible linear map, so the col_bit are independent).  With the
    span in fully reduced echelon form (each leading bit in one vector only), its least element
    x0 is colref with every leading bit cleared, then x0 ^ (the vector of the lowest leading
    bit), then x0 ^ (the vector of the second lowest).  Keys: the columns (cost 0).
    Scratch basis, leads (n,) int64."""
    z = 0
    for i in range(n):
        v = V[i, l]
        if v < 0:
            return False
        if v != 0:
            continue
        x = np.int64(col_bit[i])
        for j in range(z):
            if x & leads[j]:
                x ^= basis[j]
        if x == 0:  # (not for a full-space code: its col_bit are independent)
            continue
        lead = np.int64(1)
        while lead <= x >> np.int64(1):
            lead <<= np.int64(1)
        for j in range(z):
            if basis[j] & lead:
                basis[j] ^= x
        basis[z] = x
        leads[z] = lead
        z += 1
    if z < 2:
        return False
    x0 = np.int64(colref)
    j0 = 0
    for j in range(z):
        if x0 & leads[j]:
            x0 ^= basis[j]
        if leads[j] < leads[j0]:
            j0 = j
    j1 = 1 if j0 == 0 else 0
    for j in range(z):
        if j != j0 and leads[j] < leads[j1]:
            j1 = j
    keys[0] = x0
    keys[1] = x0 ^ basis[j0]
    keys[2] = x0 ^ basis[j1]
    return True


@njit(cache=True)
def _beyond(k1, bound, margin_q, margin, dmin, q_scale):
    """Whether every codeword of cost >= ``bound`` lies beyond the margin of the best key k1: its
    cost at least ``margin_q`` more (quantised units, ``margin_q >= 0``), and its distance's
    float32 (`_write`'s ``float32(dmin + cost / q_scale)``, monotone in the cost) more than
    ``margin`` above the best's in float32 arithmetic, as a reader of the distances computes it
    (`edge.decode.posterior`'s skip test).  False where there is no best or no margin (< 0)."""
    if margin_q < 0 or k1 == NO_KEY:
        return False
    c1 = k1 >> IDX_BITS
    if bound - c1 < margin_q:
        return False
    d1 = np.float32(dmin + c1 / q_scale)
    db = np.float32(dmin + (c1 + margin_q) / q_scale)
    return db - d1 > margin


@njit(cache=True)
def _located(key, bound):
    """A top-3 key as `_write` takes it where codewords of cost >= ``bound`` were not evaluated:
    the key where its cost is below the bound (then it is exact), else `BEYOND_KEY` (NO_KEY kept
    as it is: `_beyond_keys` fills the slots a lane's columns can hold)."""
    if key == NO_KEY or (key >> IDX_BITS) < bound:
        return key
    return BEYOND_KEY


@njit(cache=True)
def _beyond_keys(k1, k2, k3, bound, lo, hi):
    """(k2, k3) of a lane finished by the margin: `_located`, and an empty slot that a column of
    the lane's range [lo, hi] would fill (the range holds 2 or 3 or more columns) becomes
    `BEYOND_KEY`: such a codeword exists and costs at least ``bound``."""
    b2 = _located(k2, bound)
    b3 = _located(k3, bound)
    if b2 == NO_KEY and hi - lo >= 1:
        b2 = BEYOND_KEY
    if b3 == NO_KEY and hi - lo >= 2:
        b3 = BEYOND_KEY
    return b2, b3


@njit(cache=True)
def _nearest(Y, n, masks, syn_col, col_bit, leader, leader_col, has_leader, SYN, COLH, HM, E, colref, V, base):
    """Per lane, from the quantised cost differences Y (n, LANES): c_ref (its column in colref,
    the flips from h in E), base = cost(c_ref) and V (n, LANES) (`soft_lanes`).  Scratch SYN,
    COLH, HM (LANES,) int64."""
    L = LANES
    # hard decision -> syndrome and column of h, lane-parallel
    for l in range(L):
        SYN[l] = 0
        COLH[l] = 0
        HM[l] = 0
    for i in range(n):
        sc = syn_col[i]
        cbit = col_bit[i]
        ibit = np.int64(1) << i
        for l in range(L):
            m = -np.int64(Y[i, l] > 0)
            SYN[l] ^= sc & m
            COLH[l] ^= cbit & m
            HM[l] |= ibit & m
    for l in range(L):
        if has_leader:
            E[l] = np.int64(leader[SYN[l]])
            colref[l] = np.int32(COLH[l] ^ leader_col[SYN[l]])
        else:
            E[l] = HM[l] ^ np.int64(masks[COLH[l]])
            colref[l] = np.int32(COLH[l])
        base[l] = 0
    for i in range(n):
        for l in range(L):
            yv = Y[i, l]
            wv = max(yv, -yv)
            bit = (E[l] >> i) & 1
            V[i, l] = wv - 2 * wv * np.int32(bit)
            base[l] += wv * np.int32(bit)


@njit(cache=True)
def _first_keys(colref, base, lo, hi, k1):
    """k1 (LANES,) = each lane's key of c_ref (cost base), NO_KEY where its column is outside the
    lane's range [lo, hi] (the search's first candidate, D = 0)."""
    for l in range(LANES):
        cr = colref[l]
        ok = (cr >= lo[l]) & (cr <= hi[l])
        k1[l] = ((np.int64(base[l]) << IDX_BITS) | np.int64(cr)) if ok else NO_KEY


@njit(cache=True)
def _block_beyond(k1, base, lb, active, x0, width, margin_q, margin, dmin, q_scale):
    """Whether every active lane of the block (inside the image) is `_beyond` the margin with the
    lightest class's bound ``base + lb[0]``: then no codeword but c_ref needs evaluating."""
    for l in range(LANES):
        if active[l] and x0 + l < width:
            if not _beyond(k1[l], base[l] + lb[0, l], margin_q, margin, dmin[l], q_scale):
                return False
    return True


class MarginScratch(NamedTuple):
    """Per-row scratch of `margin_block` (`margin_scratch`)."""

    SYN: np.ndarray
    COLH: np.ndarray
    HM: np.ndarray
    E: np.ndarray
    colref: np.ndarray
    V: np.ndarray
    SV: np.ndarray
    base: np.ndarray
    lb: np.ndarray
    run: np.ndarray
    k1: np.ndarray


@njit(cache=True)
def margin_scratch(n, nclass):
    """A `MarginScratch` for codes of n positions and nclass weight classes."""
    L = LANES
    return MarginScratch(np.zeros(L, np.int64), np.zeros(L, np.int64), np.zeros(L, np.int64),
                         np.zeros(L, np.int64), np.zeros(L, np.int32), np.zeros((n, L), np.int32),
                         np.zeros((n, L), np.int32), np.zeros(L, np.int32), np.zeros((nclass + 1, L), np.int64),
                         np.zeros(L, np.int64), np.zeros(L, np.int64))


@njit(cache=True)
def margin_block(Y, n, tables, active, lo, hi, dmin, q_scale, margin_q, margin, x0, width, sc,
                 out_col, out_dist, out_conf, yy):
    """A block of LANES pixels whose every active lane is beyond the margin after D = 0 (the
    nearest codeword c_ref, in its range [lo, hi], ahead of every other codeword by the margin:
    `_beyond` of the lightest class's bound) is written as `soft_lanes` writes it (best c_ref,
    the other slots `BEYOND_KEY` or empty by `_beyond_keys`) and True is returned; otherwise
    nothing is written, False.  For a search of the same block by another kernel (the band's):
    the lane search's first step only, scratch ``sc`` (`margin_scratch`)."""
    if margin_q < 0 or tables.cls_weight.shape[0] == 0:
        return False
    _nearest(Y, n, tables.masks, tables.syn_col, tables.col_bit, tables.leader, tables.leader_col,
             tables.has_leader, sc.SYN, sc.COLH, sc.HM, sc.E, sc.colref, sc.V, sc.base)
    nclass = tables.cls_weight.shape[0]
    _first_keys(sc.colref, sc.base, lo, hi, sc.k1)
    if not _first_bounds(sc.V, sc.SV, sc.run, sc.lb, n, tables.cls_weight, nclass, sc.k1, sc.base, active, x0,
                         width, margin_q, margin, dmin, q_scale):
        return False
    L = LANES
    for l in range(L):
        xx = x0 + l
        if xx >= width:
            break
        if not active[l]:
            _write_none(out_col, out_dist, out_conf, yy, xx)
            continue
        b2, b3 = _beyond_keys(sc.k1[l], NO_KEY, NO_KEY, sc.base[l] + sc.lb[0, l], lo[l], hi[l])
        _write(out_col, out_dist, out_conf, yy, xx, sc.k1[l], b2, b3, dmin[l], q_scale, margin)
    return True


#: A block's lanes that D = 0 leaves for the lightest weight class are queued (copied, to run
#: with other blocks' in full queues) only where that class holds at least this many codewords
#: (ecc-22-10: 330); below, copying a lane costs about what evaluating the class for it does
#: (gray-10: 10 codewords of weight 1), and the block runs the class itself.
QUEUE_MIN_WORDS = 64


class LaneQueue(NamedTuple):
    """A block of up to LANES lanes gathered from several blocks of a row (`_queue_lane`), each
    with what its search needs next: V (n, LANES) int32, class bounds lb (nclass + 1, LANES) int64,
    base, colref, lo, hi (LANES,) int32, keys k1 / k2 / k3 (LANES,) int64, dmin (LANES,) float64
    and its pixel's x (LANES,) int64."""

    V: np.ndarray
    lb: np.ndarray
    base: np.ndarray
    colref: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    k3: np.ndarray
    dmin: np.ndarray
    x: np.ndarray


@njit(cache=True)
def _lane_queue(n, nclass):
    """An empty `LaneQueue` for codes of n positions and nclass weight classes."""
    L = LANES
    return LaneQueue(np.zeros((n, L), np.int32), np.zeros((nclass + 1, L), np.int64), np.zeros(L, np.int32),
                     np.zeros(L, np.int32), np.zeros(L, np.int32), np.zeros(L, np.int32), np.full(L, NO_KEY),
                     np.full(L, NO_KEY), np.full(L, NO_KEY), np.zeros(L, np.float64), np.zeros(L, np.int64))


@njit(cache=True)
def _queue_lane(q, p, V, lb, base, colref, lo, hi, k1, k2, k3, dmin, l, xx, n, nclass):
    """Copy lane l (pixel x = xx) of a block into slot p of queue q."""
    for i in range(n):
        q.V[i, p] = V[i, l]
    for c in range(nclass + 1):
        q.lb[c, p] = lb[c, l]
    q.base[p] = base[l]
    q.colref[p] = colref[l]
    q.lo[p] = lo[l]
    q.hi[p] = hi[l]
    q.k1[p] = k1[l]
    q.k2[p] = k2[l]
    q.k3[p] = k3[l]
    q.dmin[p] = dmin[l]
    q.x[p] = xx


@njit(cache=True)
def _pad_queue(q, count, n):
    """Lanes count.. of a partly filled queue: V, base and colref 0 (their results are not read)."""
    for p in range(count, LANES):
        for i in range(n):
            q.V[i, p] = 0
        q.base[p] = 0
        q.colref[p] = 0


@njit(cache=True)
def _run_pending(P, count, n, tables, acc, q_scale, out_col, out_dist, out_conf, yy):
    """The pending queue's ``count`` lanes: every class from the second on until their top-3 is
    proved (exact), then written.  Returns the codeword evaluations."""
    nclass = tables.cls_weight.shape[0]
    _pad_queue(P, count, n)
    evaluated = count * _run_classes(P.V, P.lb, P.base, P.colref, P.lo, P.hi, P.k1, P.k2, P.k3, acc, count, 1,
                                     nclass, nclass, tables.cls_weight, tables.cls_start, tables.cls_pstart,
                                     tables.dpos, tables.dcol)
    for p in range(count):
        _write(out_col, out_dist, out_conf, yy, P.x[p], P.k1[p], P.k2[p], P.k3[p], P.dmin[p], q_scale)
    return evaluated


@njit(cache=True)
def _run_first(Q, count, live, nlive, P, npend, n, tables, acc, margin_q, margin, q_scale, out_col, out_dist,
               out_conf, yy, ZB, ZL, ZK, last_col, cnt):
    """Lanes 0..count-1 of Q (a queue, lanes past ``count`` padded; or a block of the row, count
    = LANES) evaluate the lightest weight class; then each lane with ``live`` set (``nlive`` of
    them): top-3 proved by the next class's bound (written), or every codeword not evaluated
    beyond the margin (written, `_beyond_keys`), or a full-space code's ties at cost 0
    (`_zero_set_top3`, written), else moved to the pending queue P (which runs once full).
    Returns P's new count; adds to cnt: [0] evaluations (``nlive`` per codeword), [1] lanes moved
    to P, [2] 1 if any was, [3] pending queues run, [4] zero-set lanes, [5] margin lanes."""
    nclass = tables.cls_weight.shape[0]
    full_space = tables.full_space
    if count < LANES:
        _pad_queue(Q, count, n)
    for p in range(count):
        Q.k2[p] = NO_KEY
        Q.k3[p] = NO_KEY
    cnt[0] += nlive * _run_classes(Q.V, Q.lb, Q.base, Q.colref, Q.lo, Q.hi, Q.k1, Q.k2, Q.k3, acc, count, 0, 1,
                                   nclass, tables.cls_weight, tables.cls_start, tables.cls_pstart, tables.dpos,
                                   tables.dcol)
    moved = False
    for p in range(count):
        if not live[p]:
            continue
        xx = Q.x[p]
        bound = Q.base[p] + Q.lb[1, p]
        if (Q.k3[p] >> IDX_BITS) < bound:
            _write(out_col, out_dist, out_conf, yy, xx, Q.k1[p], Q.k2[p], Q.k3[p], Q.dmin[p], q_scale)
            continue
        if _beyond(Q.k1[p], bound, margin_q, margin, Q.dmin[p], q_scale):
            b2, b3 = _beyond_keys(Q.k1[p], Q.k2[p], Q.k3[p], bound, Q.lo[p], Q.hi[p])
            _write(out_col, out_dist, out_conf, yy, xx, Q.k1[p], b2, b3, Q.dmin[p], q_scale, margin)
            cnt[5] += 1
            continue
        # a full-space code, every column a candidate, two or more zero costs: the top three
        # are the tied words' least columns (`_zero_set_top3`), no class search needed
        if (full_space and Q.lo[p] <= 0 and Q.hi[p] >= last_col
                and _zero_set_top3(Q.V, p, n, Q.colref[p], tables.col_bit, ZB, ZL, ZK)):
            _write(out_col, out_dist, out_conf, yy, xx, ZK[0], ZK[1], ZK[2], Q.dmin[p], q_scale)
            cnt[4] += 1
            continue
        moved = True
        cnt[1] += 1
        _queue_lane(P, npend, Q.V, Q.lb, Q.base, Q.colref, Q.lo, Q.hi, Q.k1, Q.k2, Q.k3, Q.dmin, p, xx, n, nclass)
        npend += 1
        if npend == LANES:
            cnt[0] += _run_pending(P, npend, n, tables, acc, q_scale, out_col, out_dist, out_conf, yy)
            cnt[3] += 1
            npend = 0
    if moved:
        cnt[2] += 1
    return npend


@njit(cache=True)
def _lanes_row(yy, frames, inverse, has_inv, white, black, scale, model, tables, band, margin_q, margin,
               out_col, out_dist, out_conf, out_stats):
    """Row yy of `soft_lanes` (a plain function: keeps the parallel kernel small to compile)."""
    metric, sr2, ss2, q_scale, ltab = model.metric, model.sr2, model.ss2, model.q_scale, model.ltab
    masks, syn_col, col_bit = tables.masks, tables.syn_col, tables.col_bit
    leader, leader_col, has_leader = tables.leader, tables.leader_col, tables.has_leader
    cls_weight = tables.cls_weight
    full_space = tables.full_space
    ncols, use_band, min_d, max_d, stripe = band.ncols, band.use_band, band.min_d, band.max_d, band.stripe
    n, height, width = frames.shape
    nclass = cls_weight.shape[0]
    L = LANES
    R = np.zeros((n, L), np.float64)
    RI = np.zeros((n, L), np.float64)
    PA = np.zeros((8, L), np.float64)
    Y = np.zeros((n, L), np.int32)
    # the block's D = 0 scratch: `margin_block`'s (the same first step)
    sc = margin_scratch(n, nclass)
    SYN, COLH, HM, E, colref, V, SV, base, lb, run, k1 = (sc.SYN, sc.COLH, sc.HM, sc.E, sc.colref, sc.V, sc.SV,
                                                          sc.base, sc.lb, sc.run, sc.k1)
    acc = np.zeros(L, np.int32)
    lo = np.zeros(L, np.int32)
    hi = np.zeros(L, np.int32)
    none = np.full(L, NO_KEY)
    dmin = np.zeros(L, np.float64)
    active = np.zeros(L, np.bool_)
    live = np.zeros(L, np.bool_)  # the block's lanes that D = 0 left for the lightest class
    queued = np.ones(L, np.bool_)  # a queue's lanes (its first count)
    # the block itself as a queue (its lanes at x0 + l), for `_run_first` where it runs whole
    B = LaneQueue(V, lb, base, colref, lo, hi, k1, np.full(L, NO_KEY), np.full(L, NO_KEY), dmin,
                  np.zeros(L, np.int64))
    # queue a block's unfinished lanes only where the lightest class costs more than copying them
    queue_pays = tables.cls_start[1] - tables.cls_start[0] >= QUEUE_MIN_WORDS if nclass > 0 else False
    Q = _lane_queue(n, nclass)  # lanes due for the lightest class
    P = _lane_queue(n, nclass)  # lanes due for the heavier classes
    ZB = np.zeros(n, np.int64)
    ZL = np.zeros(n, np.int64)
    ZK = np.zeros(3, np.int64)
    cnt = np.zeros(6, np.int64)
    last_col = (1 << n) - 1 if full_space else 0  # a full-space code's last column (n <= IDX_BITS)
    nq = 0
    npend = 0
    evaluated = 0
    blocks = 0
    first_blocks = 0
    n_margin = 0
    lane_margin = 0
    blocks_margin = 0
    for x0 in range(0, width, L):
        blocks += 1
        nact = _block_llr(frames, inverse, has_inv, white, black, scale, metric, sr2, ss2,
                          q_scale, ltab, yy, x0, use_band, min_d, max_d, stripe, ncols, R, RI, PA,
                          Y, dmin, active, lo, hi)
        _nearest(Y, n, masks, syn_col, col_bit, leader, leader_col, has_leader, SYN, COLH, HM, E, colref, V, base)
        if nact == 0:
            for l in range(L):
                if x0 + l < width:
                    _write_none(out_col, out_dist, out_conf, yy, x0 + l)
            continue
        _first_keys(colref, base, lo, hi, k1)
        evaluated += nact
        if nclass == 0:  # no codeword but c_ref
            for l in range(L):
                if x0 + l < width:
                    if active[l]:
                        _write(out_col, out_dist, out_conf, yy, x0 + l, k1[l], NO_KEY, NO_KEY, dmin[l], q_scale)
                    else:
                        _write_none(out_col, out_dist, out_conf, yy, x0 + l)
            continue
        # with a margin: the lightest class is skipped where every lane's best is already the
        # margin ahead of all other codewords (the block), else lane by lane
        whole = _first_bounds(V, SV, run, lb, n, cls_weight, nclass, k1, base, active, x0, width, margin_q, margin,
                              dmin, q_scale)
        blocks_margin += 1 if whole else 0
        nlive = 0
        for l in range(L):
            xx = x0 + l
            live[l] = False
            B.x[l] = xx
            if xx >= width:
                continue
            if not active[l]:
                _write_none(out_col, out_dist, out_conf, yy, xx)
                continue
            bound = base[l] + lb[0, l]
            if whole or _beyond(k1[l], bound, margin_q, margin, dmin[l], q_scale):
                b2, b3 = _beyond_keys(k1[l], NO_KEY, NO_KEY, bound, lo[l], hi[l])
                _write(out_col, out_dist, out_conf, yy, xx, k1[l], b2, b3, dmin[l], q_scale, margin)
                n_margin += 1
                lane_margin += 0 if whole else 1
                continue
            live[l] = True
            nlive += 1
        if nlive == 0:
            continue
        if nlive == nact or not queue_pays:  # the block runs the lightest class itself
            npend = _run_first(B, L, live, nlive, P, npend, n, tables, acc, margin_q, margin, q_scale, out_col,
                               out_dist, out_conf, yy, ZB, ZL, ZK, last_col, cnt)
            first_blocks += 1
            continue
        for l in range(L):
            if not live[l]:
                continue
            _queue_lane(Q, nq, V, lb, base, colref, lo, hi, k1, none, none, dmin, l, x0 + l, n, nclass)
            nq += 1
            if nq == L:
                npend = _run_first(Q, nq, queued, nq, P, npend, n, tables, acc, margin_q, margin, q_scale, out_col,
                                   out_dist, out_conf, yy, ZB, ZL, ZK, last_col, cnt)
                first_blocks += 1
                nq = 0
    if nq > 0:
        npend = _run_first(Q, nq, queued, nq, P, npend, n, tables, acc, margin_q, margin, q_scale, out_col, out_dist,
                           out_conf, yy, ZB, ZL, ZK, last_col, cnt)
        first_blocks += 1
    if npend > 0:
        cnt[0] += _run_pending(P, npend, n, tables, acc, q_scale, out_col, out_dist, out_conf, yy)
        cnt[3] += 1
    out_stats[yy, 0] = cnt[1]
    out_stats[yy, 1] = evaluated + cnt[0]
    out_stats[yy, 2] = cnt[2]
    out_stats[yy, 3] = blocks
    out_stats[yy, 4] = cnt[3]
    out_stats[yy, 5] = cnt[4]
    out_stats[yy, 6] = n_margin + cnt[5]
    out_stats[yy, 7] = blocks_margin
    out_stats[yy, 8] = first_blocks
    out_stats[yy, 9] = lane_margin


@njit(cache=True, parallel=True)
def soft_lanes(frames, inverse, has_inv, white, black, scale, model, tables, band, margin_q, margin,
               out_col, out_dist, out_conf, out_stats):
    """Exact top-3 soft decoding of a column-linear binary code, LANES pixels at a time.

    model: `CostModel`; tables: `edge.decode.tables.LaneTables`; band: `Band`.
    Per pixel: y, h, w as in `edge.decode.kernels.cost`; c_ref = nearest codeword of h (coset
    leader e of the syndrome of h, else the re-encoded information bits), base = cost(c_ref),
    V_i = +w_i where c_ref agrees with h, -w_i where not (stored V[i, lane]).  Every
    other codeword is c_ref ^ D with cost base + sum_{i in D} V_i and column col(c_ref) ^ col(D).
    Stage 1 evaluates D = 0 for the whole block; the lanes it does not finish (below) evaluate
    the lightest weight class (`_run_first`): in the block itself where every active lane needs
    it or the class is small (`QUEUE_MIN_WORDS`), else queued, in full (or, at the end of the
    row, partial) queues of LANES lanes from the row's blocks; a lane is done when its third-best cost is below
    base + (sum of the t smallest V) for every heavier class weight t.  Unfinished lanes are
    moved into a pending queue of the row; full (or, at the end of the row, partial) pending
    queues evaluate the next classes until every lane is done (`_run_pending`).  Which lanes
    share a queue does not change any lane's result: each lane's keys see the same codewords in
    the same order, and a lane already proved stays proved while its queue runs on.
    Ties go to the lower column (keys (cost << IDX_BITS) | column).

    Columns outside a lane's candidates [lo, hi] (band, ncols < size) are dropped; the bounds
    stay valid, so the result is exact within the candidates.
    A full-space code (`edge.decode.tables.CodeTables.full_space`: every n-bit word a codeword,
    so base = 0 and every V >= 0) with every column a candidate of the lane: a lane with two or
    more zero V after stage 1 (ties at cost 0, which the bounds cannot break: dark pixels whose
    pattern and inverse samples are equal) takes its top three from `_zero_set_top3` instead of
    the pending block.
    A margin (``margin_q >= 0`` quantised cost units, ``margin`` the same in distance units,
    ``margin_q > margin * q_scale``; ``margin_q = -1``: none, exact top-3): a lane is also
    finished where every codeword not evaluated is beyond the margin of its best (`_beyond`: the
    bound at least margin_q above the best cost and, in float32 distances, more than ``margin``
    above it).  Its best is then exact, and so is every other slot whose cost is below the bound;
    a slot that is not holds `BEYOND_KEY` (row `BEYOND` = -2, distance inf: a codeword at least
    the margin behind, not located).  A block whose every lane is beyond the margin after
    D = 0 skips the lightest class (tried first with `_lightest_floor`'s bounds, which need no
    sort, then with `_class_bounds`': `_first_bounds`); in any other block each lane beyond the
    margin with its class bound is finished there, and only the others are queued for the
    lightest class.  This is what a reader that ignores every candidate more than
    ``margin`` behind the best needs (the error rule's posterior, `SKIP_MARGIN`), and in a
    high-SNR capture nearly every block skips its lightest class.  Slots within the margin, and
    the pending queue's lanes, are exact top-3 as without a margin.
    out_stats (H, 10) int64 per row: pixels that needed the second class, codeword evaluations,
    lightest-class runs (a queue or a block, `_run_first`) with at least one such pixel, stage-1
    blocks, pending queues run, pixels resolved by `_zero_set_top3`, pixels finished by the
    margin, blocks that skipped the lightest class, lightest-class runs, pixels finished by the
    margin after D = 0 in a block that did not skip.
    """
    height = frames.shape[1]
    for yy in prange(height):
        _lanes_row(yy, frames, inverse, has_inv, white, black, scale, model, tables, band, margin_q, margin,
                   out_col, out_dist, out_conf, out_stats)
