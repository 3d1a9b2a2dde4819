"""`DecodeSettings`: the one decoder settings object (library, profiles, evaluations, service).

Every knob of the column decoder that is not a fact of the capture lives here; the capture's
facts (inverse frames, disparity band, columns in use, stripe width, bit depth) stay arguments of
`edge.decode.decode`.  A profile's ``[decoder]`` / ``[camera]`` sections map onto it with
`from_profile`, so any configuration an evaluation runs can be written in a profile.

Fields (units: normalised intensity, 1 = full scale of the frame dtype):

* ``method``: "hard" | "soft" | "list" | "median" | "list+median" | "sgm" (see `edge.decode.decoder`).
* ``metric``: "ml" (heteroscedastic Gaussian likelihood) | "normalized" (the paper's distance).
* ``levels``: "auto" (default: where the "error" rule applies to a binary code, the search uses
  each pixel's on / off levels split from its own n + 2 samples and the rule refits them per
  candidate, `edge.decode.posterior`; for q-ary codes (q > 2: the split assumes two levels) and
  under the "confidence" rule the calibration frames; `level_source`) | "calibration" (white /
  black taken as the on / off levels) | "refit" (a first decode, a per-pixel least-squares refit
  from the code frames and a second decode, `edge.decode.levels`).
* ``validity``: "auto" (default: "error" for the soft methods on captures without inverse
  frames, binary or q-ary, else "confidence"; `rule`) | "error" (valid where the estimated
  probability that the column is wrong, `edge.decode.posterior`, is below ``max_error``; the
  noise model is fitted from the capture) | "confidence" (the contrast / confidence thresholds
  below).
* ``max_error`` in (0, 1): the error-probability target of the "error" rule (default 0.01: at
  most about 1 in 100 published columns off by more than one codebook row); method "sgm" uses
  it under either rule (`edge.decode.sgm`).
* `MIN_SIGMA_R` <= ``sigma_r`` <= `MAX_SIGMA`, 0 <= ``sigma_s`` <= `MAX_SIGMA`: read + quantisation sigma and shot-noise coefficient
  (variance = sigma_r**2 + sigma_s**2 * I) of the search; under the "error" rule a prior only
  (the rule fits the noise model from the capture's residuals).
* ``min_contrast`` in [0, 1]: white - black floor; ``min_confidence`` in [0, 1]: (d2 - d1)/d2 floor (the
  "confidence" rule; the "error" rule has no contrast floor: contrast enters the error
  probability in noise sigmas).
* ``t_low`` <= ``t_high`` in [0, 1]: spatial-check thresholds (voters / anchors >= t_high; below
  t_low never accepted on spatial support alone).
* ``spatial_check``: accept confidence in [t_low, min_confidence) where 5x5 neighbours agree.
* ``backend``: "cpu" | "cuda" | "auto" (`edge.decode.backends.resolve`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from ..capture import MAX_SIGMA
from .backends import BACKEND_NAMES

#: The one list of each choice (profiles, the CLI and the service take theirs from here; the
#: backends from their registry, `edge.decode.backends._MODULES`).
METHODS = ("hard", "soft", "list", "median", "list+median", "sgm")
METRIC_NAMES = ("ml", "normalized")
LEVELS = ("auto", "calibration", "refit")
VALIDITY = ("auto", "error", "confidence")
#: Smallest sigma_r (normalised units): below about 7.5e-155 the cost model's reciprocal variance
#: ``1 / sigma_r**2`` overflows float64 and the costs become NaN; 1e-6 is far below any camera's
#: read and quantisation noise (a 16-bit step's quantisation sigma is 4.4e-6 of full scale) and equals the
#: variance floor the noise fit keeps for float frames (1e-12, `edge.decode.posterior.fit_noise`).
MIN_SIGMA_R = 1e-6


@dataclass(frozen=True)
class DecodeSettings:
    """Validated decoder settings (see the module docstring for each field)."""

    method: str = "soft"
    metric: str = "ml"
    levels: str = "auto"
    sigma_r: float = 0.01
    sigma_s: float = 0.03
    min_contrast: float = 0.02
    min_confidence: float = 0.3
    t_low: float = 0.05
    t_high: float = 0.3
    spatial_check: bool = True
    validity: str = "auto"
    max_error: float = 0.01
    backend: str = "cpu"

    def __post_init__(self) -> None:
        for name, allowed in (("method", METHODS), ("metric", METRIC_NAMES), ("levels", LEVELS),
                              ("validity", VALIDITY), ("backend", BACKEND_NAMES)):
            v = getattr(self, name)
            if v not in allowed:
                raise ValueError(f"{name}: expected one of {', '.join(allowed)}, got {v!r}")
        for name in ("sigma_r", "sigma_s", "min_contrast", "min_confidence", "t_low", "t_high", "max_error"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name}: expected a finite number, got {v!r}")
        if not MIN_SIGMA_R <= self.sigma_r <= MAX_SIGMA:
            raise ValueError(f"sigma_r: expected {MIN_SIGMA_R:g} <= sigma_r <= {MAX_SIGMA:g} (normalised units, "
                             "1 = full scale), "
                             f"got {self.sigma_r}")
        if not 0 <= self.sigma_s <= MAX_SIGMA:
            raise ValueError(f"sigma_s: expected 0 <= sigma_s <= {MAX_SIGMA:g} (normalised units, 1 = full scale), "
                             f"got {self.sigma_s}")
        for name in ("min_contrast", "min_confidence"):  # a contrast (normalised) and a ratio: [0, 1]
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name}: expected 0..1, got {getattr(self, name)}")
        if not (0 <= self.t_low <= self.t_high <= 1):
            raise ValueError(f"t_low, t_high: expected 0 <= t_low <= t_high <= 1, got {self.t_low}, {self.t_high}")
        if not 0 < self.max_error < 1:
            raise ValueError(f"max_error: expected a probability in (0, 1), got {self.max_error}")
        if not isinstance(self.spatial_check, bool):
            raise ValueError(f"spatial_check: expected True or False, got {self.spatial_check!r}")

    def replace(self, **changes: Any) -> "DecodeSettings":
        """A copy with `changes` applied; unknown names raise one ValueError naming them."""
        unknown = sorted(set(changes) - set(FIELDS))
        if unknown:
            raise ValueError(f"decoder settings: unknown option(s) {', '.join(unknown)}; "
                             f"expected any of {', '.join(FIELDS)}")
        return dataclasses.replace(self, **changes) if changes else self

    def with_noise(self, a: float, beta: float) -> "DecodeSettings":
        """A copy whose sigmas are those of a fitted noise model ``var(I) = a + beta * I``
        (normalised units): ``sqrt(a)``, ``sqrt(beta)``, held to the settings' bounds (a fit on a
        pathological capture can exceed `MAX_SIGMA`; the capture is still decoded)."""
        return self.replace(sigma_r=min(max(math.sqrt(max(a, 0.0)), MIN_SIGMA_R), MAX_SIGMA),
                            sigma_s=min(math.sqrt(max(beta, 0.0)), MAX_SIGMA))

    def rule(self, has_inverse: bool) -> str:
        """The validity rule these settings apply to a capture with / without inverse frames:
        "error" or "confidence".  ``validity="auto"``: "error" for the soft methods on captures
        without inverse frames; "confidence" for "hard" and for pattern + inverse captures (the
        full-exposure captures that rule was validated on; "error" takes them when asked, see
        the README).

        The same for binary and q-ary (q > 2) codes, but with ``levels="auto"`` the error rule
        of a q-ary code runs on the calibration levels, not on the two-level split
        (`level_source`): on q-ary captures at fixed total exposure (tools/eval_nary.py, both
        generators, sigma_s 0.01-0.04) the split throws the search off (nary8-3: 99-100 % of lit
        pixels wrong or unpublished at sigma_s 0.01), while the error rule on the calibration
        levels is the best error-rule variant on every code and noise level measured (nary8-3 at
        sigma_s 0.01: 13-23 %; docs/results/nary).  The confidence rule publishes more of the
        noisiest q-ary captures and errs less there, but mostly 2-9x more of what it publishes is
        wrong and it has no error target."""
        if self.validity == "error":
            return "error"
        if self.validity == "confidence" or has_inverse or self.method == "hard":
            return "confidence"
        return "error"

    def level_source(self, rule: str, q: int) -> str:
        """Where the on / off levels of a code with `q` symbols come from under `rule` ("error"
        or "confidence", as `rule` returns): "split" (each pixel's two-means split,
        `edge.decode.posterior.split_levels`: ``levels="auto"`` under the error rule, binary
        codes only), "calibration" (white / black) or "refit"."""
        if rule not in ("error", "confidence"):
            raise ValueError(f"rule: expected 'error' or 'confidence', got {rule!r}")
        if self.levels != "auto":
            return self.levels
        return "split" if rule == "error" and int(q) == 2 else "calibration"

    def as_dict(self) -> dict[str, Any]:
        """The settings as a plain dict (field name -> value)."""
        return dataclasses.asdict(self)


FIELDS = tuple(f.name for f in dataclasses.fields(DecodeSettings))
#: The library's defaults (what `edge.decode.decode` uses with no options).
DEFAULT_SETTINGS = DecodeSettings()


def from_profile(profile: Any) -> DecodeSettings:
    """The `DecodeSettings` a validated profile asks for (duck-typed: reads attributes only).

    ``[decoder]`` keys named like a field override the library default; the noise model comes
    from ``[camera] sigma_r / sigma_s`` (sigma_r floored at 1e-4: a noiseless simulated camera
    still quantises).  Keys a profile does not have keep the library default.
    """
    dec = profile.decoder
    values = {name: getattr(dec, name) for name in FIELDS if hasattr(dec, name)}
    cam = getattr(profile, "camera", None)
    if cam is not None and "sigma_r" not in values and hasattr(cam, "sigma_r"):
        values["sigma_r"] = max(float(cam.sigma_r), 1e-4)
    if cam is not None and "sigma_s" not in values and hasattr(cam, "sigma_s"):
        values["sigma_s"] = float(cam.sigma_s)
    return DEFAULT_SETTINGS.replace(**values)
