"""Decision-directed estimation of each pixel's "on" and "off" levels.

`decode` takes the all-on (white) and all-off (black) calibration frames as the exact mean
levels of a pixel.  In the paper's acquisition they are single frames at the per-frame exposure
T/n, so they are as noisy as one code frame, and that error is common to all n samples of the
pixel: coding cannot average it away (for ecc-63-10 at T/63 it dominates), and where noise makes
``white <= black`` the decoder has no levels at all and returns no column.

The code frames themselves hold about n/2 samples of each level.  `refine_levels` fits, per
pixel, ``r_i = black + (white - black) * x_i`` by least squares over the n code samples (with
``x_i`` the symbol of a decoded column, ``s / (q - 1)``) plus the two calibration frames (x = 1
and x = 0).  `decode_refined` decodes once, refits the levels with the decoded columns and
decodes again with the refitted levels (float frames, normalised).  This is the usual EM-style
refinement of a communication receiver; it needs no extra frames.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..codes import Code
from .decoder import Decoded, decode
from .inputs import validate

#: Smallest white - black contrast (normalised units) a refitted pixel keeps, so that the decoder
#: still decodes it (the kernels need white > black).
MIN_CONTRAST = 1e-6


def normalised(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code, *,
               bit_depth: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frames (n, H, W), white (H, W), black (H, W)) as float32 in normalised units [0, 1]."""
    stack = validate(frames, white, black, code, bit_depth=bit_depth)
    s = np.float32(stack.scale)
    return (stack.frames.astype(np.float32) * s, stack.white.astype(np.float32) * s,
            stack.black.astype(np.float32) * s)


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


def decode_refined(frames: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code, *,
                   method: str = "soft", iterations: int = 1, bit_depth: int | None = None,
                   **kwargs: Any) -> Decoded:
    """`decode` with the levels refitted from the code frames (see the module docstring).

    Pass 0 decodes with `initial_levels` (method "soft"; "hard" for method "hard"); each of
    `iterations` passes refits the levels with `refine_levels` on the previous columns and decodes
    again; the last pass uses `method`.  Other keyword arguments go to `decode` (not ``inverse``:
    pattern + inverse captures do not use the calibration levels for their decisions).  The frames
    passed on are float32 normalised, so `bit_depth` applies to the input only.
    """
    if "inverse" in kwargs:
        raise ValueError("decode_refined: expected no inverse frames (they do not use calibration levels), got inverse=")
    if iterations < 0:
        raise ValueError(f"iterations: expected >= 0, got {iterations}")
    if kwargs.get("settings") is not None:  # the passes below decode with calibration levels
        kwargs["settings"] = kwargs["settings"].replace(levels="calibration")
    f, w, b = normalised(frames, white, black, code, bit_depth=bit_depth)
    w, b = initial_levels(f, w, b)
    first = "hard" if method == "hard" else "soft"
    # every pass decodes all pixels; the valid mask of the last pass is the caller's
    probe = {**kwargs, "min_contrast": 0.0, "min_confidence": 0.0}
    for _ in range(iterations):
        out = decode(f, w, b, code, method=first, **probe)
        w, b = refine_levels(f, w, b, code, out.candidates[..., 0])
    return decode(f, w, b, code, method=method, **kwargs)
