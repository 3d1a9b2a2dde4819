"""Synthetic captures with known columns under the decoder's noise model (tests, benchmarks).

Not a scene simulator (that is `edge.sim`): every pixel sees one known codebook row, with
per-pixel albedo and ambient light, heteroscedastic Gaussian noise sigma_r**2 + sigma_s**2 * I
on every frame (white and black included), clipping to [0, 1] and quantisation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..codes import Code


@dataclass(frozen=True)
class SyntheticCapture:
    """frames (n, H, W), white, black (H, W) in `dtype`; columns (H, W) int64 true rows;
    inverse (n, H, W) or None."""

    frames: np.ndarray
    white: np.ndarray
    black: np.ndarray
    columns: np.ndarray
    inverse: np.ndarray | None


def _quantise(x: np.ndarray, dtype: np.dtype) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    if dtype == np.uint8:
        return np.rint(x * 255).astype(np.uint8)
    if dtype == np.uint16:
        return np.rint(x * 65535).astype(np.uint16)
    return x.astype(dtype)


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
) -> SyntheticCapture:
    """Capture of `code` where pixel (y, x) sees codebook row columns[y, x].

    Level of symbol s: ambient + albedo * s / (q - 1) (normalised intensity).
    """
    columns = np.asarray(columns, dtype=np.int64)
    h, w = columns.shape
    alb = np.broadcast_to(np.asarray(albedo, dtype=np.float64), (h, w))
    symbols = code.codebook[columns].transpose(2, 0, 1).astype(np.float64)  # (n, H, W)
    levels = ambient + alb[None] * symbols / (code.q - 1)

    def noisy(level: np.ndarray) -> np.ndarray:
        sd = np.sqrt(sigma_r**2 + sigma_s**2 * level)
        return level + sd * rng.standard_normal(level.shape)

    frames = _quantise(noisy(levels), dtype)
    inv = None
    if inverse:
        inv = _quantise(noisy(ambient + alb[None] * (1 - symbols / (code.q - 1))), dtype)
    white = _quantise(noisy(ambient + alb), dtype)
    black = _quantise(noisy(np.full((h, w), ambient)), dtype)
    return SyntheticCapture(frames=frames, white=white, black=black, columns=columns, inverse=inv)
