"""Projector frames from a `Code`.

Column mapping: projector column ``x`` (0-based, left to right) sends codebook row ``x // stripe``.
A projector narrower than ``q**k * stripe`` columns uses only the first ``ceil(width / stripe)``
codebook rows (the last stripe may be cut); a wider one is an error, since columns past the
codebook would repeat codewords.  With ``orientation="rows"`` the same mapping applies to
projector rows ``y`` (``height`` plays the role of ``width``).

Levels: binary symbols map to 0 / 255; an N-ary symbol ``s`` of a code with alphabet ``q`` maps to
``round(255 * s / (q - 1))``.
"""

from __future__ import annotations

import numpy as np

from ..codes.code import Code

ORIENTATIONS = ("columns", "rows")


def symbol_levels(q: int) -> np.ndarray:
    """(q,) uint8 grey level of each symbol: round(255 * s / (q - 1))."""
    if q < 2:
        raise ValueError(f"alphabet size q must be >= 2, got {q}")
    return np.round(255.0 * np.arange(q) / (q - 1)).astype(np.uint8)


def _check_size(width: int, height: int) -> None:
    for label, v in (("width", width), ("height", height)):
        if not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"projector {label} must be a positive integer, got {v!r}")


def column_rows(code: Code, extent: int, stripe: int = 1) -> np.ndarray:
    """(extent,) int64: codebook row sent by each projector column (x // stripe); ValueError when
    the projector is wider than ``code.size * stripe``."""
    if not isinstance(stripe, (int, np.integer)) or stripe < 1:
        raise ValueError(f"stripe must be a positive integer number of projector columns, got {stripe!r}")
    if extent > code.size * stripe:
        raise ValueError(
            f"projector extent {extent} is larger than the {code.size} codewords of {code.name!r} times "
            f"stripe {stripe} = {code.size * stripe} columns"
        )
    return np.arange(extent, dtype=np.int64) // stripe


def render(code: Code, width: int, height: int, *, stripe: int = 1, orientation: str = "columns") -> np.ndarray:
    """All n frames of ``code`` for a ``width`` x ``height`` projector: uint8 (n, height, width).

    Frame i, pixel (y, x) shows symbol ``codebook[x // stripe, i]`` (``y // stripe`` for rows).
    """
    _check_size(width, height)
    if orientation not in ORIENTATIONS:
        raise ValueError(f"orientation must be 'columns' or 'rows', got {orientation!r}")
    extent = width if orientation == "columns" else height
    rows = column_rows(code, extent, stripe)
    levels = symbol_levels(code.q)
    profile = levels[code.codebook[rows].T]  # (n, extent)
    if orientation == "columns":
        return np.ascontiguousarray(np.broadcast_to(profile[:, None, :], (code.n, height, width)))
    return np.ascontiguousarray(np.broadcast_to(profile[:, :, None], (code.n, height, width)))


def calibration(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """(white, black) uint8 (height, width) frames: all 255 and all 0."""
    _check_size(width, height)
    return np.full((height, width), 255, dtype=np.uint8), np.zeros((height, width), dtype=np.uint8)
