"""Synthetic captures with known columns under the decoder's noise model (tests, benchmarks).

Not a scene simulator (that is `edge.sim`): every pixel sees one known codebook row, with
per-pixel albedo and ambient light, heteroscedastic Gaussian noise sigma_r**2 + sigma_s**2 * I
on every frame (white and black included), clipping to [0, 1] and quantisation to the full scale
of the dtype and bit depth (`edge.capture.full_scale`).
"""

from __future__ import annotations

import numpy as np

from ..capture import CodedCapture, NoiseModel, full_scale
from ..codes import Code

def _quantise(x: np.ndarray, dtype: np.dtype, bit_depth: int | None = None) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    if np.dtype(dtype).kind == "f":
        return x.astype(dtype)
    return np.rint(x * full_scale(dtype, bit_depth)).astype(dtype)


def make_capture(
    code: Code,
    columns: np.ndarray,
    *,
    rng: np.random.Generator,
    albedo: np.ndarray | float = 0.5,
    ambient: float = 0.05,
    sigma_r: float = 0.01,
    sigma_s: float = 0.03,
    dtype: type = np.uint8,
    inverse: bool = False,
    bit_depth: int | None = None,
) -> CodedCapture:
    """Capture of `code` where pixel (y, x) sees codebook row columns[y, x].

    Level of symbol s: ambient + albedo * s / (q - 1) (normalised intensity).  Returns a
    `CodedCapture`: frames (n, H, W), white, black (H, W), inverse (n, H, W) or None in `dtype`
    (integers hold 0 .. full_scale(dtype, bit_depth), and the capture's bit_depth is the one
    quantised at: the dtype's width when None); truth (H, W) int64 = columns; equal
    frame exposures (relative 1.0); noise = (sigma_r, sigma_s).
    """
    columns = np.asarray(columns, dtype=np.int64)
    h, w = columns.shape
    alb = np.broadcast_to(np.asarray(albedo, dtype=np.float64), (h, w))
    symbols = code.codebook[columns].transpose(2, 0, 1).astype(np.float64)  # (n, H, W)
    levels = ambient + alb[None] * symbols / (code.q - 1)

    def noisy(level: np.ndarray) -> np.ndarray:
        sd = np.sqrt(sigma_r**2 + sigma_s**2 * level)
        return level + sd * rng.standard_normal(level.shape)

    frames = _quantise(noisy(levels), dtype, bit_depth)
    inv = None
    if inverse:
        inv = _quantise(noisy(ambient + alb[None] * (1 - symbols / (code.q - 1))), dtype, bit_depth)
    white = _quantise(noisy(ambient + alb), dtype, bit_depth)
    black = _quantise(noisy(np.full((h, w), ambient)), dtype, bit_depth)
    if bit_depth is None and np.issubdtype(dtype, np.integer):
        bit_depth = np.dtype(dtype).itemsize * 8  # as quantised: the dtype's full scale, not a detected depth
    return CodedCapture(frames=frames, white=white, black=black, inverse=inv, code=code, bit_depth=bit_depth,
                        frame_exposure=np.ones(code.n + 2), exposure_unit="relative",
                        noise=NoiseModel(float(sigma_r), float(sigma_s)), truth=columns)
