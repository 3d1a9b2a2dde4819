"""`decode`: frames of a coded capture -> projector column, confidence and top-3 candidates.

Methods (``method=``):

* ``"hard"``: binarise each sample against (white + black)/2 (or pattern vs inverse), decode to
  the nearest codeword in Hamming distance (coset-leader table for binary linear codes, exact
  top-3 Hamming search otherwise).  Confidence (syndrome path): ``max(0, d_min - 2 d1) /
  (d_min - d1)``, the paper's ratio with the guaranteed lower bound ``d2 >= d_min - d1``.
* ``"soft"``: exact maximum-likelihood top-3 under the heteroscedastic Gaussian model (see
  `edge.decode.kernels`); confidence ``(d2 - d1) / d2``.
* ``"list"``: soft + order prior along image rows (`edge.decode.spatial.order_prior`).
* ``"median"``: soft + confidence median filter (`edge.decode.spatial.confidence_median`).
* ``"list+median"``: order prior, then the median filter.

``metric="ml"`` (default) or ``"normalized"`` (the paper's plain normalised distance) selects the
per-sample costs for the soft methods.  ``levels="refit"`` re-estimates each pixel's on/off
levels from its code frames (`edge.decode.levels`) before the final decode.  The valid mask is
``eligible & (confidence >= min_confidence | (confidence >= t_low & supported))`` where
``eligible = contrast >= min_contrast & column >= 0`` and ``supported`` means the column is
within 1 of the median column of the eligible pixels with confidence >= t_high in the 5x5
neighbourhood (at least 3 voters; `spatial.spatial_support`, columns unchanged).  Pass
``spatial_check=False`` for the plain confidence + contrast mask.  "list" and "median" use the
validity rules of `spatial.order_prior` / `spatial.confidence_median`.  Defaults: `DEFAULTS`
(chosen on the real OpenCV Gray-code capture, see tests/test_decode_real.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..capture import CodedCapture
from ..codes import Code
from . import kernels
from .inputs import Stack, validate
from .spatial import confidence_median, order_prior, spatial_support
from .tables import code_tables
from .validity import eligible_column, final_mask

METHODS = ("hard", "soft", "list", "median", "list+median")
LEVELS = ("calibration", "refit")
METRICS = {"ml": kernels.METRIC_ML, "normalized": kernels.METRIC_NORMALIZED}

#: Documented defaults of `decode`.
DEFAULTS = {
    # Noise model, in normalised intensity units (1 = full scale of the frame dtype):
    # readout + quantisation sigma and shot-noise coefficient (variance = sr^2 + ss^2 * I).
    "sigma_r": 0.01,
    "sigma_s": 0.03,
    # Valid mask: white - black (normalised) and (d2 - d1)/d2 thresholds.
    "min_contrast": 0.02,
    "min_confidence": 0.3,
    # Spatial checks: confidence >= t_high votes / anchors; below t_low a pixel is never
    # accepted on spatial support alone (the median filter replaces it).
    "t_low": 0.05,
    "t_high": 0.3,
}

#: Quantisation steps per unit of per-sample cost (ML: chi-square units; normalised: x**2 units).
Q_SCALE = {kernels.METRIC_ML: 256.0, kernels.METRIC_NORMALIZED: 16384.0, kernels.METRIC_HARD: 1.0}
#: With a disparity band of at most this many columns the soft search scans the band directly
#: (`kernels.soft_band`); wider bands use the lane search with the band as a restriction.  The
#: crossover measured with tools/bench_decode.py's input (ecc-22-10, 600 x 700): scan 135 / 203 /
#: 271 ms CPU for 64 / 128 / 192 columns, lane search 272 / 224 / 217 ms.
BAND_BRUTE_MAX = 160


@dataclass(frozen=True)
class Decoded:
    """Decoder output for an (H, W) camera image.

    column: (H, W) int32 codebook row (projector column // stripe), -1 where invalid.
    confidence: (H, W) float32 in [0, 1], higher = more confident.
    valid: (H, W) bool (column >= 0 exactly where valid).
    candidates: (H, W, 3) int32 best three codebook rows by distance (-1 where fewer exist).
    distances: (H, W, 3) float32 their distances (inf where absent).
    stats: counters of the search: ``path`` ("lanes", "band", "band-scan", "scalar", "nary", "syndrome" or
        "hamming-search"), ``seconds``, and for the soft paths ``evaluated`` (codeword costs
        computed, summed over pixels) and ``brute_pixels``; the "lanes" path adds
        ``second_class_pixels`` / ``second_class_blocks`` / ``blocks`` / ``pending_blocks``; the
        "band" path adds ``wide_key_pixels`` (pixels whose costs exceeded the 32-bit keys and were
        redone with 64-bit keys, see `kernels.soft_band_fold`).
    """

    column: np.ndarray
    confidence: np.ndarray
    valid: np.ndarray
    candidates: np.ndarray
    distances: np.ndarray
    stats: dict = field(default_factory=dict)


def _band_args(width: int, min_disparity: float | None, max_disparity: float | None) -> tuple[bool, int, int]:
    if min_disparity is None and max_disparity is None:
        return False, 0, 0
    for name, v in (("min_disparity", min_disparity), ("max_disparity", max_disparity)):
        if v is not None and not (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                                  and np.isfinite(v) and abs(v) <= 2**30):
            raise ValueError(f"{name}: expected a finite number of pixels (|d| <= 2**30) or None, got {v!r}")
    lo = -(10**9) if min_disparity is None else int(np.floor(min_disparity))
    hi = 10**9 if max_disparity is None else int(np.ceil(max_disparity))
    if lo > hi:
        raise ValueError(f"disparity band: expected min_disparity <= max_disparity, got {min_disparity} > {max_disparity}")
    return True, lo, hi


def _band_columns(band: tuple[bool, int, int], stripe: int) -> int:
    """Upper bound of the candidate columns per pixel of a disparity band."""
    use_band, min_d, max_d = band
    return (max_d - min_d) // stripe + 2 if use_band else 10**9


def search(
    stack: Stack,
    code: Code,
    *,
    metric: int,
    sigma_r: float,
    sigma_s: float,
    columns: int,
    band: tuple[bool, int, int],
    stripe: int,
    path: str | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Exact top-3 search: (candidates (H,W,3) i32, distances (H,W,3) f32, confidence (H,W) f32, stats).

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
    args = (stack.frames, inv, has_inv, stack.white, stack.black, stack.scale, metric, sr2, ss2, q_scale)
    t0 = time.perf_counter()
    # integer frames under the ML metric: the per-pixel variance logs from a table over the raw
    # levels (uint16: only where the image has more pixels than levels)
    levels = 0
    if metric == kernels.METRIC_ML and not has_inv:
        if stack.frames.dtype == np.uint8:
            levels = 256
        elif stack.frames.dtype == np.uint16 and h * w >= 65536:
            levels = 65536
    ltab = kernels.log_levels(levels, stack.scale, sr2, ss2)
    if code.q != 2:
        kernels.soft_nary(*args, code.q, tb.codebook, columns, use_band, min_d, max_d, stripe,
                          cand, dist, conf)
        st = {"path": "nary", "brute_pixels": h * w, "evaluated": -1}
    elif path == "band":
        stats = np.zeros((h, 3), np.int64)
        kernels.soft_band_fold(*args, ltab, tb.fold_b, tb.fold_v, tb.fold_sgn, tb.fold_row, tb.fold_usign,
                               tb.masks_t, columns, min_d, max_d, stripe, cand, dist, conf, stats)
        st = {"path": path, "brute_pixels": int(stats[:, 0].sum()), "evaluated": int(stats[:, 1].sum()),
              "wide_key_pixels": int(stats[:, 2].sum())}
    elif path == "band-scan":
        stats = np.zeros((h, 2), np.int64)
        kernels.soft_band(*args, ltab, tb.masks_t, columns, min_d, max_d, stripe, cand, dist, conf, stats)
        st = {"path": path, "brute_pixels": int(stats[:, 0].sum()), "evaluated": int(stats[:, 1].sum())}
    elif path == "lanes":
        stats = np.zeros((h, 5), np.int64)
        kernels.soft_lanes(*args, ltab, tb.masks, tb.syn_col, tb.col_bit, tb.leader, tb.leader_col,
                           tb.has_leader, tb.cls_weight, tb.cls_start, tb.cls_pstart, tb.dpos,
                           tb.dcol, columns, use_band, min_d, max_d, stripe, cand, dist, conf, stats)
        tot = stats.sum(axis=0)
        st = {"path": path, "brute_pixels": 0, "evaluated": int(tot[1]),
              "second_class_pixels": int(tot[0]), "second_class_blocks": int(tot[2]),
              "blocks": int(tot[3]), "pending_blocks": int(tot[4])}
    elif path == "scalar":
        stats = np.zeros((h, 2), np.int64)
        kernels.soft_binary(
            *args, tb.masks, tb.comp_info, tb.col_of_info, tb.comp_syn,
            tb.leader, tb.has_leader, tb.linear, tb.diff_masks, tb.diff_info, tb.class_start,
            tb.sub_start, tb.sub_p0, tb.class_sub, columns, use_band, min_d, max_d, stripe,
            BAND_BRUTE_MAX, cand, dist, conf, stats,
        )
        st = {"path": path, "brute_pixels": int(stats[:, 0].sum()), "evaluated": int(stats[:, 1].sum())}
    else:
        raise ValueError(f"path: expected 'band', 'band-scan', 'lanes' or 'scalar', got {path!r}")
    st["seconds"] = time.perf_counter() - t0
    return cand, dist, conf, st


def _hard(stack: Stack, code: Code, columns: int, band: tuple[bool, int, int], stripe: int):
    tb = code_tables(code)
    h, w = stack.shape
    if code.q == 2 and tb.linear and tb.has_leader:
        cand = np.empty((h, w, 3), np.int32)
        dist = np.empty((h, w, 3), np.float32)
        conf = np.empty((h, w), np.float32)
        inv = stack.inverse if stack.inverse is not None else stack.frames[:1, :1, :1]
        use_band, min_d, max_d = band
        t0 = time.perf_counter()
        kernels.hard_lean(
            stack.frames, inv, stack.inverse is not None, stack.white, stack.black, tb.syn_col,
            tb.info_bit, tb.leader_info, tb.leader_wt, tb.col_of_info, code.d_min, columns,
            use_band, min_d, max_d, stripe, cand, dist, conf,
        )
        return cand, dist, conf, {"path": "syndrome", "seconds": time.perf_counter() - t0}
    cand, dist, conf, st = search(stack, code, metric=kernels.METRIC_HARD, sigma_r=1.0, sigma_s=0.0,
                                  columns=columns, band=band, stripe=stripe)
    st["path"] = "hamming-search"
    return cand, dist, conf, st


def decode(
    frames: np.ndarray,
    white: np.ndarray,
    black: np.ndarray,
    code: Code,
    *,
    method: str = "soft",
    inverse: np.ndarray | None = None,
    min_disparity: float | None = None,
    max_disparity: float | None = None,
    metric: str = "ml",
    sigma_r: float = DEFAULTS["sigma_r"],
    sigma_s: float = DEFAULTS["sigma_s"],
    min_contrast: float = DEFAULTS["min_contrast"],
    min_confidence: float = DEFAULTS["min_confidence"],
    t_low: float = DEFAULTS["t_low"],
    t_high: float = DEFAULTS["t_high"],
    spatial_check: bool = True,
    columns: int | None = None,
    stripe: int = 1,
    bit_depth: int | None = None,
    levels: str = "calibration",
) -> Decoded:
    """Decode a capture of `code` into projector columns.

    frames: (n, H, W) uint8 / uint16 / float (normalised, >= 0); white, black: (H, W) frames of
    the fully lit / dark projector, same dtype; inverse: optional (n, H, W) inverse-pattern
    frames.  min/max_disparity: candidate columns for camera column x are those whose projector
    columns [row*stripe, (row+1)*stripe) meet [x - max_disparity, x - min_disparity].
    columns: codebook rows in use (projector width / stripe, default all).  levels: the on/off
    level of each pixel: "calibration" (white and black as given, the default) or "refit"
    (`edge.decode.levels.decode_refined`: decode, refit each pixel's levels by least squares
    from its own code frames plus white and black, decode again; about twice the time; not with
    inverse frames).  See the module docstring for methods, metrics and the valid mask.
    """
    if method not in METHODS:
        raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    if levels not in LEVELS:
        raise ValueError(f"levels: expected one of {', '.join(LEVELS)}, got {levels!r}")
    if levels == "refit":
        if inverse is not None:
            raise ValueError("levels: 'refit' expects no inverse frames (pattern + inverse decisions "
                             "do not use the calibration levels), got inverse=")
        from .levels import decode_refined  # levels builds on decode

        return decode_refined(frames, white, black, code, method=method, bit_depth=bit_depth,
                              min_disparity=min_disparity, max_disparity=max_disparity, metric=metric,
                              sigma_r=sigma_r, sigma_s=sigma_s, min_contrast=min_contrast,
                              min_confidence=min_confidence, t_low=t_low, t_high=t_high,
                              spatial_check=spatial_check, columns=columns, stripe=stripe)
    if metric not in METRICS:
        raise ValueError(f"metric: expected one of {', '.join(METRICS)}, got {metric!r}")
    if not (sigma_r > 0 and sigma_s >= 0):
        raise ValueError(f"sigma_r, sigma_s: expected sigma_r > 0 and sigma_s >= 0, got {sigma_r}, {sigma_s}")
    if not (np.isfinite(min_contrast) and np.isfinite(min_confidence)):
        raise ValueError(f"min_contrast, min_confidence: expected finite numbers, got {min_contrast}, {min_confidence}")
    if not (0 <= t_low <= t_high <= 1):
        raise ValueError(f"t_low, t_high: expected 0 <= t_low <= t_high <= 1, got {t_low}, {t_high}")
    if stripe < 1:
        raise ValueError(f"stripe: expected >= 1, got {stripe}")
    ncols = code.size if columns is None else int(columns)
    if not 1 <= ncols <= code.size:
        raise ValueError(f"columns: expected 1..{code.size} for code {code.name!r}, got {columns}")
    stack = validate(frames, white, black, code, inverse=inverse, bit_depth=bit_depth)
    h, w = stack.shape
    band = _band_args(w, min_disparity, max_disparity)
    if method == "hard":
        cand, dist, conf, st = _hard(stack, code, ncols, band, stripe)
    else:
        cand, dist, conf, st = search(stack, code, metric=METRICS[metric], sigma_r=sigma_r,
                                      sigma_s=sigma_s, columns=ncols, band=band, stripe=stripe)
    # eligible = contrast >= min_contrast & column >= 0 (contrast in float32), one fused pass
    column0 = np.empty((h, w), np.int32)
    eligible = np.empty((h, w), np.bool_)
    eligible_column(cand, stack.white, stack.black, np.float32(stack.scale), np.float32(min_contrast),
                    column0, eligible)
    confidence = conf
    if method in ("soft", "hard"):
        support = spatial_support(column0, conf, eligible, t_vote=t_high) if spatial_check else eligible
        column = np.empty((h, w), np.int32)
        valid = np.empty((h, w), np.bool_)
        final_mask(column0, conf, eligible, support, bool(spatial_check), np.float32(min_confidence),
                   np.float32(t_low), column, valid)
        return Decoded(column=column, confidence=confidence, valid=valid, candidates=cand, distances=dist,
                       stats=st)
    if method in ("list", "list+median"):
        column, valid = order_prior(cand, confidence, eligible, t_high=t_high, t_low=t_low)
    else:
        column = column0
    if method in ("median", "list+median"):
        column, valid = confidence_median(column, confidence, eligible & (column >= 0), t_low=t_low,
                                          t_high=t_high, candidates=cand)
    column = np.where(valid, column, -1).astype(np.int32)
    return Decoded(column=column, confidence=confidence, valid=column >= 0, candidates=cand,
                   distances=dist, stats=st)


def decode_capture(capture: CodedCapture, code: Code | None = None, *, settings=None, **overrides) -> Decoded:
    """`decode` of one `edge.capture.CodedCapture`.

    Unpacks frames, white, black, inverse, bit_depth and, where the capture states them,
    ``columns`` (codebook rows in use) and ``stripe``; code defaults to ``capture.code``.
    settings (a `DecodeSettings`, where `decode` takes one) and keyword ``overrides`` (any
    `decode` keyword, e.g. ``method``, ``sigma_r``) are passed on; an override wins over what the
    capture states.
    """
    code = capture.code if code is None else code
    if code is None:
        raise ValueError("decode_capture: expected a code (the capture does not name one), got None")
    kwargs: dict = {"inverse": capture.inverse, "bit_depth": capture.bit_depth}
    if capture.columns is not None:
        kwargs["columns"] = int(capture.columns)
    if capture.stripe is not None:
        kwargs["stripe"] = int(capture.stripe)
    if settings is not None:
        kwargs["settings"] = settings
    kwargs.update(overrides)
    return decode(capture.frames, capture.white, capture.black, code, **kwargs)
