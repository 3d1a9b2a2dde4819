"""Validation of decoder inputs: frame stacks, calibration frames, inverse frames.

Every check raises one `ValueError` naming what was expected and what was given (a capture in
which no pixel sees the projector raises its subclass `NoPatternContrast`). Arrays are
not copied here (the kernels read uint8 / uint16 / float32 / float64 directly) except to make
them C-contiguous and of the machine's byte order (`native`: a big-endian ``>u2`` capture decodes
as its values); the only product is a `edge.capture.CodedCapture` whose ``scale``
(`edge.capture.full_scale`) maps raw values to the normalised range [0, 1].  The bit-depth rule
(`edge.capture.bit_depth_of`, `edge.capture.DETECTED_DEPTHS`) lives with `CodedCapture`, which
applies it too; `validate` imports it from there.
"""

from __future__ import annotations

import numpy as np

from ..capture import CodedCapture, bit_depth_of
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


def check_code(code: Code) -> Code:
    """`code` where it is a `edge.codes.Code`; one TypeError otherwise (a code's name is not one)."""
    if not isinstance(code, Code):
        raise TypeError(f"code: expected an edge.codes.Code (e.g. edge.codes.get_code('ecc-22-10')), "
                        f"got {type(code).__name__} {code!r}"[:300])
    return code


def codebook_rows(code: Code, columns: int | None) -> int:
    """The codebook rows in use (projector width / stripe): ``columns``, an integer 1..code.size,
    or all of `code` for None; one ValueError otherwise."""
    if columns is None:
        return int(code.size)
    if isinstance(columns, bool) or not isinstance(columns, (int, np.integer)) or not 1 <= columns <= code.size:
        raise ValueError(f"columns: expected an integer 1..{code.size} for code {code.name!r}, got {columns!r}")
    return int(columns)


def native(a: np.ndarray) -> np.ndarray:
    """`a` in the machine's byte order (the same values; ``a`` itself where it is already): the
    kernels read native arrays, and numpy's dtype checks tell ``>u2`` from uint16."""
    return a if a.dtype.isnative else a.astype(a.dtype.newbyteorder("="))


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


def check_samples(arrays: list[tuple[str, np.ndarray]], *, scale_free: bool = False) -> None:
    """The sample checks of `validate` on (name, array) pairs: a dtype it takes, finite and
    non-negative floats normalised to [0, 1] (any scale with ``scale_free``), one dtype for all;
    one ValueError naming the array otherwise."""
    for name, a in arrays:
        _check_dtype(name, a)
        if not scale_free:
            _check_normalised(name, a)
    if len({a.dtype for _, a in arrays}) != 1:
        given = ", ".join(f"{name}={a.dtype}" for name, a in arrays)
        raise ValueError(f"expected {', '.join(name for name, _ in arrays)} of one dtype, got {given}")


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
    must share one dtype (uint8, uint16, float32 or float64; either byte order). bit_depth:
    significant bits of integer data, an integer that holds every value, 1..16 for uint16 (None:
    detected, the smallest of `edge.capture.DETECTED_DEPTHS` that holds the largest value, so that 12-bit data
    in uint16 is read as 12-bit and a contrast threshold means the same with and without it) and
    1..8 for uint8 (None: 8); ignored for floats (which must be normalised to [0, 1], unless
    ``scale_free``: for callers whose result does not depend on the intensity scale, the hard
    decisions of `edge.decode.check`).  `edge.capture.bit_depth_of` is the rule (the one
    `CodedCapture` applies where it is not given a bit depth).
    """
    check_code(code)
    frames = native(np.asarray(frames))
    white = native(np.asarray(white))
    black = native(np.asarray(black))
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
        inverse = native(np.asarray(inverse))
        if inverse.shape != frames.shape:
            raise ValueError(f"inverse: expected shape {frames.shape} to match frames, got {inverse.shape}")
    arrays = [("frames", frames), ("white", white), ("black", black)]
    if inverse is not None:
        arrays.append(("inverse", inverse))
    check_samples(arrays, scale_free=scale_free)
    if h == 0 or w == 0:
        raise ValueError(f"frames: expected a non-empty image, got shape {frames.shape}")
    if not np.greater(white, black).any():  # one dtype (checked above): compared as is
        raise NoPatternContrast()
    depth = bit_depth_of(arrays, bit_depth)  # one full-scale rule (floats are normalised)
    # Kernels index frames[i, y, x]; contiguous layout keeps that cheap.
    frames = np.ascontiguousarray(frames)
    white = np.ascontiguousarray(white)
    black = np.ascontiguousarray(black)
    if inverse is not None:
        inverse = np.ascontiguousarray(inverse)
    return CodedCapture(frames=frames, white=white, black=black, inverse=inverse, code=code, bit_depth=depth)
