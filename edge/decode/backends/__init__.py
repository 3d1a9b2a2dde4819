"""Decode backends: where the exact top-3 search runs.

A backend is a module with two functions (the seam every backend implements, tested against the
brute-force reference in tests/test_decode.py):

``search(stack, code, *, metric, sigma_r, sigma_s, columns, band, stripe, path=None, margin=None)``
    Exact soft top-3 over the codebook rows ``0..columns-1`` (restricted to the disparity
    ``band = (use_band, min_d, max_d)``, pixels).  ``stack``: `edge.capture.CodedCapture` (from `edge.decode.inputs.validate`);
    ``metric``: `edge.decode.kernels.METRIC_ML` / ``METRIC_NORMALIZED`` / ``METRIC_HARD``.
    Returns ``(candidates (H,W,3) int32, distances (H,W,3) float32, confidence (H,W) float32,
    stats dict)``; costs are quantised with `Q_SCALE` so every backend returns the same arrays.
    ``margin`` (distance units, or None): the second and third need only be located within it
    of the best; a slot beyond may hold row `edge.decode.kernels.BEYOND` (-2, distance inf).
    The exact top three meet this too (a backend may ignore it; the CPU's lane and band searches
    use it, `edge.decode.backends.cpu.search`).
``hard(stack, code, *, columns, band, stripe)``
    Hard decisions against (white + black)/2 (or pattern vs inverse), nearest codeword in
    Hamming distance; same return as ``search``.

Registering a backend: its module in this package plus one line in `_MODULES`.
"""

from __future__ import annotations

import importlib
import logging
from types import ModuleType

__all__ = ["BACKEND_NAMES", "Q_SCALE", "available", "get", "resolve"]

log = logging.getLogger("edge.decode")

#: Quantisation steps per unit of per-sample cost, by metric id (ML: chi-square units;
#: normalised: x**2 units; hard: Hamming units).  Shared by every backend.
Q_SCALE = {0: 256.0, 1: 16384.0, 2: 1.0}

_FELL_BACK: list[bool] = []  # "auto" has said once that it decodes on the CPU

#: backend name -> module (imported on first use: a backend's dependencies stay optional).
_MODULES = {"cpu": "edge.decode.backends.cpu", "cuda": "edge.decode.backends.cuda"}
#: The names `DecodeSettings.backend` accepts (`edge.decode.settings.BACKEND_NAMES`): every
#: registered backend, and "auto".
BACKEND_NAMES = (*_MODULES, "auto")


def available(name: str) -> bool:
    """True when backend `name` can run here (its module imports and, for "cuda", a device is
    present that numba-cuda compiles for)."""
    return name in _MODULES and _why_not(name) is None


def _why_not(name: str) -> str | None:
    """None where the registered backend `name` can run here, else why not, in one line (its
    import error, or the module's own ``why_unavailable()``)."""
    try:
        mod = importlib.import_module(_MODULES[name])
    except ImportError as e:
        return f"the {name} backend is not installed here ({e})"
    return _module_why_not(mod)


def _module_why_not(mod: ModuleType) -> str | None:
    """An imported backend's ``why_unavailable()`` (None: it can run; backends without devices
    have no such probe)."""
    probe = getattr(mod, "why_unavailable", None)
    return probe() if probe is not None else None


def resolve(name: str) -> str:
    """The concrete backend for a settings value: "auto" -> "cuda" where available, else "cpu" (logged)."""
    if name not in BACKEND_NAMES:
        raise ValueError(f"backend: expected one of {', '.join(BACKEND_NAMES)}, got {name!r}")
    if name != "auto":
        return name
    why = _why_not("cuda")
    if why is None:
        return "cuda"
    if not _FELL_BACK:  # one line per process, not one per stack
        _FELL_BACK.append(True)
        log.info("decoder backend auto: %s; decoding on the CPU", why)
    return "cpu"


def get(name: str) -> ModuleType:
    """The backend module for `name` ("auto" resolved); a clear error where it cannot run."""
    concrete = resolve(name)
    if concrete not in _MODULES:
        raise ValueError(f"backend: expected one of {', '.join(_MODULES)}, got {name!r}")
    try:
        mod = importlib.import_module(_MODULES[concrete])
    except ImportError as e:
        raise ValueError(f"backend {concrete!r}: not installed here ({e}); install the extra or use backend='cpu'") from None
    why = _module_why_not(mod)
    if why is not None:
        raise ValueError(f"backend {concrete!r}: {why}; use backend='cpu' or 'auto'")
    return mod
