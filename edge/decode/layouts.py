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

from ..capture import CodedCapture
from ..codes import Code, get_code
from ..patterns.manifest import MANIFEST, LayoutSpec, read_manifest
from .decoder import decode_capture

LAYOUTS = ("auto", "opencv-graycode", "manifest")
_IMAGE_SUFFIXES = {".png", ".tif", ".tiff", ".bmp", ".pgm", ".jpg", ".jpeg"}


@dataclass(frozen=True, eq=False)
class LayoutCapture:
    """A real capture ready for `decode`: one `edge.capture.CodedCapture` per coded axis.

    axes: {"columns": CodedCapture, "rows": CodedCapture}, holding only the axes the layout codes
    (each with its code, ``columns`` = cells in use, inverse frames or None, the shared white and
    black; stripe None, so that it decodes in code cells; no exposure: image files do not carry it);
    white, black: (H, W); stripe: projector pixels per code cell when the layout states it (a
    manifest), else None; layout: the layout loaded.  ``frames``, ``inverse``, ``code``,
    ``columns`` and ``row_frames``, ``row_inverse``, ``row_code``, ``rows`` read the axes (empty
    (0, H, W) frames, None and 0 for an axis the layout does not code).
    """

    axes: dict[str, CodedCapture]
    white: np.ndarray
    black: np.ndarray
    stripe: int | None = None
    layout: str = "opencv-graycode"

    def _get(self, axis: str, name: str, default):
        a = self.axes.get(axis)
        if a is None:
            return np.zeros((0,) + self.white.shape, self.white.dtype) if name == "frames" else default
        return getattr(a, name)

    frames = property(lambda self: self._get("columns", "frames", None), doc="(n, H, W) column-code frames")
    inverse = property(lambda self: self._get("columns", "inverse", None), doc="(n, H, W) inverses or None")
    code = property(lambda self: self._get("columns", "code", None), doc="the column code or None")
    columns = property(lambda self: int(self._get("columns", "columns", 0)), doc="column cells in use")
    row_frames = property(lambda self: self._get("rows", "frames", None), doc="(m, H, W) row-code frames")
    row_inverse = property(lambda self: self._get("rows", "inverse", None), doc="(m, H, W) inverses or None")
    row_code = property(lambda self: self._get("rows", "code", None), doc="the row code or None")
    rows = property(lambda self: int(self._get("rows", "columns", 0)), doc="row cells in use")


def _axis(frames: np.ndarray, inverse: np.ndarray | None, white: np.ndarray, black: np.ndarray, code: Code,
          cells: int) -> CodedCapture:
    """One coded axis; decoded in code cells (stripe None: the layout's stripe is on `LayoutCapture`)."""
    return CodedCapture(frames=frames, white=white, black=black, inverse=inverse, code=code, columns=int(cells))


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


def load_opencv_graycode(directory: str | Path, projector: tuple[int, int] = (1024, 768)) -> LayoutCapture:
    """Load an OpenCV GrayCodePattern capture from `directory` (images sorted by file name).

    projector: the ``(W, H)`` Gray-code grid in code cells (see the module docstring)."""
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise ValueError(f"capture directory {d} is a file; expected the folder of the capture's images")
    if not d.is_dir():
        raise FileNotFoundError(f"capture directory not found: {d}")
    files = sorted(p for p in d.iterdir() if is_capture_image(p))
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
    white, black = imgs[-2], imgs[-1]
    axes = {
        "columns": _axis(np.ascontiguousarray(cols[0::2]), np.ascontiguousarray(cols[1::2]), white, black,
                         get_code(f"gray-{col_bits}"), pw),
        "rows": _axis(np.ascontiguousarray(rows[0::2]), np.ascontiguousarray(rows[1::2]), white, black,
                      get_code(f"gray-{row_bits}"), ph),
    }
    return LayoutCapture(axes=axes, white=white, black=black, stripe=None, layout="opencv-graycode")


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


def load_manifest(directory: str | Path, manifest: str | Path | None = None) -> LayoutCapture:
    """Load the captures of a pattern set described by a manifest (`edge.patterns.manifest`).

    directory: the captured images, named after the manifest's frames; manifest: the
    ``manifest.json`` (default ``directory/manifest.json``)."""
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise ValueError(f"capture directory {d} is a file; expected the folder of the capture's images")
    if not d.is_dir():
        raise FileNotFoundError(f"capture directory not found: {d}")
    spec: LayoutSpec = read_manifest(Path(manifest) if manifest is not None else d / MANIFEST)
    names: list[str] = [spec.white, spec.black]
    for ax in spec.axes.values():
        names += list(ax.patterns) + list(ax.inverse or ())
    paths = [_find(d, n) for n in names]
    imgs = dict(zip(names, _stack([_read_gray(p) for p in paths], paths)))
    white, black = imgs[spec.white], imgs[spec.black]
    axes: dict[str, CodedCapture] = {}
    for axis in ("columns", "rows"):
        ax = spec.axes.get(axis)
        if ax is None:
            continue
        code = get_code(ax.code)
        if len(ax.patterns) != code.n:
            raise ValueError(f"{d}: manifest axis {axis} has {len(ax.patterns)} pattern frames, code "
                             f"{code.name} has n = {code.n}")
        if ax.cells > code.size:
            raise ValueError(f"{d}: manifest axis {axis} uses {ax.cells} cells, code {code.name} has {code.size}")
        frames = np.stack([imgs[n] for n in ax.patterns])
        inverse = None if ax.inverse is None else np.stack([imgs[n] for n in ax.inverse])
        axes[axis] = _axis(frames, inverse, white, black, code, ax.cells)
    return LayoutCapture(axes=axes, white=white, black=black, stripe=spec.stripe, layout="manifest")


def resolve_layout(directory: str | Path, layout: str, manifest: str | Path | None = None) -> str:
    """The layout `load` reads ``directory`` as: ``layout``, or for "auto" "manifest" where a
    manifest is given or the directory holds one, else "opencv-graycode" (which reads every image
    of the directory, `is_capture_image`)."""
    if layout == "auto":
        return "manifest" if manifest is not None or (Path(directory) / MANIFEST).is_file() else "opencv-graycode"
    return layout


def is_capture_image(path: str | Path) -> bool:
    """Whether the opencv-graycode layout takes a file of its directory for one of the capture's images."""
    return Path(path).suffix.lower() in _IMAGE_SUFFIXES


def load(directory: str | Path, layout: str, projector: tuple[int, int], manifest: str | Path | None = None) -> LayoutCapture:
    """Load a capture in one of `LAYOUTS` (projector: the OpenCV Gray-code grid, see above)."""
    layout = resolve_layout(directory, layout, manifest)
    if layout == "opencv-graycode":
        return load_opencv_graycode(directory, projector)
    if layout == "manifest":
        return load_manifest(directory, manifest)
    raise ValueError(f"layout: expected one of {', '.join(LAYOUTS)}, got {layout!r}")


def decode_axes(cap: LayoutCapture, axes: tuple[str, ...] = ("columns", "rows"), **decode_kwargs) -> dict:
    """Decode the coded axes of ``cap`` among ``axes`` with `edge.decode.decoder.decode_capture`
    (keyword arguments passed on, e.g. ``method``). Returns {axis: Decoded} for the axes the
    capture has; Decoded.column holds code cells (-1 invalid)."""
    out = {}
    for axis in ("columns", "rows"):
        a = cap.axes.get(axis)
        if axis in axes and a is not None and a.code is not None and a.n:
            out[axis] = decode_capture(a, a.code, **decode_kwargs)
    return out
