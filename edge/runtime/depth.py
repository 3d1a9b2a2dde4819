"""Column -> disparity -> depth: pure functions, so replay reproduces the service bit for bit.

Rectified projector-camera pair, Middlebury convention (docs/architecture.md):
``d = x_camera - column`` and ``Z = focal_px * baseline_m / (d + doffs)`` with
``doffs = cx_projector - cx_camera``.  Depth leaves as uint16 millimetres, 0 = invalid
(ROS REP 118 16UC1).  The formula itself is `edge.triangulation` (shared with the simulator).
All arithmetic is float64 numpy with round-half-even, which is deterministic across runs and
machines.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .. import triangulation


class DepthGeometry(Protocol):
    """Anything with these attributes (e.g. `edge.sim.Geometry` or a profile's geometry)."""

    focal_px: float
    baseline_m: float
    cx_camera: float
    cx_projector: float


def _check_column(column: np.ndarray) -> np.ndarray:
    column = np.asarray(column)
    if column.ndim != 2:
        raise ValueError(f"column map must be 2-D (H, W), got shape {column.shape}")
    if not (np.issubdtype(column.dtype, np.integer) or np.issubdtype(column.dtype, np.floating)):
        raise ValueError(f"column map must be integer or float, got dtype {column.dtype}")
    return column


def projector_column(codeword_index: np.ndarray, stripe: int = 1) -> np.ndarray:
    """Projector column (float64 pixels) at the centre of the stripe that sends ``codeword_index``.

    codeword_index: (H, W) int, -1 = invalid -> NaN.  stripe: projector columns per codeword.
    """
    return triangulation.stripe_centre(_check_column(codeword_index), stripe)


def column_to_disparity(column: np.ndarray) -> np.ndarray:
    """(H, W) projector column (pixels; int with -1 invalid, or float with NaN invalid) ->
    (H, W) float64 disparity ``x - column`` in pixels, NaN where invalid."""
    col = _check_column(column)
    d = triangulation.disparity(col)
    if np.issubdtype(col.dtype, np.integer):
        d[col < 0] = np.nan
    return d


def disparity_to_depth_mm(disparity: np.ndarray, geometry: DepthGeometry) -> np.ndarray:
    """(H, W) float disparity (pixels, NaN invalid) -> (H, W) uint16 depth in mm, 0 = invalid.

    Invalid: NaN disparity, ``d + doffs <= 0`` (behind the sensor / at infinity), or a depth that
    rounds to 0 or exceeds 65535 mm.
    """
    doffs = float(geometry.cx_projector) - float(geometry.cx_camera)
    z = triangulation.depth_from_disparity(disparity, geometry.focal_px, geometry.baseline_m, doffs, scale=1000.0)
    ok = np.isfinite(z)
    z = np.rint(np.where(ok, z, 0.0))
    ok &= (z >= 1) & (z <= 65535)
    return np.where(ok, z, 0).astype(np.uint16)


def column_to_depth_mm(column: np.ndarray, geometry: DepthGeometry, *, stripe: int = 1) -> np.ndarray:
    """Decoded codeword index map (H, W) int32, -1 invalid -> depth (H, W) uint16 mm, 0 invalid.

    With ``stripe`` > 1 the codeword index is converted to the centre projector column first.
    """
    col = _check_column(column)
    if stripe != 1 or not np.issubdtype(col.dtype, np.integer):
        col = projector_column(col, stripe) if np.issubdtype(col.dtype, np.integer) else col
    return disparity_to_depth_mm(column_to_disparity(col), geometry)


def confidence_to_u8(confidence: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float confidence in [0, 1] -> uint8 0..255 (higher = more confident), 0 where invalid
    and, given ``valid``, at least 1 where valid (0 means invalid on the wire: a valid pixel whose
    confidence rounds to 0 would be dropped by a consumer that filters on confidence > 0)."""
    c = np.asarray(confidence, dtype=np.float64)
    out = np.rint(np.clip(np.nan_to_num(c, nan=0.0), 0.0, 1.0) * 255.0).astype(np.uint8)
    if valid is not None:
        ok = np.asarray(valid, dtype=bool)
        out = np.where(ok, np.maximum(out, np.uint8(1)), np.uint8(0)).astype(np.uint8)
    return out


def error_image(error: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(H, W) float32 P(wrong column) in [0, 1] where `valid` (the published depth), NaN elsewhere
    (no depth, or no estimate for the published column): the ``32FC1`` error image of the service
    (REP 118's convention for float images, NaN = invalid)."""
    e = np.clip(np.asarray(error, dtype=np.float32), np.float32(0.0), np.float32(1.0))
    return np.where(np.asarray(valid, dtype=bool), e, np.float32(np.nan)).astype(np.float32)


def camera_matrix(geometry) -> np.ndarray:
    """(3, 3) float64 intrinsics K of the rectified camera in a profile / sim geometry:
    ``[[f, 0, cx_camera], [0, f, cy], [0, 0, 1]]`` (pixels, square pixels, no distortion)."""
    f, cx, cy = float(geometry.focal_px), float(geometry.cx_camera), float(geometry.cy)
    return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]], dtype=np.float64)


def depth_to_points(depth_mm: np.ndarray, k: np.ndarray, *, stride: int = 1) -> np.ndarray:
    """Back-project a depth map through a pinhole camera: the one point-cloud function of edge.

    depth_mm: (H, W) uint16 millimetres, 0 = invalid (skipped).  k: (3, 3) intrinsics (pixels,
    e.g. `camera_matrix`).  stride: use every ``stride``-th row and column (1 = every pixel).
    Returns (N, 3) float32 metres in the camera optical frame (REP 103: x right, y down,
    z forward), pixel (u, v) -> ``(z (u - cx) / fx, z (v - cy) / fy, z)`` (rays in float64, then
    float32), valid pixels in row-major order.
    """
    depth_mm = np.asarray(depth_mm)
    if depth_mm.ndim != 2 or depth_mm.dtype != np.uint16:
        raise ValueError(f"expected depth as (H, W) uint16 mm, got {depth_mm.dtype} {depth_mm.shape}")
    k = np.asarray(k, dtype=np.float64)
    if k.shape != (3, 3) or not (k[0, 0] > 0 and k[1, 1] > 0):
        raise ValueError(f"expected a (3, 3) intrinsics matrix with fx, fy > 0, got {k.tolist()}")
    if int(stride) < 1:
        raise ValueError(f"expected a point stride >= 1, got {stride}")
    s = int(stride)
    d = depth_mm[::s, ::s]
    valid = d != 0
    z = d.astype(np.float32) * np.float32(1e-3)
    # per-column / per-row rays (u - cx) / fx and (v - cy) / fy, then one masked gather per axis
    rx = ((np.arange(0, depth_mm.shape[1], s, dtype=np.float64) - k[0, 2]) / k[0, 0]).astype(np.float32)
    ry = ((np.arange(0, depth_mm.shape[0], s, dtype=np.float64) - k[1, 2]) / k[1, 1]).astype(np.float32)
    zs = z[valid]
    out = np.empty((zs.size, 3), dtype=np.float32)
    out[:, 0] = (z * rx[None, :])[valid]
    out[:, 1] = (z * ry[:, None])[valid]
    out[:, 2] = zs
    return out
