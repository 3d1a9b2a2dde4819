"""Robust plane fit of a point cloud (RANSAC, then least squares on the inliers).

Used to check metric depth on flat scenes (a chessboard taped to a wall): the RMS distance of
the inliers to the fitted plane is the depth noise, the inlier share the usable surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlaneFit:
    """normal: (3,) unit normal (z component <= 0: towards a camera looking along +z); offset:
    ``normal @ x + offset = 0`` on the plane (units of the points); inliers: (N,) bool (False for
    non-finite points); rms: RMS distance of the inliers to the plane; residuals: (N,) signed
    distances (NaN for non-finite points)."""

    normal: np.ndarray
    offset: float
    inliers: np.ndarray
    rms: float
    residuals: np.ndarray


def _lsq_plane(points: np.ndarray) -> tuple[np.ndarray, float]:
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre, full_matrices=False)
    n = vt[2]
    if n[2] > 0:
        n = -n
    return n, float(-n @ centre)


def fit_plane(points: np.ndarray, threshold: float, *, iterations: int = 300, sample: int = 50000,
              refits: int = 3, seed: int = 0) -> PlaneFit:
    """Fit a plane to (N, 3) finite points.

    RANSAC with ``iterations`` three-point hypotheses scored on a random subset of at most
    ``sample`` points; a point is an inlier within ``threshold`` (units of the points) of the plane.
    The best hypothesis is refined by ``refits`` rounds of least squares (SVD) on its inliers
    among all points.  Raises ValueError for fewer than 3 points.
    """
    pts = np.asarray(points, np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"fit_plane: expected (N, 3) points, got {pts.shape}")
    finite = np.isfinite(pts).all(axis=1)
    if finite.sum() < 3:
        raise ValueError(f"fit_plane: expected at least 3 finite points, got {int(finite.sum())}")
    all_pts, pts = pts, pts[finite]
    if not threshold > 0:
        raise ValueError(f"fit_plane: threshold must be > 0, got {threshold}")
    rng = np.random.default_rng(seed)
    sub = pts[rng.choice(pts.shape[0], min(sample, pts.shape[0]), replace=False)]
    best_n, best_off, best_count = None, 0.0, -1
    for _ in range(iterations):
        a, b, c = sub[rng.choice(sub.shape[0], 3, replace=False)]
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n)
        if norm == 0:
            continue
        n /= norm
        off = -n @ a
        count = int((np.abs(sub @ n + off) < threshold).sum())
        if count > best_count:
            best_n, best_off, best_count = n, off, count
    if best_n is None:
        raise ValueError("fit_plane: all sampled points are collinear")
    n, off = best_n, best_off
    inliers = np.abs(pts @ n + off) < threshold
    for _ in range(refits):
        if inliers.sum() < 3:
            break
        n, off = _lsq_plane(pts[inliers])
        inliers = np.abs(pts @ n + off) < threshold
    res = np.full(all_pts.shape[0], np.nan)
    res[finite] = pts @ n + off
    rms = float(np.sqrt(np.mean(res[finite][inliers] ** 2))) if inliers.any() else float("nan")
    full = np.zeros(all_pts.shape[0], bool)
    full[finite] = inliers
    return PlaneFit(normal=n, offset=float(off), inliers=full, rms=rms, residuals=res)
