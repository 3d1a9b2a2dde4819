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

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..capture import CodedCapture
from ..codes import Code
from . import kernels
from .inputs import Stack, validate
from .backends import Q_SCALE, get as get_backend
from .settings import DEFAULT_SETTINGS, LEVELS, METHODS, METRIC_NAMES, DecodeSettings
from .spatial import confidence_median, order_prior, spatial_support
from .validity import eligible_column, final_mask

METRICS = {"ml": kernels.METRIC_ML, "normalized": kernels.METRIC_NORMALIZED}
assert tuple(METRICS) == METRIC_NAMES

#: Documented defaults of `decode`'s thresholds and noise model (`DEFAULT_SETTINGS`, as a dict;
#: chosen on the real OpenCV Gray-code capture, see tests/test_decode_real.py).
DEFAULTS = {k: v for k, v in DEFAULT_SETTINGS.as_dict().items()
            if k in ("sigma_r", "sigma_s", "min_contrast", "min_confidence", "t_low", "t_high")}


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


def decode(
    frames: np.ndarray,
    white: np.ndarray,
    black: np.ndarray,
    code: Code,
    *,
    settings: DecodeSettings | None = None,
    inverse: np.ndarray | None = None,
    min_disparity: float | None = None,
    max_disparity: float | None = None,
    columns: int | None = None,
    stripe: int = 1,
    bit_depth: int | None = None,
    **options: Any,
) -> Decoded:
    """Decode a capture of `code` into projector columns.

    frames: (n, H, W) uint8 / uint16 / float (normalised, >= 0); white, black: (H, W) frames of
    the fully lit / dark projector, same dtype; inverse: optional (n, H, W) inverse-pattern
    frames.  min/max_disparity: candidate columns for camera column x are those whose projector
    columns [row*stripe, (row+1)*stripe) meet [x - max_disparity, x - min_disparity].
    columns: codebook rows in use (projector width / stripe, default all).  bit_depth:
    significant bits of uint16 frames (default 16).

    settings: a `DecodeSettings` (default `DEFAULT_SETTINGS`); ``options`` are any of its fields
    (``method="list"``, ``sigma_r=0.02``, ...) applied on top, unknown names raise one
    ValueError.  ``levels="refit"`` (`edge.decode.levels.decode_refined`) decodes, refits each
    pixel's on/off levels by least squares from its own code frames plus white and black, and
    decodes again (about twice the time; not with inverse frames).  See the module docstring for
    methods, metrics and the valid mask.
    """
    s = (DEFAULT_SETTINGS if settings is None else settings).replace(**options)
    method, metric, sigma_r, sigma_s = s.method, s.metric, s.sigma_r, s.sigma_s
    min_contrast, min_confidence, t_low, t_high = s.min_contrast, s.min_confidence, s.t_low, s.t_high
    spatial_check = s.spatial_check
    if s.backend != "cpu":  # device backends (edge.decode.backends.cuda) run levels, search and mask whole
        whole = getattr(get_backend(s.backend), "decode_whole", None)
        if whole is not None:
            return whole(frames, white, black, code, s, inverse=inverse, min_disparity=min_disparity,
                         max_disparity=max_disparity, columns=columns, stripe=stripe, bit_depth=bit_depth)
    if s.levels == "refit":
        if inverse is not None:
            raise ValueError("levels: 'refit' expects no inverse frames (pattern + inverse decisions "
                             "do not use the calibration levels), got inverse=")
        from .levels import decode_refined  # levels builds on decode

        return decode_refined(frames, white, black, code, method=s.method, settings=s.replace(levels="calibration"),
                              bit_depth=bit_depth, min_disparity=min_disparity,
                              max_disparity=max_disparity, columns=columns, stripe=stripe)
    if metric not in METRICS:
        raise ValueError(f"metric: expected one of {', '.join(METRICS)}, got {metric!r}")
    if stripe < 1:
        raise ValueError(f"stripe: expected >= 1, got {stripe}")
    ncols = code.size if columns is None else int(columns)
    if not 1 <= ncols <= code.size:
        raise ValueError(f"columns: expected 1..{code.size} for code {code.name!r}, got {columns}")
    stack = validate(frames, white, black, code, inverse=inverse, bit_depth=bit_depth)
    h, w = stack.shape
    band = _band_args(w, min_disparity, max_disparity)
    backend = get_backend(s.backend)
    if method == "hard":
        cand, dist, conf, st = backend.hard(stack, code, columns=ncols, band=band, stripe=stripe)
    else:
        cand, dist, conf, st = backend.search(stack, code, metric=METRICS[metric], sigma_r=sigma_r,
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
