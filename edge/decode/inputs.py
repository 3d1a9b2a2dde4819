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


def validate(
    frames: np.ndarray,
    white: np.ndarray,
    black: np.ndarray,
    code: Code,
    inverse: np.ndarray | None = None,
    bit_depth: int | None = None,
) -> CodedCapture:
    """Check shapes, dtypes and values of a capture for `code`; return a `CodedCapture`.

    frames (n, H, W) with n == code.n; white, black (H, W); inverse (n, H, W) or None. All arrays
    must share one dtype (uint8, uint16, float32 or float64). bit_depth: significant bits of
    uint16 data (default 16); ignored for uint8 (8) and floats (already normalised to [0, 1]).
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
    dtypes = {a.dtype for _, a in arrays}
    if len(dtypes) != 1:
        given = ", ".join(f"{name}={a.dtype}" for name, a in arrays)
        raise ValueError(f"expected frames, white, black (and inverse) of one dtype, got {given}")
    if h == 0 or w == 0:
        raise ValueError(f"frames: expected a non-empty image, got shape {frames.shape}")
    if not np.greater(white, black).any():  # one dtype (checked above): compared as is
        raise NoPatternContrast()
    # bit_depth counts for uint16 only (uint8 is 8 bits, floats are normalised): one full-scale rule
    depth = None if bit_depth is None or frames.dtype != np.uint16 else int(bit_depth)
    full_scale(frames.dtype, depth)  # raises on a bit_depth outside 1..16
    # Kernels index frames[i, y, x]; contiguous layout keeps that cheap.
    frames = np.ascontiguousarray(frames)
    white = np.ascontiguousarray(white)
    black = np.ascontiguousarray(black)
    if inverse is not None:
        inverse = np.ascontiguousarray(inverse)
    return CodedCapture(frames=frames, white=white, black=black, inverse=inverse, code=code, bit_depth=depth)
