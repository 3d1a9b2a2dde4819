"""Stage 2 of `edge.decode.decode`: the candidate search (exact top-3 per pixel, on a backend).

Interface: a validated `edge.decode.inputs.CodedCapture` (frames (n, H, W), white / black (H, W), raw
values times ``stack.scale`` = normalised intensity) and the settings' ``method``, ``metric``,
``sigma_r``, ``sigma_s`` and ``backend`` -> `Candidates`:

* ``candidates`` (H, W, 3) int32: the three best codebook rows (projector column // stripe),
  best first, -1 where fewer exist (white <= black, empty disparity band); searched with a
  ``margin``, the second and third only where within it of the best (-2 = `kernels.BEYOND`, a
  codeword further behind that was not located; the error rule's soft method);
* ``distances`` (H, W, 3) float32: their distances (ML: -2 log-likelihood up to a per-pixel
  constant; normalised: sum of squared normalised errors; hard: Hamming), inf where absent;
* ``confidence`` (H, W) float32 in [0, 1]: ``(d2 - d1) / d2`` (hard syndrome path:
  ``max(0, d_min - 2 d1) / (d_min - d1)``), 0 where undecoded;
* ``stats``: the backend's counters (``path``, ``seconds``, ...; see `edge.decode.Decoded`).

The facts of the capture come as arguments: ``columns`` (codebook rows in use), ``band``
(`band_args`: ``(use_band, min_d, max_d)`` in camera pixels) and ``stripe`` (projector columns
per codebook row).  Which backend runs is ``settings.backend`` (`edge.decode.backends`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..codes import Code
from .backends import get as get_backend
from ..capture import CodedCapture
from .inputs import check_code, codebook_rows
from .kernels import METRIC_ML, METRIC_NORMALIZED
from .settings import METRIC_NAMES, DecodeSettings

#: settings.metric -> metric id of the backends (`edge.decode.kernels`).
METRICS = {"ml": METRIC_ML, "normalized": METRIC_NORMALIZED}
assert tuple(METRICS) == METRIC_NAMES


@dataclass(frozen=True)
class Candidates:
    """Output of the candidate search (see the module docstring for shapes, dtypes and units)."""

    candidates: np.ndarray
    distances: np.ndarray
    confidence: np.ndarray
    stats: dict = field(default_factory=dict)


def check_call(code: Code, settings: DecodeSettings, *, inverse: np.ndarray | None, columns: int | None,
               stripe: int) -> int:
    """The capture facts `decode` checks for every backend (one ValueError each; a TypeError for
    a `code` that is not a `edge.codes.Code`); returns the codebook rows in use (``columns``, an
    integer, default all of ``code``: `inputs.codebook_rows`)."""
    check_code(code)
    if settings.levels == "refit" and inverse is not None:
        raise ValueError("levels: 'refit' expects no inverse frames (pattern + inverse decisions "
                         "do not use the calibration levels), got inverse=")
    if isinstance(stripe, bool) or not isinstance(stripe, (int, np.integer)) or stripe < 1:
        raise ValueError(f"stripe: expected an integer >= 1 (projector columns per code cell), got {stripe!r}")
    return codebook_rows(code, columns)


def band_args(min_disparity: float | None, max_disparity: float | None) -> tuple[bool, int, int]:
    """``(use_band, min_d, max_d)`` of a disparity band in camera pixels (floor / ceil to integers;
    no band when both are None); one ValueError for a non-finite, huge or inverted band."""
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


def search_candidates(stack: CodedCapture, code: Code, settings: DecodeSettings, *, columns: int,
                      band: tuple[bool, int, int], stripe: int, margin: float | None = None) -> Candidates:
    """Exact top-3 search of `stack` on ``settings.backend``: the hard-decision search for
    ``method="hard"``, the soft search under ``settings.metric`` otherwise.  margin (soft search,
    CPU backend; None: none): the second and third are located only within ``margin`` of the
    best (`edge.decode.backends.cpu.search`; a slot beyond it may hold row -2)."""
    backend = get_backend(settings.backend)
    if settings.method == "hard":
        cand, dist, conf, st = backend.hard(stack, code, columns=columns, band=band, stripe=stripe)
    else:
        extra = {} if margin is None else {"margin": margin}
        cand, dist, conf, st = backend.search(stack, code, metric=METRICS[settings.metric], sigma_r=settings.sigma_r,
                                              sigma_s=settings.sigma_s, columns=columns, band=band, stripe=stripe,
                                              **extra)
    return Candidates(candidates=cand, distances=dist, confidence=conf, stats=st)
