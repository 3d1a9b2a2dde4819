"""Validation of decoder inputs: frame stacks, calibration frames, inverse frames.

Every check raises one `ValueError` naming what was expected and what was given (a capture in
which no pixel sees the projector raises its subclass `NoPatternContrast`). Arrays are
never copied here (the kernels read uint8 / uint16 / float32 / float64 directly); the only
product is a `edge.capture.CodedCapture` whose ``scale`` (`edge.capture.full_scale`) maps raw
values to the normalised range [0, 1].
"""

from __future__ import annotations

import numpy as np

from ..capture import CodedCapture, full_scale
from ..codes import Code

#: The message of `NoPatternContrast`.
NO_CONTRAST = ("white/black: expected white brighter than black somewhere, got white <= black everywhere "
               "(no pixel sees the projector: it is off or blocked, the lens is covered, every pixel is "
               "saturated, or white and black are swapped)")


class NoPatternContrast(ValueError):
    """A capture whose white frame is nowhere brighter than its black frame: no pixel can be
    decoded.  A `ValueError` (callers that treat it as bad input still do); the depth service
    publishes an empty depth map for such a stack instead of counting a decode error
    (`edge.runtime.pipeline.DepthPipeline.process`), since a covered lens or a projector that is
    off is a scene, not a fault."""

    def __init__(self, message: str = NO_CONTRAST) -> None:
        super().__init__(message)


_INT_DTYPES = (np.uint8, np.uint16)
_FLOAT_DTYPES = (np.float32, np.float64)


def _check_dtype(name: str, a: np.ndarray) -> None:
    if a.dtype not in _INT_DTYPES + _FLOAT_DTYPES:
        raise ValueError(
            f"{name}: expected dtype uint8, uint16, float32 or float64, got {a.dtype}"
        )
    if a.dtype.kind == "f":
        if not np.isfinite(a).all():
            raise ValueError(f"{name}: expected finite intensities, got NaN or infinite values")
        if a.size and float(a.min()) < 0.0:
            raise ValueError(f"{name}: expected non-negative intensities, got minimum {float(a.min())}")


def _check_normalised(name: str, a: np.ndarray) -> None:
    if a.dtype.kind == "f" and a.size and float(a.max()) > 1.0:
        raise ValueError(f"{name}: expected float intensities normalised to [0, 1] (1 = full scale), got maximum "
                         f"{float(a.max()):g}: divide raw counts by the sensor's full scale (e.g. 4095 for 12 bits)")


#: Bit depths `validate` detects uint16 data as, where none is given: the common ADC widths.
DETECTED_DEPTHS = (8, 10, 12, 14, 16)


def _bit_depth(arrays: list[tuple[str, np.ndarray]], bit_depth: int | None) -> int | None:
    """The bit depth of uint16 data (None for other dtypes): ``bit_depth`` where given (1..16, an
    integer; a value above its full scale raises), else the smallest of `DETECTED_DEPTHS` whose
    full scale holds the largest value."""
    if arrays[0][1].dtype != np.uint16:
        return None
    top = max(int(a.max()) if a.size else 0 for _, a in arrays)
    if bit_depth is None:
        return next(b for b in DETECTED_DEPTHS if top <= (1 << b) - 1)
    if isinstance(bit_depth, bool) or not isinstance(bit_depth, (int, np.integer)):
        raise ValueError(f"bit_depth: expected an integer number of bits, got {bit_depth!r}")
    full_scale(np.uint16, int(bit_depth))  # raises outside 1..16
    if top > (1 << int(bit_depth)) - 1:
        name = next(n for n, a in arrays if a.size and int(a.max()) == top)
        raise ValueError(f"{name}: values up to {top} exceed the full scale {(1 << int(bit_depth)) - 1} of "
                         f"bit_depth={int(bit_depth)}")
    return int(bit_depth)


def validate(
    frames: np.ndarray,
    white: np.ndarray,
    black: np.ndarray,
    code: Code,
    inverse: np.ndarray | None = None,
    bit_depth: int | None = None,
    *,
    scale_free: bool = False,
) -> CodedCapture:
    """Check shapes, dtypes and values of a capture for `code`; return a `CodedCapture`.

    frames (n, H, W) with n == code.n; white, black (H, W); inverse (n, H, W) or None. All arrays
    must share one dtype (uint8, uint16, float32 or float64). bit_depth: significant bits of
    uint16 data, an integer 1..16 that holds every value (None: detected, the smallest of
    `DETECTED_DEPTHS` that holds the largest value, so that 12-bit data in uint16 is read as 12-bit
    and a contrast threshold means the same with and without it); ignored for uint8 (8) and floats
    (which must be normalised to [0, 1], unless ``scale_free``: for callers whose result does not
    depend on the intensity scale, the hard decisions of `edge.decode.check`).
    """
    frames = np.asarray(frames)
    white = np.asarray(white)
    black = np.asarray(black)
    if frames.ndim != 3:
        raise ValueError(f"frames: expected a (n, H, W) stack, got shape {frames.shape}")
    if frames.shape[0] != code.n:
        raise ValueError(
            f"frames: code {code.name!r} has n={code.n} frames, got a stack of {frames.shape[0]}"
        )
    h, w = frames.shape[1:]
    for name, a in (("white", white), ("black", black)):
        if a.shape != (h, w):
            raise ValueError(f"{name}: expected shape {(h, w)} to match frames, got {a.shape}")
    if inverse is not None:
        inverse = np.asarray(inverse)
        if inverse.shape != frames.shape:
            raise ValueError(f"inverse: expected shape {frames.shape} to match frames, got {inverse.shape}")
    arrays = [("frames", frames), ("white", white), ("black", black)]
    if inverse is not None:
        arrays.append(("inverse", inverse))
    for name, a in arrays:
        _check_dtype(name, a)
        if not scale_free:
            _check_normalised(name, a)
    dtypes = {a.dtype for _, a in arrays}
    if len(dtypes) != 1:
        given = ", ".join(f"{name}={a.dtype}" for name, a in arrays)
        raise ValueError(f"expected frames, white, black (and inverse) of one dtype, got {given}")
    if h == 0 or w == 0:
        raise ValueError(f"frames: expected a non-empty image, got shape {frames.shape}")
    if not np.greater(white, black).any():  # one dtype (checked above): compared as is
        raise NoPatternContrast()
    # bit_depth counts for uint16 only (uint8 is 8 bits, floats are normalised): one full-scale rule
    depth = _bit_depth(arrays, bit_depth)
    # Kernels index frames[i, y, x]; contiguous layout keeps that cheap.
    frames = np.ascontiguousarray(frames)
    white = np.ascontiguousarray(white)
    black = np.ascontiguousarray(black)
    if inverse is not None:
        inverse = np.ascontiguousarray(inverse)
    return CodedCapture(frames=frames, white=white, black=black, inverse=inverse, code=code, bit_depth=depth)
