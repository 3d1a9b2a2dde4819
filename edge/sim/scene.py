"""The `Scene` value: a camera-visible surface with per-pixel ground truth.

`build_scene` turns a depth map, an albedo map and object labels into a Scene: disparity and
projector column from the geometry, the projector-shadow mask from a z-buffer rendered from the
projector, and the global-illumination operators.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ._kernels import projector_lit
from .geometry import Geometry
from .gi import Interreflection, build_interreflection, scatter

#: Relative depth tolerance of the projector z-buffer test (0.2 %).
LIT_REL_TOL = 2e-3
#: A pixel is marked ``indirect`` when an all-white pattern gives it indirect irradiance above this
#: fraction of the full projector irradiance.
INDIRECT_THRESHOLD = 0.02


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Scene:
    """A simulated scene with ground truth for every camera pixel.

    Attributes:
        name: scene name (``"flying"``, ``"plane"``...).
        albedo: (H, W) float32 reflectance in [0, 1] (shading included).
        column: (H, W) float32 true projector column (NaN where no projector light reaches).
        column_int: (H, W) int32 nearest projector column ``floor(column + 0.5)`` (-1 where none).
        disparity: (H, W) float32 ``x - column`` (pixels; defined wherever there is a surface).
        depth_m: (H, W) float32 depth in metres.
        lit: (H, W) bool: the projector reaches the pixel (first surface along the projector ray,
            inside the projector's columns).
        indirect: (H, W) bool: pixel receives indirect light (inter-reflection or scattering).
        geometry: the `Geometry` the ground truth was computed with.
        object_id: (H, W) int32 surface label (0 = background).
        scattering: (H, W) float32 sub-surface scattering strength in [0, 1] (0 = none).
        scattering_sigma: scattering footprint in pixels.
        interreflection: one-bounce transport, or None.
        t: time of the snapshot (seconds).
        seed: random seed.
        params: scene parameters as given.
    """

    name: str
    albedo: np.ndarray
    column: np.ndarray
    column_int: np.ndarray
    disparity: np.ndarray
    depth_m: np.ndarray
    lit: np.ndarray
    indirect: np.ndarray
    geometry: Geometry
    object_id: np.ndarray
    scattering: np.ndarray
    scattering_sigma: float = 0.0
    interreflection: Interreflection | None = None
    t: float = 0.0
    seed: int = 0
    params: dict[str, Any] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return self.albedo.shape  # type: ignore[return-value]

    @property
    def height(self) -> int:
        return int(self.albedo.shape[0])

    @property
    def width(self) -> int:
        return int(self.albedo.shape[1])

    @property
    def has_scattering(self) -> bool:
        return bool(self.scattering_sigma > 0 and np.any(self.scattering > 0))

    def disparity_band(self, margin: int = 2) -> tuple[int, int]:
        """Integer (min_disparity, max_disparity) of the lit pixels, widened by ``margin``."""
        d = self.disparity[self.lit]
        if d.size == 0:
            return self.geometry.disparity_band()
        return int(np.floor(d.min())) - margin, int(np.ceil(d.max())) + margin

    def indirect_light(self, irradiance: np.ndarray) -> np.ndarray:
        """Projector irradiance (m, H, W) after global illumination (scattering, then one bounce).

        ``irradiance`` is the direct projector irradiance at each pixel (0 where not lit).
        """
        e = irradiance.astype(np.float32, copy=False)
        if self.has_scattering:
            e = scatter(e, self.scattering, self.scattering_sigma)
        if self.interreflection is not None and self.interreflection.strength > 0:
            e = e + self.interreflection.indirect(e * self.albedo[None])
        return e


def build_scene(name: str, depth_m: np.ndarray, albedo: np.ndarray, object_id: np.ndarray,
                geometry: Geometry, *, scattering: np.ndarray | None = None, scattering_sigma: float = 0.0,
                interreflection: float = 0.0, t: float = 0.0, seed: int = 0,
                params: dict[str, Any] | None = None, gi_patch: int = 16, bounces: int = 1,
                gloss: float = 0.0) -> Scene:
    """Ground truth for a camera-visible surface.

    depth_m: (H, W) metres (NaN = no surface); albedo: (H, W) in [0, 1]; object_id: (H, W) int
    labels (neighbouring pixels with the same label are one continuous surface for the projector
    z-buffer); scattering: (H, W) strength map in [0, 1] or None; interreflection: one-bounce
    strength (0 = off, 1 = physical); gi_patch: inter-reflection patch side (pixels); bounces,
    gloss: see `edge.sim.gi.build_interreflection`.
    """
    h, w = depth_m.shape
    depth = depth_m.astype(np.float32)
    disparity = geometry.disparity_from_depth(depth)
    xs = np.arange(w, dtype=np.float32)[None, :]
    column_all = (xs - disparity).astype(np.float32)
    oid = object_id.astype(np.int32)
    lit = projector_lit(column_all, depth, oid, int(geometry.projector_width), LIT_REL_TOL)
    column = np.where(lit, column_all, np.float32(np.nan)).astype(np.float32)
    column_int = np.where(lit, np.floor(column_all + 0.5), -1).astype(np.int32)
    scat = np.zeros((h, w), np.float32) if scattering is None else np.clip(scattering, 0, 1).astype(np.float32)
    transport = None
    if interreflection > 0:
        transport = build_interreflection(np.where(np.isfinite(depth), depth, np.nan), geometry,
                                          strength=interreflection, patch=gi_patch, bounces=bounces, gloss=gloss,
                                          albedo=albedo)
    scene = Scene(
        name=name, albedo=_readonly(np.clip(albedo, 0, 1).astype(np.float32)), column=_readonly(column),
        column_int=_readonly(column_int), disparity=_readonly(disparity), depth_m=_readonly(depth),
        lit=_readonly(lit), indirect=_readonly(np.zeros((h, w), bool)), geometry=geometry,
        object_id=_readonly(oid), scattering=_readonly(scat), scattering_sigma=float(scattering_sigma),
        interreflection=transport, t=float(t), seed=int(seed), params=dict(params or {}),
    )
    indirect = np.zeros((h, w), bool)
    if transport is not None:
        white = lit.astype(np.float32)[None]
        indirect |= transport.indirect(white * scene.albedo[None])[0] > INDIRECT_THRESHOLD
    if scene.has_scattering:
        indirect |= scat > 0
    object.__setattr__(scene, "indirect", _readonly(indirect))
    return scene
