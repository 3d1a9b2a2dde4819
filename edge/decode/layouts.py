"""Loaders for real capture layouts.

``opencv-graycode``: the layout of OpenCV's ``cv::structured_light::GrayCodePattern`` for a
``W x H`` code grid: ``2 * (ceil(log2 W) + ceil(log2 H)) + 2`` images in file-name order: the
column bits of a reflected Gray code (MSB first), each followed by its inverse, then the row
bits the same way, then an all-white and an all-black image.  Column ``c`` sends
``gray(c) = c ^ (c >> 1)``, which is `edge.codes.get_code("gray-<bits>")`.  ``W x H`` is the
grid the patterns were generated for, in code cells: procam-calibration's
``gen_graycode_imgs.py PH PW -graycode_step S`` projects a ``((PW - 1) // S + 1) x ((PH - 1) // S + 1)``
grid.

``manifest``: a directory holding ``manifest.json`` (`edge.patterns.manifest`, written by
``edge patterns write``) and the captured image of every frame under the frame's file name (any
image suffix).  ``auto`` (the CLI default): ``manifest`` when the directory holds a
``manifest.json``, else ``opencv-graycode``.
"""

from __future__ import annotations

import glob
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..codes import Code, get_code
from ..patterns.manifest import MANIFEST, LayoutSpec, read_manifest
from .decoder import decode

LAYOUTS = ("auto", "opencv-graycode", "manifest")
_IMAGE_SUFFIXES = {".png", ".tif", ".tiff", ".bmp", ".pgm", ".jpg", ".jpeg"}


@dataclass(frozen=True)
class Capture:
    """A real capture ready for `decode`.

    frames, inverse: (n, H, W) column-bit patterns and their inverses (n = 0 when the layout codes
    no columns; inverse None when it has no inverse frames); white, black: (H, W);
    row_frames, row_inverse: (m, H, W) row-bit patterns (m = 0 when the layout codes no rows;
    row_inverse None without inverse frames); code: the column code (None without columns);
    columns: column cells in use; row_code, rows: the same for rows; stripe: projector pixels per
    code cell when the layout states it (a manifest), else None; layout: the layout loaded.
    """

    frames: np.ndarray
    inverse: np.ndarray | None
    white: np.ndarray
    black: np.ndarray
    row_frames: np.ndarray
    row_inverse: np.ndarray | None
    code: Code | None
    columns: int
    row_code: Code | None = None
    rows: int = 0
    stripe: int | None = None
    layout: str = "opencv-graycode"


def _read_gray(path: Path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"{path}: expected a readable image, got an unreadable file")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"{path}: expected an 8- or 16-bit image, got dtype {img.dtype}")
    return img


def _stack(images: list[np.ndarray], files: list[Path]) -> np.ndarray:
    shapes = {(im.shape, im.dtype.str) for im in images}
    if len(shapes) > 1:
        first = images[0]
        bad = next(f for f, im in zip(files, images) if im.shape != first.shape or im.dtype != first.dtype)
        raise ValueError(f"{bad}: expected every image to be {first.shape[1]}x{first.shape[0]} {first.dtype} "
                         f"like {files[0].name}, got another size or bit depth")
    return np.stack(images)


def load_opencv_graycode(directory: str | Path, projector: tuple[int, int] = (1024, 768)) -> Capture:
    """Load an OpenCV GrayCodePattern capture from `directory` (images sorted by file name).

    projector: the ``(W, H)`` Gray-code grid in code cells (see the module docstring)."""
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
            f"{d}: expected {expected} images for a {pw}x{ph} OpenCV Gray-code capture, got {len(files)} "
            f"(--projector is the Gray-code grid in cells: projector pixels / graycode step)"
        )
    imgs = _stack([_read_gray(p) for p in files], files)
    cols = imgs[: 2 * col_bits]
    rows = imgs[2 * col_bits: 2 * (col_bits + row_bits)]
    return Capture(
        frames=np.ascontiguousarray(cols[0::2]), inverse=np.ascontiguousarray(cols[1::2]),
        white=imgs[-2], black=imgs[-1], row_frames=np.ascontiguousarray(rows[0::2]),
        row_inverse=np.ascontiguousarray(rows[1::2]), code=get_code(f"gray-{col_bits}"), columns=pw,
        row_code=get_code(f"gray-{row_bits}"), rows=ph, stripe=None, layout="opencv-graycode",
    )


