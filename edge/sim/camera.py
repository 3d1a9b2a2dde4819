"""`CameraModel`: light levels, exposure and noise of the simulated sensor (eq. 1 of the paper).

Intensities are normalised so that 1.0 is full scale (saturation).  A camera frame of exposure
``t`` (relative units) reads, before noise,

    I = t * albedo * (projector * E + ambient)

where E in [0, 1] is the projector irradiance at the pixel (pattern value after warping, defocus
and global illumination).  ``projector`` and ``ambient`` are therefore the levels a white
(albedo 1) surface reaches in a frame of exposure 1 under the full projector / ambient light alone.
Noise is Gaussian with variance ``sigma_r**2 + sigma_s**2 * I`` (read noise plus shot noise), then
the value is quantised to ``bits`` bits and clipped to full scale.

Fixed total exposure: `capture_code` gives each of a code's n frames the exposure
``total_exposure / n``; the default ``total_exposure = 10`` makes the frames of a 10-frame code
(gray-10) exposure 1.0 and those of ecc-22-10 exposure 10/22.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..capture import MAX_SIGMA

SUPPORTED_BITS = (8, 10, 12, 16)


@dataclass(frozen=True)
class CameraModel:
    """Sensor and illumination parameters.

    Attributes:
        bits: ADC bits, one of 8, 10, 12, 16 (frames are uint8 for 8, else uint16).
        sigma_r: read noise standard deviation (normalised units, >= 0).
        sigma_s: shot-noise parameter: variance contributes ``sigma_s**2 * I`` (>= 0).
        ambient: ambient level (white surface, exposure 1), >= 0.
        projector: projector level (white surface, full-on pattern, exposure 1), >= 0.
        exposure: per-frame exposure used by `capture` when none is given (> 0).
        total_exposure: fixed exposure budget shared by the n frames of a code in `capture_code` (> 0).
        defocus_sigma: Gaussian defocus blur of the projected pattern, in projector pixels (>= 0).
        sampling: how a pixel samples the projector row: ``"nearest"`` column (exact for binary
            codes: the pixel sees exactly ``scene.column_int``) or ``"linear"`` interpolation.
    """

    bits: int = 8
    sigma_r: float = 0.002
    sigma_s: float = 0.015
    ambient: float = 0.2
    projector: float = 0.5
    exposure: float = 1.0
    total_exposure: float = 10.0
    defocus_sigma: float = 0.0
    sampling: str = "nearest"

    def __post_init__(self) -> None:
        if self.bits not in SUPPORTED_BITS:
            raise ValueError(f"camera: bits must be one of {SUPPORTED_BITS}, got {self.bits}")
        for name in ("sigma_r", "sigma_s", "ambient", "projector", "defocus_sigma"):
            value = getattr(self, name)
            if not value >= 0:
                raise ValueError(f"camera: {name} must be >= 0, got {value}")
            if name.startswith("sigma") and value > MAX_SIGMA:  # the decoder's and the profiles' bound too
                raise ValueError(f"camera: {name} must be <= {MAX_SIGMA:g} (normalised units, 1 = full scale), "
                                 f"got {value}")
        for name in ("exposure", "total_exposure"):
            value = getattr(self, name)
            if not value > 0:
                raise ValueError(f"camera: {name} must be > 0, got {value}")
        if self.sampling not in ("nearest", "linear"):
            raise ValueError(f"camera: sampling must be 'nearest' or 'linear', got {self.sampling!r}")

    @property
    def levels(self) -> int:
        """Largest code value, ``2**bits - 1`` (`edge.capture.full_scale` of the frames)."""
        from ..capture import dtype_for_bits, full_scale

        return int(full_scale(dtype_for_bits(self.bits), self.bits))

    def frame_exposure(self, n_frames: int) -> float:
        """Per-frame exposure of an ``n_frames`` capture at fixed total exposure."""
        if n_frames < 1:
            raise ValueError(f"frame_exposure: n_frames must be >= 1, got {n_frames}")
        return self.total_exposure / n_frames

    def with_(self, **changes: object) -> "CameraModel":
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)  # type: ignore[arg-type]
