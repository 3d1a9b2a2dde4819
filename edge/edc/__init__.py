"""Error detection (CRC) driven adaptive re-projection, and the Gupta et al. 2011 ensemble baseline.

Public API::

    AdaptiveScan(scheme, projector_width, height, *, stripe=1, max_rounds=3, binarisation="self",
                 neighbour_tolerance=3, noise=(sigma_r, sigma_s), keep_guess=True, masking=True, ...)
        .start() -> frames; .update(captured[, guess=]) -> RoundResult; .next_frames() -> frames | None;
        .result(); .guesses (round-1 single-pass columns); .run(capture[, guess=]) -> AdaptiveResult
        (the one driver: start, then update(capture(frames)) every round until done)
        Only open pixels are decoded per round (sparse kernels, `edge.edc._kernels`); verified
        columns are never replaced; reported pixels stay reported (never worse than round 1).
    run_adaptive(scene, camera, scheme, *, rng=0, stripe=1, max_rounds=3, ...) -> AdaptiveResult
    EdcScheme(code), EnsembleScheme(codes=None, min_agree=2), gupta_codes(k), ensemble_vote(columns)
    maxminsw_code(k=10) -> Code (family "maxminsw"; k = 10: cyclic, every stripe >= 7 columns)
    unmeasurable_columns(scheme) -> (size,) bool (constant words: never decoded when self-calibrated)
    lookup_columns(frames, white, black, code) -> column or -1 (the EDC check)
"""

from ..numba_cache import install as _install_cache_lock

_install_cache_lock()  # before any kernel of this package is compiled or loaded (edge.numba_cache)

from .adaptive import AdaptiveResult, AdaptiveScan, RoundResult, run_adaptive
from .gupta import EnsembleScheme, ensemble_vote, gupta_codes
from .lookup import lookup_columns
from .maxminsw import maxminsw_code
from .scheme import EdcScheme, unmeasurable_columns

__all__ = [
    "AdaptiveResult", "AdaptiveScan", "EdcScheme", "EnsembleScheme", "RoundResult", "ensemble_vote",
    "gupta_codes", "lookup_columns", "maxminsw_code", "run_adaptive", "unmeasurable_columns",
]
