"""OpenCV ``cv::structured_light::GrayCodePattern`` frames, as procam-calibration projects them.

For a ``W x H`` grid, ``GrayCodePattern.create(W, H).generate()`` returns
``2 * (ceil(log2 W) + ceil(log2 H))`` uint8 images: for each column bit of the reflected Gray code
``gray(x) = x ^ (x >> 1)``, most significant bit first, the pattern (255 where the bit is 1, else 0)
followed by its inverse; then the row bits the same way with ``gray(y)``.  procam-calibration's
``gen_graycode_imgs.py H W -graycode_step S`` generates the grid
``((W - 1) // S + 1) x ((H - 1) // S + 1)``, blows each cell up to ``S x S`` projector pixels
(pixel ``(y, x)`` shows cell ``(y // S, x // S)``) and appends an all-white and an all-black image:
``opencv_graycode(W, H, step=S)`` returns exactly those frames.
"""

from __future__ import annotations

import math

import numpy as np

from ..codes import get_code
from .render import calibration, render


def grid(width: int, height: int, step: int = 1) -> tuple[int, int]:
    """Gray-code grid (cells) of a ``width x height`` projector with ``step`` pixels per cell."""
    if int(step) != step or step < 1:
        raise ValueError(f"graycode step: expected a positive integer, got {step!r}")
    for label, v in (("width", width), ("height", height)):
        if int(v) != v or v < 1:
            raise ValueError(f"projector {label}: expected a positive integer, got {v!r}")
    gw, gh = (int(width) - 1) // int(step) + 1, (int(height) - 1) // int(step) + 1
    if gw < 2 or gh < 2:
        raise ValueError(f"an OpenCV Gray-code grid needs at least 2x2 cells, got {gw}x{gh} "
                         f"({width}x{height} pixels, step {step})")
    return gw, gh


def bits(cells_w: int, cells_h: int) -> tuple[int, int]:
    """(column bits, row bits) = (ceil(log2 W), ceil(log2 H)) of a ``W x H`` grid."""
    return math.ceil(math.log2(cells_w)), math.ceil(math.log2(cells_h))


def opencv_graycode(width: int, height: int, *, step: int = 1) -> np.ndarray:
    """(2 * (bc + br) + 2, height, width) uint8 frames in projection order (see module docstring):
    column pattern / inverse pairs MSB first, row pairs, white, black."""
    gw, gh = grid(width, height, step)
    bc, br = bits(gw, gh)
    cols = render(get_code(f"gray-{bc}"), int(width), int(height), stripe=int(step))
    rows = render(get_code(f"gray-{br}"), int(width), int(height), stripe=int(step), orientation="rows")
    white, black = calibration(int(width), int(height))
    out = np.empty((2 * (bc + br) + 2, int(height), int(width)), np.uint8)
    for i, f in enumerate(np.concatenate([cols, rows])):
        out[2 * i] = f
        out[2 * i + 1] = 255 - f
    out[-2], out[-1] = white, black
    return out
