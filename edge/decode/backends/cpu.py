"""The CPU backend: numba kernels (`edge.decode.kernels`) over the per-path code tables (`edge.decode.tables`).

Implements the backend seam of `edge.decode.backends` (``search``, ``hard``).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...codes import Code
from .. import kernels
from ...capture import CodedCapture
from ..tables import code_tables
from . import Q_SCALE

#: With a disparity band of at most this many columns the soft search scans the band directly
#: (`kernels.soft_band`); wider bands use the lane search with the band as a restriction.  The
#: crossover measured with tools/bench_decode.py's input (ecc-22-10, 600 x 700): scan 135 / 203 /
#: 271 ms CPU for 64 / 128 / 192 columns, lane search 272 / 224 / 217 ms.
BAND_BRUTE_MAX = 160
#: The lane search's margin in quantised costs is ``ceil((margin + MARGIN_SLACK) * q_scale)``
#: (distance units): the slack keeps the float32 distances of codewords beyond it more than
#: ``margin`` apart from the best's (`kernels.lanes._beyond` checks that too).
MARGIN_SLACK = 1.0


def _band_columns(band: tuple[bool, int, int], stripe: int) -> int:
    """Upper bound of the candidate columns per pixel of a disparity band."""
    use_band, min_d, max_d = band
    return (max_d - min_d) // stripe + 2 if use_band else 10**9


def search(
    stack: CodedCapture,
    code: Code,
    *,
    metric: int,
    sigma_r: float,
    sigma_s: float,
    columns: int,
    band: tuple[bool, int, int],
    stripe: int,
    path: str | None = None,
    margin: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Exact top-3 search: (candidates (H,W,3) i32, distances (H,W,3) f32, confidence (H,W) f32, stats).

    margin (distance units, > 0; None: exact top-3): the second and third candidates are only
    located within ``margin`` of the best (the "lanes" path, `kernels.soft_lanes`, and the "band"
    path's blocks that the lane search's first step finishes, `kernels.soft_band_fold`; the other
    paths return exact top-3, which meets the same contract): a slot beyond it may hold row
    `kernels.BEYOND` (-2, distance inf), a codeword at least ``margin`` behind the best in
    float32 distances.  The best candidate, and every slot within the margin, are exact.

    path (binary codes; default chosen from the code and band): "band" (a band of at most
    `BAND_BRUTE_MAX` columns: folded Walsh-Hadamard blocks, `kernels.soft_band_fold`, for
    column-linear codes, else the scan "band-scan"), "band-scan" (`kernels.soft_band`, a scan of
    the band, any binary code), "lanes" (weight-class search over blocks of `kernels.LANES`
    pixels, column-linear codes), "scalar" (per-pixel branch-and-bound or brute force, any
    binary code; the reference the others are tested against).  All are exact and return the
    same arrays.
    """
    tb = code_tables(code)
    h, w = stack.shape
    cand = np.empty((h, w, 3), np.int32)
    dist = np.empty((h, w, 3), np.float32)
    conf = np.empty((h, w), np.float32)
    inv = stack.inverse if stack.inverse is not None else stack.frames[:1, :1, :1]
    has_inv = stack.inverse is not None
    use_band, min_d, max_d = band
    q_scale = Q_SCALE[metric]
    sr2, ss2 = float(sigma_r) ** 2, float(sigma_s) ** 2
    if code.q == 2 and path is None:
        if use_band and _band_columns(band, stripe) <= BAND_BRUTE_MAX:
            path = "band"
        elif tb.column_linear:
            path = "lanes"
        else:
            path = "scalar"
    if path == "band" and not tb.column_linear:
        path = "band-scan"
    if path in ("band", "band-scan") and not use_band:
        raise ValueError(f"path: {path!r} needs min_disparity / max_disparity")
    if path == "lanes" and not tb.column_linear:
        raise ValueError(f"path: 'lanes' needs a column-linear binary code, got {code.name!r}")
    pixels = (stack.frames, inv, has_inv, stack.white, stack.black, stack.scale)
    t0 = time.perf_counter()
    # integer frames under the ML metric: the per-pixel variance logs from a table over the raw
    # levels (uint16: only where the image has more pixels than levels)
    levels = 0
    if metric == kernels.METRIC_ML and not has_inv:
        if stack.frames.dtype == np.uint8:
            levels = 256
        elif stack.frames.dtype == np.uint16 and h * w >= 65536:
            levels = 65536
    model = kernels.CostModel(metric, sr2, ss2, q_scale, kernels.log_levels(levels, stack.scale, sr2, ss2))
    margin_q = -1 if margin is None else int(math.ceil((float(margin) + MARGIN_SLACK) * q_scale))
    margin_f = np.inf if margin is None else float(margin)
    bnd = kernels.Band(int(columns), bool(use_band), int(min_d), int(max_d), int(stripe))
    if code.q != 2:
        kernels.soft_nary(*pixels, model, tb.nary_tables, bnd, cand, dist, conf)
        st = {"path": "nary", "brute_pixels": h * w, "evaluated": -1}
    elif path == "band":
        stats = np.zeros((h, 4), np.int64)
        kernels.soft_band_fold(*pixels, model, tb.fold_tables, bnd, tb.lane_tables, np.int64(margin_q),
                               np.float64(margin_f), cand, dist, conf, stats)
        st = {"path": path, "brute_pixels": int(stats[:, 0].sum()), "evaluated": int(stats[:, 1].sum()),
              "wide_key_pixels": int(stats[:, 2].sum()), "margin_blocks": int(stats[:, 3].sum())}
    elif path == "band-scan":
        stats = np.zeros((h, 2), np.int64)
        kernels.soft_band(*pixels, model, tb.scan_tables, bnd, cand, dist, conf, stats)
        st = {"path": path, "brute_pixels": int(stats[:, 0].sum()), "evaluated": int(stats[:, 1].sum())}
    elif path == "lanes":
        stats = np.zeros((h, 10), np.int64)
        kernels.soft_lanes(*pixels, model, tb.lane_tables, bnd, np.int64(margin_q), np.float64(margin_f),
                           cand, dist, conf, stats)
        tot = stats.sum(axis=0)
        st = {"path": path, "brute_pixels": 0, "evaluated": int(tot[1]),
              "second_class_pixels": int(tot[0]), "second_class_blocks": int(tot[2]),
              "blocks": int(tot[3]), "pending_blocks": int(tot[4]), "zero_set_pixels": int(tot[5]),
              "margin_pixels": int(tot[6]), "margin_blocks": int(tot[7]), "first_class_blocks": int(tot[8]),
              "margin_lanes": int(tot[9])}
    elif path == "scalar":
        stats = np.zeros((h, 2), np.int64)
        kernels.soft_binary(*pixels, model, tb.scalar_tables, bnd, BAND_BRUTE_MAX, cand, dist, conf, stats)
        st = {"path": path, "brute_pixels": int(stats[:, 0].sum()), "evaluated": int(stats[:, 1].sum())}
    else:
        raise ValueError(f"path: expected 'band', 'band-scan', 'lanes' or 'scalar', got {path!r}")
    st["seconds"] = time.perf_counter() - t0
    return cand, dist, conf, st


def hard(stack: CodedCapture, code: Code, *, columns: int, band: tuple[bool, int, int], stripe: int):
    """Hard decisions, nearest codeword in Hamming distance (see `edge.decode.backends`)."""
    tb = code_tables(code)
    h, w = stack.shape
    if code.q == 2 and tb.linear and tb.has_leader:
        cand = np.empty((h, w, 3), np.int32)
        dist = np.empty((h, w, 3), np.float32)
        conf = np.empty((h, w), np.float32)
        inv = stack.inverse if stack.inverse is not None else stack.frames[:1, :1, :1]
        use_band, min_d, max_d = band
        t0 = time.perf_counter()
        kernels.hard_lean(stack.frames, inv, stack.inverse is not None, stack.white, stack.black, tb.hard_tables,
                          kernels.Band(int(columns), bool(use_band), int(min_d), int(max_d), int(stripe)),
                          cand, dist, conf)
        return cand, dist, conf, {"path": "syndrome", "seconds": time.perf_counter() - t0}
    cand, dist, conf, st = search(stack, code, metric=kernels.METRIC_HARD, sigma_r=1.0, sigma_s=0.0,
                                  columns=columns, band=band, stripe=stripe)
    st["path"] = "hamming-search"
    return cand, dist, conf, st
