"""Accuracy metrics of a decoded column map against a scene's ground truth.

Decoded columns are int32 (H, W) codeword indices, -1 = invalid (not decoded).  With ``stripe``
s, the true codeword of a pixel is ``scene.column_int // s``.  Ground-truth-valid pixels are those
the projector reaches (``scene.lit``) whose column the code covers.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .. import triangulation

from .scene import Scene

THRESHOLDS = (0, 1, 2)


@dataclass(frozen=True)
class Metrics:
    """Summary of one decoded map.

    Attributes:
        error_rate: fraction of GT-valid pixels whose decoded column is invalid or differs from the
            truth by more than ``threshold`` (the paper's "incorrect disparity" for threshold 0).
        wrong_rate: fraction of GT-valid pixels decoded (column >= 0) to a wrong column.
        fraction_decoded: fraction of GT-valid pixels with a decoded column >= 0.
        rmse_mm: depth RMSE in millimetres over decoded GT-valid pixels (inside ``valid`` if given).
        wrongly_valid: fraction of GT-valid pixels that the decoder's mask accepts but are wrong.
        wrongly_rejected: fraction of GT-valid pixels that the mask rejects but are right.
        threshold: column tolerance used (codeword units).
        pixels: number of GT-valid pixels.
    """

    error_rate: float
    wrong_rate: float
    fraction_decoded: float
    rmse_mm: float
    wrongly_valid: float
    wrongly_rejected: float
    threshold: int
    pixels: int

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def _check(decoded_column: np.ndarray, scene: Scene, threshold: int, stripe: int) -> np.ndarray:
    col = np.asarray(decoded_column)
    if col.shape != scene.shape:
        raise ValueError(f"decoded column map has shape {col.shape}, scene is {scene.shape}")
    if not np.issubdtype(col.dtype, np.integer):
        raise ValueError(f"decoded columns must be integers (-1 = invalid), got dtype {col.dtype}")
    if threshold < 0:
        raise ValueError(f"error threshold must be >= 0, got {threshold}")
    if stripe < 1:
        raise ValueError(f"stripe must be >= 1, got {stripe}")
    return col.astype(np.int64)


def truth(scene: Scene, *, stripe: int = 1, code_size: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(true codeword (H, W) int64, GT-valid mask (H, W) bool)."""
    gt = np.where(scene.column_int >= 0, scene.column_int // stripe, -1).astype(np.int64)
    valid = scene.lit & (gt >= 0)
    if code_size is not None:
        valid &= gt < code_size
    return gt, valid


def truth_columns(scene: Scene, stripe: int = 1) -> np.ndarray:
    """(H, W) int32 true codeword index (`truth`), -1 where it is not GT-valid (projector does not reach)."""
    gt, valid = truth(scene, stripe=stripe)
    return np.where(valid, gt, -1).astype(np.int32)


def error_map(decoded_column: np.ndarray, scene: Scene, *, threshold: int = 0, stripe: int = 1) -> np.ndarray:
    """(H, W) bool: GT-valid pixels whose decoded column is invalid or off by more than ``threshold``."""
    col = _check(decoded_column, scene, threshold, stripe)
    gt, valid = truth(scene, stripe=stripe)
    return valid & ((col < 0) | (np.abs(col - gt) > threshold))


def error_rate(decoded_column: np.ndarray, scene: Scene, *, threshold: int = 0, stripe: int = 1) -> float:
    """Fraction of GT-valid pixels decoded wrongly or not at all (see `error_map`)."""
    _, valid = truth(scene, stripe=stripe)
    n = int(valid.sum())
    return float(error_map(decoded_column, scene, threshold=threshold, stripe=stripe).sum() / n) if n else float("nan")


def depth_from_columns(decoded_column: np.ndarray, scene: Scene, *, stripe: int = 1) -> np.ndarray:
    """Depth in metres (float32, NaN where invalid) from decoded codewords (stripe centre)."""
    col = np.asarray(decoded_column)
    z = scene.geometry.depth_from_disparity(triangulation.disparity(triangulation.stripe_centre(col, stripe)))
    return np.where(col >= 0, z, np.nan).astype(np.float32)


def evaluate(decoded_column: np.ndarray, scene: Scene, *, valid: np.ndarray | None = None, threshold: int = 0,
             stripe: int = 1) -> Metrics:
    """All metrics of one decoded map; ``valid`` is the decoder's (H, W) bool accept mask (optional)."""
    col = _check(decoded_column, scene, threshold, stripe)
    gt, gt_valid = truth(scene, stripe=stripe)
    n = int(gt_valid.sum())
    if n == 0:
        raise ValueError(f"scene {scene.name!r} has no pixel the projector reaches; nothing to evaluate")
    decoded = col >= 0
    correct = decoded & (np.abs(col - gt) <= threshold)
    accept = decoded if valid is None else (np.asarray(valid, dtype=bool) & decoded)
    if accept.shape != scene.shape:
        raise ValueError(f"valid mask has shape {accept.shape}, scene is {scene.shape}")
    z = depth_from_columns(col, scene, stripe=stripe)
    sel = gt_valid & accept & np.isfinite(z)
    rmse = float(np.sqrt(np.mean((z[sel] - scene.depth_m[sel]) ** 2)) * 1000.0) if sel.any() else float("nan")
    return Metrics(
        error_rate=float((gt_valid & ~correct).sum() / n),
        wrong_rate=float((gt_valid & decoded & ~correct).sum() / n),
        fraction_decoded=float((gt_valid & decoded).sum() / n),
        rmse_mm=rmse,
        wrongly_valid=float((gt_valid & accept & ~correct).sum() / n),
        wrongly_rejected=float((gt_valid & ~accept & correct).sum() / n),
        threshold=int(threshold),
        pixels=n,
    )
