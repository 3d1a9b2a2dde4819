"""`CodedCapture`: the one coded-capture type; `full_scale` and `bit_depth_of`, the one full-scale rule.

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
  0 .. 2**bit_depth - 1).  Not given: 8 for uint8; for uint16 detected from the samples by
  `bit_depth_of` (the smallest of `DETECTED_DEPTHS` holding the largest value, so 12-bit data in
  uint16 reads at 4095) and stored, so that ``scale`` is the one `edge.decode.decode` reads the
  same arrays at, whichever entry point a capture comes through.  A producer that knows its
  sensor's depth (the runtime, the simulator) states it.
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


#: Bit depths `bit_depth_of` detects uint16 data as, where none is given: the common ADC widths.
DETECTED_DEPTHS = (8, 10, 12, 14, 16)


def bit_depth_of(arrays: list[tuple[str, np.ndarray]], bit_depth: int | None) -> int | None:
    """The bit depth of integer samples (None for floats, which are normalised, and for uint8
    without ``bit_depth``: 8 bits).  ``arrays``: (name, array) pairs of one dtype.  ``bit_depth``
    where given: an integer that holds every value, 1..8 for uint8 and 1..16 for uint16
    (`full_scale`); else, for uint16, the smallest of `DETECTED_DEPTHS` whose full scale holds
    the largest value.  One ValueError naming the problem otherwise."""
    dtype = arrays[0][1].dtype
    if bit_depth is not None:
        full_scale(dtype, bit_depth)  # raises for a non-integer, outside 1..8 (uint8) / 1..16 (uint16)
    if dtype.kind == "f" or (dtype == np.uint8 and bit_depth is None):
        return None
    top = max(int(a.max()) if a.size else 0 for _, a in arrays)
    if bit_depth is None:
        return next(b for b in DETECTED_DEPTHS if top <= (1 << b) - 1)
    if top > (1 << int(bit_depth)) - 1:
        name = next(n for n, a in arrays if a.size and int(a.max()) == top)
        raise ValueError(f"{name}: values up to {top} exceed the full scale {(1 << int(bit_depth)) - 1} of "
                         f"bit_depth={int(bit_depth)}")
    return int(bit_depth)


def dtype_for_bits(bits: int) -> type:
    """Sample dtype of a sensor with ``bits`` ADC bits: uint8 for 8 (or fewer), uint16 up to 16."""
    if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)) or not 1 <= int(bits) <= 16:
        raise ValueError(f"bits: expected 1..16 ADC bits, got {bits}")
    return np.uint8 if int(bits) <= 8 else np.uint16


#: Largest sigma_r / sigma_s (normalised units, 1 = full scale): the one bound of the noise
#: sigmas, which the decoder's settings (`edge.decode.settings`), the profiles' ``[camera] sigma_r
#: / sigma_s`` (`edge.profiles.settings`) and the simulator's camera (`edge.sim.CameraModel`) take.
#: A read-noise or shot-noise sigma of more than the full scale means no signal; the bound also
#: keeps the variance's square finite in float64 (a sigma of 4e250 overflowed inside decode).
MAX_SIGMA = 1.0


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
        bit_depth: significant bits of integer samples; None: 8 for uint8, detected for uint16
            (`bit_depth_of`; the detected depth is stored here).
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
        if self.bit_depth is None:
            object.__setattr__(self, "bit_depth", self._detected_depth())
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

    def _detected_depth(self) -> int | None:
        """`bit_depth_of` the uint16 samples (either byte order) of frames, white, black and
        inverse (those of the frames' dtype); None for any other dtype (uint8 is 8 bits, floats are
        normalised, other dtypes are refused where a decoder reads them)."""
        dtype = getattr(self.frames, "dtype", None)
        if dtype is None or np.dtype(dtype).newbyteorder("=") != np.uint16:
            return None
        arrays = [(name, a) for name, a in (("frames", self.frames), ("white", self.white),
                                            ("black", self.black), ("inverse", self.inverse))
                  if a is not None and getattr(a, "dtype", None) == dtype]
        return bit_depth_of(arrays, None)

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
