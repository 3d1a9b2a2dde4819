"""The depth formula of a rectified projector-camera pair: the one place it is written.

Middlebury convention (docs/architecture.md): a camera pixel in column ``x`` that sees projector
column ``c`` has disparity ``d = x - c`` (pixels, may be negative) and depth
``Z = focal_px * baseline_m / (d + doffs)`` with ``doffs = cx_projector - cx_camera`` (pixels).
A codeword index ``i`` of a code drawn with ``stripe`` projector columns per codeword is read at
the stripe's centre column ``i * stripe + (stripe - 1) / 2``.

Pure numpy functions at the bottom of the pipeline (numpy only), used by the simulator
(`edge.sim.geometry`, `edge.sim.metrics`), the light-source models (`edge.source`) and the
service's depth output (`edge.runtime.depth`).
"""

from __future__ import annotations

import numpy as np


def stripe_centre(index: np.ndarray, stripe: int = 1) -> np.ndarray:
    """Projector column (float64 pixels) at the centre of the stripe that sends codeword ``index``.

    index: int array of any shape, < 0 = invalid -> NaN.  stripe: projector columns per codeword (>= 1).
    """
    if stripe < 1:
        raise ValueError(f"stripe must be >= 1 projector column per codeword, got {stripe}")
    idx = np.asarray(index)
    out = idx.astype(np.float64) * stripe + (stripe - 1) / 2.0
    out[idx < 0] = np.nan
    return out


def disparity(column: np.ndarray) -> np.ndarray:
    """(H, W) projector column (pixels, NaN invalid) -> (H, W) float64 disparity ``x - column``."""
    col = np.asarray(column)
    return np.arange(col.shape[-1], dtype=np.float64)[None, :] - col.astype(np.float64)


def depth_from_disparity(disparity: np.ndarray, focal_px: float, baseline_m: float, doffs: float, *,
                         scale: float = 1.0) -> np.ndarray:
    """(H, W) disparity (pixels, NaN invalid) -> float64 depth ``scale * focal_px * baseline_m / (d + doffs)``.

    scale: 1 for metres, 1000 for millimetres.  NaN where ``d + doffs <= 0`` (behind the sensor /
    at infinity) or d is NaN.  Raises ValueError unless ``focal_px * baseline_m > 0``.
    """
    d = np.asarray(disparity, dtype=np.float64)
    fb = float(focal_px) * float(baseline_m) * scale
    if not fb > 0:
        raise ValueError(f"focal_px * baseline_m must be positive, got {fb / scale}")
    denom = d + float(doffs)
    ok = denom > 0
    z = np.full(d.shape, np.nan, dtype=np.float64)
    np.divide(fb, denom, out=z, where=ok)
    return z


def disparity_from_depth(depth_m: np.ndarray, focal_px: float, baseline_m: float, doffs: float) -> np.ndarray:
    """Disparity (pixels) of depth ``Z`` metres: ``focal_px * baseline_m / Z - doffs``.

    Computed in the dtype of ``depth_m`` (float32 stays float32; pass float64 for float64; a
    Python number gives a Python float); inf where an array's Z = 0 and ``-doffs`` where Z is
    inf, without warnings.
    """
    if isinstance(depth_m, (int, float)):  # a plain number stays a Python float
        return focal_px * baseline_m / float(depth_m) - doffs
    z = np.asarray(depth_m)
    with np.errstate(divide="ignore", invalid="ignore"):
        return focal_px * baseline_m / z - doffs
