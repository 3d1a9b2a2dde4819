"""A minimal structured-light renderer for the tests, independent of `edge.sim`.

Scene: a slanted background plane, a raised box and a sphere in front of it, seen by a camera
rectified with the projector (baseline along x).  Albedo is a smooth random field in [0.25, 1].
Every frame (the n code frames and the white / black calibration frames) gets the per-frame
exposure ``T / n`` of a fixed total exposure ``T``; the intensity of a pixel in a frame is

    I = t * albedo * (projector * symbol / (q - 1) + ambient)

plus Gaussian noise of variance ``read**2 + shot**2 * I``, quantised to `bits` bits (uint8 for 8,
uint16 holding `bits`-bit values otherwise) or left as float32 (``bits=None``).  Ground truth:
the projector column (codebook row, stripe 1) each pixel sees.  Codebooks may be q-ary (symbol s
at ``s / (q - 1)`` of the projector's power, as `edge.patterns` renders them).
"""

from __future__ import annotations

import numpy as np


def scene(width: int, height: int, *, seed: int, columns: int = 1024) -> tuple[np.ndarray, np.ndarray]:
    """(column (H, W) int64 projector column seen by each pixel, albedo (H, W) float64)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    u, v = x / width, y / height
    # disparity in projector columns: plane, box, sphere (nearer = larger disparity)
    disp = 60.0 + 40.0 * u + 25.0 * v
    box = (np.abs(u - 0.3) < 0.12) & (np.abs(v - 0.6) < 0.2)
    disp = np.where(box, disp + 70.0, disp)
    r2 = ((u - 0.7) / 0.18) ** 2 + ((v - 0.4) / 0.25) ** 2
    sphere = r2 < 1.0
    disp = np.where(sphere, disp + 90.0 * np.sqrt(np.clip(1.0 - r2, 0.0, 1.0)) + 20.0, disp)
    column = np.clip(np.round(x * (columns - 1) / (width - 1) * 0.75 + disp), 0, columns - 1).astype(np.int64)
    # smooth albedo: a few random low-frequency sinusoids, rescaled to [0.25, 1]
    a = np.zeros_like(u)
    for _ in range(4):
        fx, fy, ph = rng.uniform(1, 6), rng.uniform(1, 6), rng.uniform(0, 2 * np.pi)
        a += np.sin(2 * np.pi * (fx * u + fy * v) + ph)
    a = (a - a.min()) / max(np.ptp(a), 1e-9)
    return column, 0.25 + 0.75 * a


def render(codebook: np.ndarray, column: np.ndarray, albedo: np.ndarray, *, ambient: float, projector: float = 0.5,
           total_exposure: float = 10.0, read: float = 0.002, shot: float = 0.04, bits: int | None = 12,
           seed: int = 0, q: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frames (n, H, W), white (H, W), black (H, W)) of a `codebook` (rows = columns) of symbols
    0..q-1 (binary by default); symbol s is projected at ``s / (q - 1)`` of full power.

    ambient / projector: levels a white surface reaches in a frame of exposure 1; each of the
    n + 2 frames has exposure ``total_exposure / n``.
    """
    if q < 2 or int(np.max(codebook)) > q - 1:
        raise ValueError(f"expected symbols 0..{q - 1} (q >= 2), got a codebook up to {int(np.max(codebook))}")
    rng = np.random.default_rng(seed)
    n = codebook.shape[1]
    t = total_exposure / n
    bits_of = codebook[column].astype(np.float64) / (q - 1)           # (H, W, n) in [0, 1]
    patterns = np.concatenate([np.moveaxis(bits_of, -1, 0), np.ones((1,) + column.shape), np.zeros((1,) + column.shape)])
    clean = t * albedo[None] * (projector * patterns + ambient)
    noisy = clean + rng.standard_normal(clean.shape) * np.sqrt(read ** 2 + shot ** 2 * clean)
    noisy = np.clip(noisy, 0.0, 1.0)
    if bits is None:
        out = noisy.astype(np.float32)
    else:
        levels = 2 ** bits - 1
        out = np.round(noisy * levels).astype(np.uint8 if bits == 8 else np.uint16)
    return out[:n], out[n], out[n + 1]
