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
* ``"sgm"``: semi-global regularisation of the top-3 candidates with a smoothness prior on
  disparity (`edge.decode.sgm`; beyond the paper).  Under the "error" rule on the posterior's
  likelihoods, each uncertain pixel widened by one state, its neighbours' column scored on its
  own samples (`edge.decode.propagate`; `sgm_stage`), candidates re-ordered by aggregated cost
  and error re-derived from it; under the
  "confidence" rule on the search's ML distances, valid where eligible and its error <
  ``max_error``.

``metric="ml"`` (default) or ``"normalized"`` (the paper's plain normalised distance) selects the
per-sample costs for the soft methods.  ``levels="refit"`` re-estimates each pixel's on/off
levels from its code frames (`edge.decode.levels`) before the final decode.  The valid mask is
``eligible & (confidence >= min_confidence | (confidence >= t_low & supported))`` where
``eligible = contrast >= min_contrast & column >= 0`` and ``supported`` means the column is
within 1 of the median column of the eligible pixels with confidence >= t_high in the 5x5
neighbourhood (at least 3 voters; `spatial.spatial_support`, columns unchanged).  Pass
``spatial_check=False`` for the plain confidence + contrast mask.  "list" and "median" use the
validity rules of `spatial.order_prior` / `spatial.confidence_median`.  Then, for every method
but "hard", the goodness-of-fit test (`confidence_fit`, `edge.decode.misfit`): a published
column whose residuals are far beyond the noise is not published.  ``(d2 - d1) / d2`` cannot see
that the truth is outside the search (a surface beyond the disparity band, columns beyond
``columns``): there the two best codewords are both wrong and the ratio can be high.  Noise
model: `edge.decode.posterior.fit_noise` of the search's best candidates; scale: the misfit
statistic's median over the published pixels; captures too small for the noise fit are not
tested.  "hard" is left as it is (the test costs several times its decode).  The CUDA backend's
confidence path (`backends.cuda.pipeline.finish`) does not run this stage yet.  Defaults:
`DEFAULTS` (chosen on the real OpenCV Gray-code capture, see tests/test_decode_real.py).

`decode` is a composition of five stages, each driven by the one `DecodeSettings`:

1. inputs (`edge.decode.inputs.validate`): the capture -> `CodedCapture` (raw frames, ``scale``);
2. levels (`edge.decode.levels.estimate_levels`): "calibration" keeps white / black, "refit"
   refits them from a first candidate search (CodedCapture -> CodedCapture);
3. candidate search (`edge.decode.search.search_candidates`, on ``settings.backend``): CodedCapture ->
   `Candidates` (top-3 rows, distances, confidence, stats);
4. spatial methods (`edge.decode.validity.eligibility`, then `edge.decode.spatial.spatial_stage`):
   eligible pixels, the support test or the order prior / median filter, with the stripe width;
5. validity rule (`edge.decode.validity.valid_mask`, then `confidence_fit`): -> column and valid mask.

Under the "error" rule (`_decode_error_rule`) stages 2-5 are the split levels, the search, the
noise fit and the posterior (`edge.decode.posterior`), then `publish_error_rule` on the host for
every backend: the goodness-of-fit test (`edge.decode.misfit`), the method on P(wrong), and no
published column that misfits.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..capture import CodedCapture
from ..codes import Code
from .backends import Q_SCALE
from .backends import get as get_backend
from .inputs import NoPatternContrast, validate
from .levels import estimate_levels
from .misfit import check_fit, fit_published, fits
from .posterior import SKIP_MARGIN, Noise, fit_noise, normalised32, posterior, split_levels
from .propagate import propagate
from .search import METRICS, band_args, check_call, search_candidates
from .settings import DEFAULT_SETTINGS, METHODS, DecodeSettings
from .sgm import Regularised
from .sgm import from_posterior as sgm_from_posterior
from .spatial import error_rule_spatial, published_error, spatial_stage
from .validity import eligibility, valid_mask

__all__ = ["DEFAULTS", "METHODS", "METRICS", "Q_SCALE", "Decoded", "decode", "decode_refined"]

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
        ``second_class_pixels`` / ``second_class_blocks`` / ``blocks`` / ``pending_blocks`` /
        ``zero_set_pixels`` (a full-space code's ties at cost 0 resolved directly) and, searched
        with a margin (the "error" rule's soft method), ``margin_pixels`` / ``margin_blocks``
        (pixels finished by it, blocks that skipped their lightest class) and ``margin_lanes`` (of
        those pixels, the ones finished alone in a block that did not), with
        ``first_class_blocks`` (lightest-class runs, a block or a queue of lanes); the
        "band" path adds ``wide_key_pixels`` (pixels whose costs exceeded the 32-bit keys and were
        redone with 64-bit keys, see `kernels.soft_band_fold`) and ``margin_blocks``.  Under the "error" rule it adds
        ``rule``, ``levels``, ``level_source`` ("split", "calibration" or "refit",
        `DecodeSettings.level_source`) and the fitted noise model ``noise_a`` / ``noise_beta`` (variance
        ``a + beta * I``, normalised units) with ``noise_fitted``.  Under the "confidence" rule
        (every method but "hard", CPU backend) it adds the goodness-of-fit test's
        ``misfit_noise``, ``misfit_threshold`` and ``misfit_dropped`` (`confidence_fit`).
    error: (H, W) float32 estimated probability that ``candidates[..., 0]`` is more than one
        codebook row off (`edge.decode.posterior`; the "error" validity rule), else None; with
        methods "list" / "median", where the method published another candidate, that
        candidate's (`edge.decode.spatial.published_error`: the pixel's own evidence, so it may be
        above ``max_error`` where neighbours' support published the column).  Under
        that rule candidates / distances are the posterior's (re-ordered by it, distances the
        negative log-likelihoods plus the capture's level prior, `edge.decode.level_prior`; with
        methods "soft" and "sgm" a second or third more than `posterior.SKIP_MARGIN` behind the
        best is not searched for and is -1, distance inf) and confidence is ``(d2 - d1) / d2`` of their Mahalanobis parts; with method "sgm", candidates are re-ordered by aggregated cost and error is the
        regularised one (`edge.decode.sgm`).
    """

    column: np.ndarray
    confidence: np.ndarray
    valid: np.ndarray
    candidates: np.ndarray
    distances: np.ndarray
    stats: dict = field(default_factory=dict)
    error: np.ndarray | None = None


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

    frames: (n, H, W) uint8 / uint16 / float (normalised to [0, 1]); white, black: (H, W) frames of
    the fully lit / dark projector, same dtype; inverse: optional (n, H, W) inverse-pattern
    frames.  min/max_disparity: candidate columns for camera column x are those whose projector
    columns [row*stripe, (row+1)*stripe) meet [x - max_disparity, x - min_disparity].
    columns: codebook rows in use (projector width / stripe, default all; an integer).  stripe:
    projector columns per codebook row (an integer >= 1).  bit_depth: significant bits of
    integer frames, an integer that holds every value (uint16: None = detected from the data,
    the smallest of 8, 10, 12, 14, 16 bits that holds its largest value; uint8: None = 8;
    ignored for floats; `edge.capture.bit_depth_of`).  Either byte order.  Returns a
    `Decoded` of (H, W) arrays (see there for dtypes and units).  Bad input raises one ValueError
    naming it (`NoPatternContrast` where white <= black everywhere); a `code` or `settings` of
    the wrong type one TypeError.

    settings: a `DecodeSettings` (default `DEFAULT_SETTINGS`); ``options`` are any of its fields
    (``method="list"``, ``sigma_r=0.02``, ...) applied on top, unknown names raise one
    ValueError.  ``levels="refit"`` (`edge.decode.levels`) searches once, refits each
    pixel's on/off levels by least squares from its own code frames plus white and black, and
    searches again (about twice the time; not with inverse frames).  See the module docstring for
    methods, metrics and the valid mask.
    """
    s = _settings(settings, options)
    if s.backend != "cpu":  # device backends (edge.decode.backends.cuda) run levels, search, validity rule whole
        whole = getattr(get_backend(s.backend), "decode_whole", None)
        if whole is not None:
            return whole(frames, white, black, code, s, inverse=inverse, min_disparity=min_disparity,
                         max_disparity=max_disparity, columns=columns, stripe=stripe, bit_depth=bit_depth)
    return _decode(frames, white, black, code, s, inverse=inverse, min_disparity=min_disparity,
                   max_disparity=max_disparity, columns=columns, stripe=stripe, bit_depth=bit_depth)


def decode_refined(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code, *,
                   iterations: int = 1, settings: DecodeSettings | None = None, inverse: np.ndarray | None = None,
                   min_disparity: float | None = None, max_disparity: float | None = None,
                   columns: int | None = None, stripe: int = 1, bit_depth: int | None = None,
                   **options: Any) -> Decoded:
    """`decode` with ``levels="refit"`` and `iterations` refits (0: `levels.initial_levels` only).

    Pass 0 searches with the initial levels ("hard" for method "hard", else "soft"); each
    refit uses the previous pass's top-1 columns (every pixel, no valid mask); the last search
    uses the settings' method.  ``validity="auto"`` means the "confidence" rule here.  Other
    arguments as for `decode`.
    """
    s = _settings(settings, options).replace(levels="refit")
    if s.validity == "auto":  # the refinement study's rule (the "error" rule refits per candidate itself)
        s = s.replace(validity="confidence")
    return _decode(frames, white, black, code, s, inverse=inverse, min_disparity=min_disparity,
                   max_disparity=max_disparity, columns=columns, stripe=stripe, bit_depth=bit_depth,
                   iterations=iterations)


def _settings(settings: DecodeSettings | None, options: dict[str, Any]) -> DecodeSettings:
    """`settings` (default `DEFAULT_SETTINGS`) with ``options`` applied; one TypeError where
    `settings` is not a `DecodeSettings` (a dict of options goes in as keywords)."""
    if settings is not None and not isinstance(settings, DecodeSettings):
        raise TypeError(f"settings: expected a DecodeSettings or None (options as keywords: "
                        f"decode(..., method='list')), got {type(settings).__name__}")
    return (DEFAULT_SETTINGS if settings is None else settings).replace(**options)


#: The margin of a search whose best candidate alone is read (the levels' refit): none, so the
#: second and third are never located (`search_candidates`; the best stays exact).
TOP1_MARGIN = 0.0


def _decode(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code, s: DecodeSettings, *,
            inverse: np.ndarray | None, min_disparity: float | None, max_disparity: float | None,
            columns: int | None, stripe: int, bit_depth: int | None, iterations: int = 1) -> Decoded:
    """The stages of the module docstring, in order."""
    ncols = check_call(code, s, inverse=inverse, columns=columns, stripe=stripe)
    band = band_args(min_disparity, max_disparity)
    stack = validate(frames, white, black, code, inverse=inverse, bit_depth=bit_depth)
    if s.rule(stack.inverse is not None) == "error":
        return _decode_error_rule(stack, code, s, ncols=ncols, band=band, stripe=stripe)
    first = s.replace(method="hard" if s.method == "hard" else "soft")

    def top1(st: CodedCapture) -> np.ndarray:
        return search_candidates(st, code, first, columns=ncols, band=band, stripe=stripe,
                                 margin=TOP1_MARGIN).candidates[..., 0]

    searched = estimate_levels(stack, code, s.level_source("confidence", code.q), top1, iterations=iterations)
    found = search_candidates(searched, code, s, columns=ncols, band=band, stripe=stripe)
    column0, eligible = eligibility(searched, found.candidates, s.min_contrast)
    spatial = spatial_stage(s, found.candidates, found.confidence, column0, eligible, stripe=stripe,
                            distances=found.distances, choices=band_choices(ncols, band, stripe), columns=ncols)
    column, valid = valid_mask(spatial, found.confidence, eligible, s)
    column, valid, fit = confidence_fit(searched, code, s, column0, column)
    return Decoded(column=column, confidence=found.confidence, valid=valid, candidates=found.candidates,
                   distances=found.distances, stats=dict(found.stats, **fit))


def confidence_fit(stack: CodedCapture, code: Code, s: DecodeSettings, best: np.ndarray,
                   column: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """The "confidence" rule's goodness-of-fit test (host; every method but "hard"): a published
    column whose residuals are far beyond the noise is not published (`edge.decode.misfit`).

    Noise model: `edge.decode.posterior.fit_noise` of the search's best candidates ``best``
    (H, W) int (the error rule's fit, on the samples of ``stack``).  Where it could not be fitted
    (fewer than `posterior.MIN_FIT_PIXELS` pixels) nothing is tested: the settings' sigma_r /
    sigma_s weigh this rule's search but are not checked against the capture, and a prior
    several times below the camera's noise would reject right columns.  Scale and threshold:
    `misfit.fit_published` over the published pixels.  stack: the `CodedCapture` the search
    read (the validated capture; with ``levels="refit"`` its float32 frames and refitted levels,
    `edge.decode.levels`, which stand in for white / black: a calibration frame the refit
    overruled does not reject the pixel); column (H, W) int32 the rule's columns, -1 where
    invalid.  Returns (column (H, W) int32, -1 where invalid; valid (H, W) bool; stats:
    ``misfit_noise`` (a, beta) of the variance ``a + beta * I``, normalised units, or None where
    not fitted, ``misfit_threshold`` (inf where nothing was tested) and ``misfit_dropped``, the
    published pixels the test took out; empty for "hard", whose columns are returned as they
    are)."""
    column = np.asarray(column, np.int32)
    if s.method == "hard":  # the fast path: the test would cost several times its decode
        return column, column >= 0, {}
    noise = fit_noise(stack.frames, stack.white, stack.black, float(np.float32(stack.scale)), code, best,
                      prior=(s.sigma_r, s.sigma_s), inverse=stack.inverse)
    if not noise.fitted:
        return column, column >= 0, untested_fit()
    valid, threshold = fit_published(stack, code, (noise.a, noise.beta), column)
    stats = {"misfit_noise": (noise.a, noise.beta), "misfit_threshold": threshold,
             "misfit_dropped": int((column >= 0).sum() - valid.sum())}
    return np.where(valid, column, -1).astype(np.int32), valid, stats


def untested_fit() -> dict:
    """`confidence_fit`'s stats where its noise could not be fitted: nothing was tested."""
    return {"misfit_noise": None, "misfit_threshold": float("inf"), "misfit_dropped": 0}


def band_choices(ncols: int, band: tuple[bool, int, int], stripe: int) -> int:
    """N of the error rule: the codebook rows a pixel can decode to (all rows in use, or the rows
    a disparity band of ``max_d - min_d`` camera pixels meets)."""
    use, lo, hi = band
    if not use:
        return ncols
    return int(max(1, min(ncols, (hi - lo) // stripe + 2)))


def _decode_error_rule(stack: CodedCapture, code: Code, s: DecodeSettings, *, ncols: int,
                       band: tuple[bool, int, int], stripe: int) -> Decoded:
    """The stages under the "error" validity rule (`edge.decode.posterior`): split levels (with
    ``levels="auto"`` and a binary code, `DecodeSettings.level_source`), the candidate search,
    the noise fit, the posterior of the top three, the spatial methods on ``1 - error``, and
    ``error < max_error``."""
    scale = np.float32(stack.scale)
    source = s.level_source("error", code.q)
    if source == "refit":
        first = s.replace(method="hard" if s.method == "hard" else "soft")
        searched = estimate_levels(stack, code, "refit", lambda st: search_candidates(
            st, code, first, columns=ncols, band=band, stripe=stripe, margin=TOP1_MARGIN).candidates[..., 0])
    elif source == "split":
        on, off, first_noise = split_levels(stack.frames, stack.white, stack.black, float(scale),
                                            prior=(s.sigma_r, s.sigma_s), inverse=stack.inverse)
        searched = split_capture(stack, on, off)
        s = s.with_noise(first_noise.a, first_noise.beta)
    else:
        searched = stack
    # the posterior rescores only candidates within SKIP_MARGIN of the best (the others: distance
    # inf), so the search need not locate the others for "soft", nor for "sgm", whose stages treat
    # a candidate of distance inf as absent (propagate scores such a row afresh, sgm's unaries
    # give it the absent state's cost); "list" / "median" may publish any of the top 3 that the
    # neighbours support, whatever its distance, so they get the exact top 3
    margin = SKIP_MARGIN if s.method in ("soft", "sgm") else None
    found = search_candidates(searched, code, s, columns=ncols, band=band, stripe=stripe, margin=margin)
    best = found.candidates[..., 0]
    noise = fit_noise(stack.frames, stack.white, stack.black, float(scale), code, best,
                      prior=(s.sigma_r, s.sigma_s), inverse=stack.inverse)
    post = posterior(stack.frames, stack.white, stack.black, float(scale), code, found.candidates, noise,
                     choices=band_choices(ncols, band, stripe), inverse=stack.inverse, distances=found.distances)
    column, valid, candidates, distances, error = publish_error_rule(
        stack, code, s, noise, post.candidates, post.distances, post.error, rows=ncols,
        choices=band_choices(ncols, band, stripe), stripe=stripe, misfit=post.misfit)
    stats = dict(found.stats, noise_a=noise.a, noise_beta=noise.beta, noise_fitted=noise.fitted,
                 rule="error", levels=s.levels, level_source=source)
    return Decoded(column=column, confidence=post.confidence, valid=valid, candidates=candidates,
                   distances=distances, stats=stats, error=error)


def publish_error_rule(stack: CodedCapture, code: Code, s: DecodeSettings, noise: Noise, candidates: np.ndarray,
                       distances: np.ndarray | None, error: np.ndarray, *, rows: int, choices: int,
                       stripe: int, misfit: np.ndarray | None = None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """The error rule's host stages after the posterior (every backend): the goodness-of-fit test
    (`edge.decode.misfit.check_fit`: the methods see a misfitting best candidate's P(wrong) as 1),
    the method ("soft" / "hard": P(wrong) < max_error; "list" / "median": `error_rule_spatial`;
    "sgm": `sgm_stage`), and no published column that misfits.  candidates (H, W, 3) int32 (the
    CUDA backend's soft path: its published columns in [..., 0], -1 elsewhere), distances (H, W,
    3) (required by "sgm", "list" and "median") or None, error (H, W) float32 P(wrong) of
    candidates[..., 0]; misfit (H, W)
    float32 the posterior's goodness-of-fit statistic of its best candidates (`Posterior.misfit`),
    or None to compute it from the samples.  Returns
    (column (H, W) int32 -1 where invalid, valid, candidates, distances, error): the error is the
    posterior's (among the searched codewords), with "sgm" the regularised one, with "list" /
    "median" that of the column published (`published_error`)."""
    column0 = np.ascontiguousarray(candidates[..., 0])
    target = s.max_error  # the one error-probability target
    seen, threshold = check_fit(stack, code, (noise.a, noise.beta), column0, error, target, misfit)
    if s.method == "sgm":
        reg = sgm_stage(stack, code, candidates, distances, seen, noise, max_error=target, rows=rows,
                        choices=choices, stripe=stripe)
        column, valid = reg.column, reg.valid
        candidates, distances, error = reg.candidates, reg.distances, reg.error
    elif s.method in ("soft", "hard"):
        valid = (seen < np.float32(target)) & (column0 >= 0)
        column = np.where(valid, column0, -1).astype(np.int32)
    else:
        column, valid = error_rule_spatial(s, candidates, seen, stripe=stripe)
    if s.method not in ("soft", "hard"):  # a column the method chose must explain the samples too
        valid = valid & fits(stack, code, (noise.a, noise.beta), column, threshold)
        column = np.where(valid, column, -1).astype(np.int32)
    if s.method in ("list", "median", "list+median"):  # the error of the column published, not of the best
        error = published_error(candidates, distances, error, column)
    return column, valid, candidates, distances, error


def sgm_stage(stack: CodedCapture, code: Code, candidates: np.ndarray, distances: np.ndarray, error: np.ndarray,
              noise: Noise, *, max_error: float, rows: int, choices: int, stripe: int) -> Regularised:
    """Method "sgm" under the "error" rule (every backend runs this on the host): the posterior's
    candidates (H, W, 3), distances ``L_k`` and error (H, W) of `stack`, widened by one state per
    uncertain pixel (`edge.decode.propagate`, its neighbours' column scored with `noise`), then
    regularised (`edge.decode.sgm.from_posterior`); candidates / distances come back (H, W, 3),
    re-ordered by aggregated cost."""
    wide = propagate(stack.frames, stack.white, stack.black, float(stack.scale), code, candidates, distances, error,
                     noise, max_error=max_error, choices=choices, rows=rows, inverse=stack.inverse)
    reg = sgm_from_posterior(wide.candidates, wide.distances, error, stripe=stripe, max_error=max_error,
                             choices=choices, scored=3)
    return reg._replace(candidates=np.ascontiguousarray(reg.candidates[..., :3]),
                        distances=np.ascontiguousarray(reg.distances[..., :3]),
                        costs=np.ascontiguousarray(reg.costs[..., [0, 1, 2, 4]]))


def split_capture(stack: CodedCapture, on: np.ndarray, off: np.ndarray) -> CodedCapture:
    """The search's input under the split levels: the frames (and inverse frames) as float32
    normalised intensities (`posterior.normalised32`), white / black = the (H, W) float32 split
    levels on / off.  What `inputs.validate` would return for these arrays (float32 samples of
    a validated integer or float capture are finite and >= 0; its white > black check is kept)."""
    if not np.greater(on, off).any():
        raise NoPatternContrast()
    scale = np.float32(stack.scale)
    inv = None if stack.inverse is None else normalised32(stack.inverse, scale)
    return CodedCapture(frames=normalised32(stack.frames, scale), white=np.ascontiguousarray(on),
                        black=np.ascontiguousarray(off), inverse=inv, code=stack.code, bit_depth=None)


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
