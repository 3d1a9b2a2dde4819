"""numba kernels of the simulator: projector z-buffer, pattern warp, exposure + noise + quantisation.

All kernels are deterministic (no random numbers drawn inside numba: noise samples come from the
caller's numpy Generator) and parallel over image rows.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _zbuffer_row(column: np.ndarray, depth: np.ndarray, object_id: np.ndarray, zbuf: np.ndarray) -> None:
    """Rasterise one camera row into the projector depth buffer ``zbuf`` (projector columns).

    Neighbouring camera pixels of the same object are joined by a segment whose inverse depth is
    interpolated linearly in projector column (exact for planes), so continuous surfaces leave no
    holes; pixels of different objects are splatted on their own nearest column.
    """
    w = column.shape[0]
    wp = zbuf.shape[0]
    for x in range(w):
        c = column[x]
        z = depth[x]
        if not (np.isfinite(c) and np.isfinite(z)) or z <= 0.0:
            continue
        j = int(np.floor(c + 0.5))
        if 0 <= j < wp and z < zbuf[j]:
            zbuf[j] = z
        if x + 1 < w and object_id[x + 1] == object_id[x]:
            c2 = column[x + 1]
            z2 = depth[x + 1]
            if not (np.isfinite(c2) and np.isfinite(z2)) or z2 <= 0.0:
                continue
            lo = c
            hi = c2
            ilo = 1.0 / z
            ihi = 1.0 / z2
            if c2 < c:
                lo = c2
                hi = c
                ilo = 1.0 / z2
                ihi = 1.0 / z
            j0 = int(np.ceil(lo))
            j1 = int(np.floor(hi))
            if j0 < 0:
                j0 = 0
            if j1 > wp - 1:
                j1 = wp - 1
            span = hi - lo
            for jj in range(j0, j1 + 1):
                if span > 0:
                    a = (jj - lo) / span
                    inv = ilo + a * (ihi - ilo)
                else:
                    inv = ilo
                if inv > 0:
                    zz = 1.0 / inv
                    if zz < zbuf[jj]:
                        zbuf[jj] = zz


@njit(cache=True, parallel=True)
def projector_lit(column: np.ndarray, depth: np.ndarray, object_id: np.ndarray, projector_width: int,
                  rel_tol: float) -> np.ndarray:
    """(H, W) bool: the surface point of each camera pixel is the first along its projector ray.

    column: (H, W) float32 projector column seen by each pixel (NaN = no surface);
    depth: (H, W) float32 metres; object_id: (H, W) int32 (segments join same-id neighbours).
    """
    h, w = column.shape
    lit = np.zeros((h, w), dtype=np.bool_)
    for y in prange(h):
        zbuf = np.full(projector_width, np.inf)
        _zbuffer_row(column[y], depth[y], object_id[y], zbuf)
        for x in range(w):
            c = column[y, x]
            z = depth[y, x]
            if not (np.isfinite(c) and np.isfinite(z)):
                continue
            if c < -0.5 or c >= projector_width - 0.5:
                continue
            j0 = int(np.floor(c))
            a = c - j0
            j1 = j0 + 1
            z0 = zbuf[j0] if 0 <= j0 < projector_width else np.inf
            z1 = zbuf[j1] if 0 <= j1 < projector_width else np.inf
            if np.isfinite(z0) and np.isfinite(z1):
                zref = 1.0 / ((1.0 - a) / z0 + a / z1)
            elif np.isfinite(z0):
                zref = z0
            else:
                zref = z1
            if z <= zref * (1.0 + rel_tol):
                lit[y, x] = True
    return lit


@njit(cache=True, parallel=True)
def warp_nearest(patterns: np.ndarray, column_int: np.ndarray, row_of: np.ndarray) -> np.ndarray:
    """(m, H, W) float32: ``patterns[i, row_of[y], column_int[y, x]]``, 0 where column_int < 0 or beyond.

    patterns: (m, Hp, Wp) float32; column_int: (H, W) int32 (-1 = not lit); row_of: (H,) int32.
    """
    m, hp, wp = patterns.shape
    h, w = column_int.shape
    out = np.zeros((m, h, w), dtype=np.float32)
    for y in prange(h):
        r = row_of[y]
        for x in range(w):
            c = column_int[y, x]
            if 0 <= c < wp:
                for i in range(m):
                    out[i, y, x] = patterns[i, r, c]
    return out


@njit(cache=True, parallel=True)
def warp_linear(patterns: np.ndarray, column: np.ndarray, row_of: np.ndarray) -> np.ndarray:
    """(m, H, W) float32: linear interpolation of each projector row at the float ``column``.

    Projector column j is centred at j; NaN columns give 0; samples outside [0, Wp-1] clamp to the
    edge column when within half a column, else 0.
    """
    m, hp, wp = patterns.shape
    h, w = column.shape
    out = np.zeros((m, h, w), dtype=np.float32)
    for y in prange(h):
        r = row_of[y]
        for x in range(w):
            c = column[y, x]
            if not np.isfinite(c) or c < -0.5 or c >= wp - 0.5:
                continue
            if c < 0.0:
                c = 0.0
            if c > wp - 1:
                c = wp - 1.0
            j0 = int(np.floor(c))
            a = np.float32(c - j0)
            j1 = j0 + 1 if j0 + 1 < wp else j0
            for i in range(m):
                out[i, y, x] = (1.0 - a) * patterns[i, r, j0] + a * patterns[i, r, j1]
    return out


@njit(cache=True, parallel=True)
def expose(projector_irradiance: np.ndarray, albedo: np.ndarray, scale_projector: float, ambient_level: float,
           normals: np.ndarray, sigma_r2: float, sigma_s2: float, levels: float, out: np.ndarray) -> None:
    """Clean intensity, heteroscedastic noise, quantisation and clipping, written into ``out``.

    I = albedo * (scale_projector * E + ambient_level)  (normalised, 0..1 before saturation);
    noisy = I + sqrt(sigma_r2 + sigma_s2 * I) * z;  out = clip(round(noisy * levels), 0, levels).

    projector_irradiance E: (m, H, W) float32; albedo: (H, W) float32; normals z: (m, H, W) float32
    standard normal samples; out: (m, H, W) uint8 or uint16.
    """
    m, h, w = projector_irradiance.shape
    for y in prange(h):
        for i in range(m):
            for x in range(w):
                clean = albedo[y, x] * (scale_projector * projector_irradiance[i, y, x] + ambient_level)
                if clean < 0.0:
                    clean = 0.0
                noisy = clean + np.sqrt(sigma_r2 + sigma_s2 * clean) * normals[i, y, x]
                q = np.floor(noisy * levels + 0.5)
                if q < 0.0:
                    q = 0.0
                elif q > levels:
                    q = levels
                out[i, y, x] = q
