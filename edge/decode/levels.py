"""Decision-directed estimation of each pixel's "on" and "off" levels.

`decode` takes the all-on (white) and all-off (black) calibration frames as the exact mean
levels of a pixel.  In the paper's acquisition they are single frames at the per-frame exposure
T/n, so they are as noisy as one code frame, and that error is common to all n samples of the
pixel: coding cannot average it away (for ecc-63-10 at T/63 it dominates), and where noise makes
``white <= black`` the decoder has no levels at all and returns no column.

The code frames themselves hold about n/2 samples of each level.  `refine_levels` fits, per
pixel, ``r_i = black + (white - black) * x_i`` by least squares over the n code samples (with
``x_i`` the symbol of a decoded column, ``s / (q - 1)``) plus the two calibration frames (x = 1
and x = 0).  `estimate_levels` is the decoder's level stage (``levels="refit"`` of `edge.decode.decode`):
it takes the columns of a first candidate search, refits the levels and hands back a float32
normalised `CodedCapture` with the refitted white / black, which the decoder searches again.  This is
the usual EM-style refinement of a communication receiver; it needs no extra frames.

Stage interface: `CodedCapture` in (frames (n, H, W), white / black (H, W) raw, ``scale`` to normalised
units), `CodedCapture` out; ``"calibration"`` returns the stack as it is, ``"refit"`` a float32 stack in
normalised units (scale 1).  The first search is the caller's (``top1``), so this module does
not depend on the decoder.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..codes import Code
from ..capture import CodedCapture
from .inputs import validate

#: Smallest white - black contrast (normalised units) a refitted pixel keeps, so that the decoder
#: still decodes it (the kernels need white > black).
MIN_CONTRAST = 1e-6


def initial_levels(frames: np.ndarray, white: np.ndarray, black: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Calibration levels, except where ``white <= black``: there the mean of the upper and of the
    lower half of the pixel's n + 2 samples.  All arrays float32 normalised; returns (white, black)."""
    bad = ~(white > black)
    if not bad.any():
        return white, black
    samples = np.concatenate([frames[:, bad], white[None, bad], black[None, bad]], axis=0)
    samples.sort(axis=0)
    half = samples.shape[0] // 2
    lo = samples[:half].mean(axis=0)
    hi = samples[-half:].mean(axis=0)
    w, b = white.copy(), black.copy()
    w[bad] = np.maximum(hi, lo + MIN_CONTRAST)
    b[bad] = lo
    return w, b


def refine_levels(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code,
                  column: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares on/off levels per pixel given decoded codebook rows.

    frames: (n, H, W) float32 normalised; white, black: (H, W) float32 normalised; column: (H, W)
    int codebook row, -1 where none (those pixels keep ``white``, ``black``).  Returns float32
    (white, black) with ``white - black >= MIN_CONTRAST`` wherever ``column >= 0``.
    """
    col = np.asarray(column)
    if col.shape != white.shape:
        raise ValueError(f"column: expected shape {white.shape}, got {col.shape}")
    if frames.shape[0] != code.n:
        raise ValueError(f"frames: code {code.name!r} has n={code.n} frames, got {frames.shape[0]}")
    if col.size and int(col.max()) >= code.size:
        raise ValueError(f"column: expected codebook rows < {code.size}, got {int(col.max())}")
    ok = col >= 0
    x = code.codebook[np.where(ok, col, 0)].astype(np.float32) / np.float32(code.q - 1)  # (H, W, n)
    x = np.moveaxis(x, -1, 0)
    m = code.n + 2
    sx = x.sum(axis=0) + 1.0
    sxx = (x * x).sum(axis=0) + 1.0
    sr = frames.sum(axis=0) + white + black
    sxr = (x * frames).sum(axis=0) + white
    den = m * sxx - sx * sx  # > 0: white (x = 1) and black (x = 0) are always among the points
    slope = (m * sxr - sx * sr) / den
    intercept = (sr - slope * sx) / m
    b = np.maximum(intercept, 0.0)
    w = b + np.maximum(slope, MIN_CONTRAST)
    return (np.where(ok, w, white).astype(np.float32), np.where(ok, b, black).astype(np.float32))


def estimate_levels(stack: CodedCapture, code: Code, levels: str, top1: Callable[[CodedCapture], np.ndarray], *,
                    iterations: int = 1) -> CodedCapture:
    """The level stage: the on / off levels the final search uses (see the module docstring).

    levels: "calibration" (`stack` unchanged) or "refit": the frames as float32 normalised, the
    `initial_levels`, then `iterations` times ``refine_levels(..., top1(current stack))``.
    top1: (CodedCapture) -> (H, W) int codebook rows (-1 = none), the decoder's first candidate search
    (every pixel, no valid mask).  Not with inverse frames (they do not use the calibration
    levels for their decisions).
    """
    if levels == "calibration":
        return stack
    if levels != "refit":
        raise ValueError(f"levels: expected 'calibration' or 'refit', got {levels!r}")
    if stack.inverse is not None:
        raise ValueError("levels: 'refit' expects no inverse frames (pattern + inverse decisions "
                         "do not use the calibration levels), got inverse=")
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise ValueError(f"iterations: expected an integer >= 0, got {iterations!r}")
    s = np.float32(stack.scale)
    f = stack.frames.astype(np.float32) * s
    w, b = initial_levels(f, stack.white.astype(np.float32) * s, stack.black.astype(np.float32) * s)
    for _ in range(iterations):
        w, b = refine_levels(f, w, b, code, top1(validate(f, w, b, code, scale_free=True)))
    return validate(f, w, b, code, scale_free=True)  # fitted levels may exceed 1 by their noise
