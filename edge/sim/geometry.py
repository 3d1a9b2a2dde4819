"""Rectified projector-camera geometry (Middlebury convention).

A camera pixel ``(y, x)`` and the projector column ``c`` it sees lie on the same row ``y``.
Disparity ``d = x - c`` (pixels, may be negative); depth ``Z = focal_px * baseline_m / (d + doffs)``
with ``doffs = cx_projector - cx_camera``.

Default geometry (`Geometry.default`): focal 600 px, baseline 0.10 m, projector 1024 columns with
its principal point at its centre (``cx_projector = 512``), camera principal point at the centre
of the camera image.  A 640x480 camera then has ``doffs = 192`` and, for depths 0.4..2.0 m, sees
disparities -162..-42 (projector columns 42..801); a smaller camera (e.g. 320x240) is a centred
crop of the same optics and sees the central projector columns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import triangulation

#: Depth range (metres) the default scenes are built to stay within.
DEPTH_RANGE_M = (0.4, 2.0)


@dataclass(frozen=True)
class Geometry:
    """Intrinsics and baseline of a rectified projector-camera pair.

    Attributes:
        focal_px: focal length in pixels (shared by camera and projector after rectification).
        baseline_m: projector-camera baseline in metres (> 0).
        cx_camera: camera principal point, x (pixels).
        cx_projector: projector principal point, x (projector columns).
        cy: principal point, y (pixels; rows are shared).
        projector_width: number of projector columns.
        projector_height: number of projector rows (0 = same as the camera).
    """

    focal_px: float = 600.0
    baseline_m: float = 0.10
    cx_camera: float = 320.0
    cx_projector: float = 512.0
    cy: float = 240.0
    projector_width: int = 1024
    projector_height: int = 0

    def __post_init__(self) -> None:
        if not self.focal_px > 0:
            raise ValueError(f"geometry: focal_px must be > 0, got {self.focal_px}")
        if not self.baseline_m > 0:
            raise ValueError(f"geometry: baseline_m must be > 0, got {self.baseline_m}")
        if int(self.projector_width) < 1:
            raise ValueError(f"geometry: projector_width must be >= 1, got {self.projector_width}")

    @classmethod
    def default(cls, width: int = 640, height: int = 480, **overrides: float) -> "Geometry":
        """Default geometry for a ``width`` x ``height`` camera (principal point at the centre)."""
        params = dict(cx_camera=width / 2.0, cy=height / 2.0)
        params.update(overrides)
        return cls(**params)  # type: ignore[arg-type]

    @classmethod
    def projector_as_wide(cls, width: int, height: int) -> "Geometry":
        """The light-source scenarios' pair (`edge.source`): a projector as wide as the ``width`` x
        ``height`` camera, both principal points at the centre, focal 300 px per 320 columns."""
        return cls.default(width, height, focal_px=300.0 * width / 320.0, cx_projector=width / 2.0,
                           projector_width=width)

    @property
    def doffs(self) -> float:
        """``cx_projector - cx_camera`` (pixels)."""
        return float(self.cx_projector - self.cx_camera)

    def depth_from_disparity(self, disparity: np.ndarray) -> np.ndarray:
        """Depth in metres (float32, NaN where ``d + doffs <= 0`` or d is NaN; `edge.triangulation`)."""
        return triangulation.depth_from_disparity(disparity, self.focal_px, self.baseline_m,
                                                  self.doffs).astype(np.float32)

    def disparity_from_depth(self, depth_m: np.ndarray) -> np.ndarray:
        """Disparity in pixels (float32) of depth ``Z`` metres: ``f*B/Z - doffs`` (`edge.triangulation`)."""
        z = np.asarray(depth_m, dtype=np.float64)
        return triangulation.disparity_from_depth(z, self.focal_px, self.baseline_m, self.doffs).astype(np.float32)

    def disparity_band(self, near_m: float = DEPTH_RANGE_M[0], far_m: float = DEPTH_RANGE_M[1]) -> tuple[int, int]:
        """Integer ``(min_disparity, max_disparity)`` covering depths ``near_m..far_m``."""
        if not 0 < near_m < far_m:
            raise ValueError(f"disparity band: need 0 < near < far, got near={near_m}, far={far_m}")
        lo = float(self.disparity_from_depth(np.float64(far_m)))
        hi = float(self.disparity_from_depth(np.float64(near_m)))
        return int(np.floor(lo)) - 1, int(np.ceil(hi)) + 1

    def rays(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """Normalised camera ray slopes ``u = (x - cx)/f`` (W,) and ``v = (y - cy)/f`` (H,), float64."""
        u = (np.arange(width, dtype=np.float64) - self.cx_camera) / self.focal_px
        v = (np.arange(height, dtype=np.float64) - self.cy) / self.focal_px
        return u, v