def _find(directory: Path, name: str) -> Path:
    exact = directory / name
    if exact.is_file():
        return exact
    stem = Path(name).stem
    matches = sorted(p for p in directory.glob(f"{glob.escape(stem)}.*") if p.suffix.lower() in _IMAGE_SUFFIXES)
    if len(matches) == 1:
        return matches[0]
    if not matches:
        raise FileNotFoundError(f"{directory}: expected the captured image of frame {name} "
                                f"({stem} with an image suffix), not found")
    raise ValueError(f"{directory}: expected one captured image of frame {name}, found "
                     f"{', '.join(p.name for p in matches)}")


def load_manifest(directory: str | Path, manifest: str | Path | None = None) -> Capture:
    """Load the captures of a pattern set described by a manifest (`edge.patterns.manifest`).

    directory: the captured images, named after the manifest's frames; manifest: the
    ``manifest.json`` (default ``directory/manifest.json``)."""
    d = Path(directory)
    if not d.is_dir():
        raise FileNotFoundError(f"capture directory not found: {d}")
    spec: LayoutSpec = read_manifest(Path(manifest) if manifest is not None else d / MANIFEST)
    names: list[str] = [spec.white, spec.black]
    for ax in spec.axes.values():
        names += list(ax.patterns) + list(ax.inverse or ())
    paths = [_find(d, n) for n in names]
    imgs = dict(zip(names, _stack([_read_gray(p) for p in paths], paths)))
    white, black = imgs[spec.white], imgs[spec.black]
    empty = np.zeros((0,) + white.shape, white.dtype)
    parts: dict[str, tuple] = {}
    for axis in ("columns", "rows"):
        ax = spec.axes.get(axis)
        if ax is None:
            parts[axis] = (empty, None, None, 0)
            continue
        code = get_code(ax.code)
        if len(ax.patterns) != code.n:
            raise ValueError(f"{d}: manifest axis {axis} has {len(ax.patterns)} pattern frames, code "
                             f"{code.name} has n = {code.n}")
        if ax.cells > code.size:
            raise ValueError(f"{d}: manifest axis {axis} uses {ax.cells} cells, code {code.name} has {code.size}")
        frames = np.stack([imgs[n] for n in ax.patterns])
        inverse = None if ax.inverse is None else np.stack([imgs[n] for n in ax.inverse])
        parts[axis] = (frames, inverse, code, ax.cells)
    cf, ci, cc, cn = parts["columns"]
    rf, ri, rc, rn = parts["rows"]
    return Capture(frames=cf, inverse=ci, white=white, black=black, row_frames=rf, row_inverse=ri, code=cc,
                   columns=cn, row_code=rc, rows=rn, stripe=spec.stripe, layout="manifest")


def load(directory: str | Path, layout: str, projector: tuple[int, int], manifest: str | Path | None = None) -> Capture:
    """Load a capture in one of `LAYOUTS` (projector: the OpenCV Gray-code grid, see above)."""
    if layout == "auto":
        layout = "manifest" if manifest is not None or (Path(directory) / MANIFEST).is_file() else "opencv-graycode"
    if layout == "opencv-graycode":
        return load_opencv_graycode(directory, projector)
    if layout == "manifest":
        return load_manifest(directory, manifest)
    raise ValueError(f"layout: expected one of {', '.join(LAYOUTS)}, got {layout!r}")


def decode_axes(cap: Capture, axes: tuple[str, ...] = ("columns", "rows"), **decode_kwargs) -> dict:
    """Decode the coded axes of ``cap`` among ``axes`` with `edge.decode.decode` (keyword
    arguments passed on, e.g. ``method``). Returns {axis: Decoded} for the axes the capture has;
    Decoded.column holds code cells (-1 invalid)."""
    out = {}
    if "columns" in axes and cap.code is not None and cap.frames.shape[0]:
        out["columns"] = decode(cap.frames, cap.white, cap.black, cap.code, inverse=cap.inverse,
                                columns=cap.columns, **decode_kwargs)
    if "rows" in axes and cap.row_code is not None and cap.row_frames.shape[0]:
        out["rows"] = decode(cap.row_frames, cap.white, cap.black, cap.row_code, inverse=cap.row_inverse,
                             columns=cap.rows, **decode_kwargs)
    return out
