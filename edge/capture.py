"""`CodedCapture`: the one coded-capture type, and `full_scale`, the one full-scale rule.

Every producer of coded frames builds a `CodedCapture`: the simulator (`edge.sim.capture_code`),
the file layouts (`edge.decode.layouts`, one per coded axis), the synthetic helper
(`edge.decode.synthetic.make_capture`) and the runtime (`edge.runtime.assembly.Stack.coded`).
Every consumer reads it: the decoder (`edge.decode.decoder.decode_capture`; `decode` itself
validates its arrays into one with `edge.decode.inputs.validate`), the EDC check
(`edge.decode.check.check_capture`) and the adaptive loop (through `full_scale`).

Units:

* frames (n, H, W), white, black (H, W), inverse (n, H, W) or None, all of ONE dtype: uint8,
  uint16 or float32 / float64.  Raw values; ``value * scale`` is the normalised intensity
  (1.0 = full scale).  Floats are taken as already normalised (scale 1).
* bit_depth: significant bits of integer samples (uint16 data of a 10- or 12-bit sensor holds
  0 .. 2**bit_depth - 1); None = the dtype's width (8 for uint8, 16 for uint16).
* frame_exposure: (n + 2,) float64 exposure of code frames 0 .. n-1, then white, then black, in
  ``exposure_unit``: ``"us"`` (microseconds, device frames: `edge.sensors.base.Frame.exposure_us`)
  or ``"relative"`` (the simulator's `edge.sim.CameraModel` units, where light is linear in it).
  Finite and >= 0; 0 for a frame whose source did not say (a recording's frames), None where
  the source says nothing (image files).  A threshold that compares a code frame with
  white / black scales by ``exposure_ratio`` (the frame's exposure over the white frame's).
* noise: read / shot noise in normalised units (variance ``sigma_r**2 + sigma_s**2 * I``), or
  None when unknown.

This module sits at the bottom of the pipeline: it imports numpy (and `edge.codes` for typing).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .codes import Code

EXPOSURE_UNITS = ("us", "relative")


def full_scale(dtype: np.dtype | type, bit_depth: int | None = None) -> float:
    """Largest raw value of a sample of ``dtype`` (the value that means normalised intensity 1).

    uint8: 255 (bit_depth, if given, must be 8 or less: 2**bit_depth - 1); uint16:
    2**bit_depth - 1 (bit_depth 1..16, default 16); float32 / float64: 1.0 (already normalised;
    bit_depth ignored).  Either byte order.  Any other dtype, or a bit_depth that is not an
    integer, raises ValueError naming it.
    """
    if bit_depth is not None and (isinstance(bit_depth, bool) or not isinstance(bit_depth, (int, np.integer))):
        raise ValueError(f"bit_depth: expected an integer number of bits or None, got {bit_depth!r}")
    dt = np.dtype(dtype).newbyteorder("=")
    if dt.kind == "f":
        return 1.0
    if dt == np.uint8 or dt == np.uint16:
        width = 8 * dt.itemsize
        bits = width if bit_depth is None else int(bit_depth)
        if not 1 <= bits <= width:
            raise ValueError(f"bit_depth: expected 1..{width} for {dt} frames, got {bit_depth}")
        return float((1 << bits) - 1)
    raise ValueError(f"frames: expected dtype uint8, uint16, float32 or float64, got {np.dtype(dtype)}")


def dtype_for_bits(bits: int) -> type:
    """Sample dtype of a sensor with ``bits`` ADC bits: uint8 for 8 (or fewer), uint16 up to 16."""
    if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)) or not 1 <= int(bits) <= 16:
        raise ValueError(f"bits: expected 1..16 ADC bits, got {bits}")
    return np.uint8 if int(bits) <= 8 else np.uint16


@dataclass(frozen=True)
class NoiseModel:
    """Per-sample noise in normalised units: variance ``sigma_r**2 + sigma_s**2 * I``."""

    sigma_r: float
    sigma_s: float


@dataclass(frozen=True, eq=False)
class CodedCapture:
    """One coded capture (see the module docstring for units).

    Attributes:
        frames: (n, H, W) code frames, frame 0 first.
        white, black: (H, W) calibration frames (projector all on / all off).
        inverse: (n, H, W) inverse-pattern frames, or None.
        code: the code projected (None when the producer does not know it).
        columns: codebook rows in use (projector width / stripe), None = all.
        stripe: projector pixels per code cell, None = not stated (image layouts).
        bit_depth: significant bits of integer samples, None = the dtype's width.
        frame_exposure: (n + 2,) float64 exposure of code frames, white, black; None = unknown.
        exposure_unit: "us" or "relative" (see the module docstring).
        noise: `NoiseModel` or None.
        camera: the simulator's `CameraModel` when simulated, else None.
        truth: (H, W) int64 codebook row each pixel sees (-1 none) where known (synthetic
            captures), else None.
    """

    frames: np.ndarray
    white: np.ndarray
    black: np.ndarray
    inverse: np.ndarray | None = None
    code: Code | None = None
    columns: int | None = None
    stripe: int | None = None
    bit_depth: int | None = None
    frame_exposure: np.ndarray | None = None
    exposure_unit: str = "relative"
    noise: NoiseModel | None = None
    camera: Any = field(default=None, repr=False)
    truth: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.exposure_unit not in EXPOSURE_UNITS:
            raise ValueError(f"exposure_unit: expected one of {', '.join(EXPOSURE_UNITS)}, got {self.exposure_unit!r}")
        if self.frame_exposure is not None:
            e = np.asarray(self.frame_exposure, dtype=np.float64).reshape(-1)
            n = int(np.shape(self.frames)[0]) if np.ndim(self.frames) else 0
            if e.shape != (n + 2,):
                raise ValueError(f"frame_exposure: expected {n + 2} values (n code frames, white, black), "
                                 f"got {e.size}")
            if not np.all(np.isfinite(e) & (e >= 0)):
                raise ValueError(f"frame_exposure: expected finite exposures >= 0 (0 = not known), got {e.tolist()}")
            e.setflags(write=False)
            object.__setattr__(self, "frame_exposure", e)

    # -- derived values (computed in one place) -------------------------------------------
    @property
    def n(self) -> int:
        """Number of code frames."""
        return int(self.frames.shape[0])

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the frames."""
        return int(self.frames.shape[1]), int(self.frames.shape[2])

    @property
    def dtype(self) -> np.dtype:
        return self.frames.dtype

    @property
    def full_scale(self) -> float:
        """Raw value of normalised intensity 1 (`full_scale` of the dtype and bit_depth)."""
        return full_scale(self.frames.dtype, self.bit_depth)

    @property
    def scale(self) -> float:
        """Factor taking raw values to normalised intensity: ``1 / full_scale``."""
        return 1.0 / self.full_scale

    @property
    def bits(self) -> int:
        """Significant bits of a sample (bit_depth, else the dtype's width; 0 for floats)."""
        if self.frames.dtype.kind == "f":
            return 0
        return int(self.bit_depth) if self.bit_depth is not None else 8 * self.frames.dtype.itemsize

    @property
    def exposure(self) -> float:
        """The common exposure of the code frames (in ``exposure_unit``); ValueError if unknown or unequal."""
        if self.frame_exposure is None:
            raise ValueError("exposure: this capture does not carry its frame exposures")
        codes = self.frame_exposure[: self.n]
        if codes.size and not np.all(codes == codes[0]):
            raise ValueError(f"exposure: the code frames have different exposures {codes.tolist()}")
        return float(codes[0]) if codes.size else float(self.frame_exposure[-2])

    @property
    def exposure_ratio(self) -> np.ndarray | None:
        """(n,) float64 exposure of each code frame over the white frame's (1.0 = same), or None
        where the exposures are not known (none given, or the white frame's is 0)."""
        if self.frame_exposure is None or not self.frame_exposure[self.n] > 0:
            return None
        return self.frame_exposure[: self.n] / self.frame_exposure[self.n]

    def normalised(self, a: np.ndarray) -> np.ndarray:
        """float64 normalised intensity of raw samples ``a`` of this capture."""
        return np.asarray(a, dtype=np.float64) * self.scale


def split_stack(images: np.ndarray, n: int, **fields: Any) -> CodedCapture:
    """(n + 2, H, W) images in stack order (code frames, white, black) -> `CodedCapture` (views)."""
    images = np.asarray(images)
    if images.ndim != 3 or images.shape[0] != n + 2:
        raise ValueError(f"stack: expected (n + 2, H, W) = ({n + 2}, H, W) images, got shape {images.shape}")
    return CodedCapture(frames=images[:n], white=images[n], black=images[n + 1], **fields)
