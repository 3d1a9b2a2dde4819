"""Loaders for real capture layouts.

``opencv-graycode``: the layout of OpenCV's ``cv::structured_light::GrayCodePattern`` for a
``W x H`` projector: ``2 * (ceil(log2 W) + ceil(log2 H)) + 2`` images in file-name order: the
column bits of a reflected Gray code (MSB first), each followed by its inverse, then the row
bits the same way, then an all-white and an all-black image.  Column ``c`` sends
``gray(c) = c ^ (c >> 1)``, which is `edge.codes.get_code("gray-<bits>")`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..codes import Code, get_code

LAYOUTS = ("opencv-graycode",)
_IMAGE_SUFFIXES = {".png", ".tif", ".tiff", ".bmp", ".pgm", ".jpg", ".jpeg"}


@dataclass(frozen=True)
class Capture:
    """A real capture ready for `decode`.

    frames, inverse: (n, H, W) column-bit patterns and their inverses; white, black: (H, W);
    row_frames, row_inverse: (m, H, W) row-bit patterns (unused by column decoding);
    code: the column code; columns: projector width in codebook rows.
    """

    frames: np.ndarray
    inverse: np.ndarray
    white: np.ndarray
    black: np.ndarray
    row_frames: np.ndarray
    row_inverse: np.ndarray
    code: Code
    columns: int



def _read_gray(path: Path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"{path}: expected a readable image, got an unreadable file")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"{path}: expected an 8- or 16-bit image, got dtype {img.dtype}")
    return img


def load_opencv_graycode(directory: str | Path, projector: tuple[int, int] = (1024, 768)) -> Capture:
    """Load an OpenCV GrayCodePattern capture from `directory` (images sorted by file name)."""
    d = Path(directory)
    if not d.is_dir():
        raise FileNotFoundError(f"capture directory not found: {d}")
    files = sorted(p for p in d.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES)
    pw, ph = projector
    col_bits = math.ceil(math.log2(pw))
    row_bits = math.ceil(math.log2(ph))
    expected = 2 * (col_bits + row_bits) + 2
    if len(files) != expected:
        raise ValueError(
            f"{d}: expected {expected} images for a {pw}x{ph} OpenCV Gray-code capture, got {len(files)}"
        )
    imgs = np.stack([_read_gray(p) for p in files])
    cols = imgs[: 2 * col_bits]
    rows = imgs[2 * col_bits: 2 * (col_bits + row_bits)]
    return Capture(
        frames=np.ascontiguousarray(cols[0::2]), inverse=np.ascontiguousarray(cols[1::2]),
        white=imgs[-2], black=imgs[-1], row_frames=np.ascontiguousarray(rows[0::2]),
        row_inverse=np.ascontiguousarray(rows[1::2]), code=get_code(f"gray-{col_bits}"), columns=pw,
    )


def load(directory: str | Path, layout: str, projector: tuple[int, int]) -> Capture:
    """Load a capture in one of `LAYOUTS`."""
    if layout == "opencv-graycode":
        return load_opencv_graycode(directory, projector)
    raise ValueError(f"layout: expected one of {', '.join(LAYOUTS)}, got {layout!r}")
