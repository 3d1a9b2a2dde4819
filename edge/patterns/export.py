"""Write projector frames as PNG files plus a JSON manifest (for a real projector).

Two layouts, both described by ``manifest.json`` (format: `edge.patterns.manifest`):
``write_patterns`` for any edge code (one axis or both, optional inverse frames) and
``write_opencv_graycode`` for OpenCV's GrayCodePattern layout (`edge.patterns.opencv`).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from ..codes.code import Code
from .manifest import FORMAT, MANIFEST, frame_entry
from .opencv import bits, grid, opencv_graycode
from .render import calibration, render

ORIENTATIONS = ("columns", "rows", "both")


#: The files a pattern set writes (and an earlier set in the same directory may have left).
SET_FILES = ("pattern_*.png", "white.png", "black.png", MANIFEST)


def _prepare(directory: str | Path, overwrite: bool) -> Path:
    """The output directory, created; FileExistsError where it holds a pattern set already (its
    frames would mix with the new ones: fewer new frames leave old ``pattern_*.png`` behind), unless
    ``overwrite``, which removes that set's files first (nothing else in the directory)."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    old = sorted({f for pattern in SET_FILES for f in out.glob(pattern) if f.is_file()})
    if old and not overwrite:
        raise FileExistsError(f"{out} holds a pattern set already ({len(old)} files: {old[0].name}, ...); "
                              f"choose an empty directory or pass --overwrite to replace it")
    for f in old:
        f.unlink()
    return out


def write_patterns(code: Code, directory: str | Path, width: int, height: int, *, stripe: int = 1,
                   orientation: str = "columns", inverse: bool = False, overwrite: bool = False) -> dict:
    """Write ``pattern_00.png`` .. (frame order), ``white.png``, ``black.png`` and ``manifest.json``.

    orientation: ``"columns"`` (code along x), ``"rows"`` (along y) or ``"both"`` (the column
    frames, then the row frames).  inverse: follow every pattern frame by its inverse (255 minus
    it), as OpenCV's layout does.  overwrite: replace a pattern set in ``directory`` (else
    FileExistsError, `_prepare`).  Returns the manifest: the format-1 keys of
    `edge.patterns.manifest` plus the code's name, n, k, q, d_min, ``columns_used`` (cells of the
    first axis), ``mapping``, ``levels`` and ``patterns`` (code frames in projection order).
    """
    if orientation not in ORIENTATIONS:
        raise ValueError(f"orientation must be one of {', '.join(ORIENTATIONS)}, got {orientation!r}")
    axes = ("columns", "rows") if orientation == "both" else (orientation,)
    for axis in axes:  # one cell sends one codeword to the whole projector: nothing to decode
        pixels = int(width if axis == "columns" else height)
        if int(stripe) >= 1 and -(-pixels // int(stripe)) < 2:
            raise ValueError(f"stripe {stripe}: a projector {pixels} pixels {'wide' if axis == 'columns' else 'high'} "
                             f"gets one code cell along its {axis}; expected a stripe of at most {max(1, (pixels - 1))} "
                             f"pixels (at least 2 cells)")
    rendered = [(axis, render(code, width, height, stripe=stripe, orientation=axis)) for axis in axes]
    white, black = calibration(width, height)
    out = _prepare(directory, overwrite)
    total = sum(f.shape[0] for _, f in rendered) * (2 if inverse else 1)
    digits = max(2, len(str(total - 1)))
    files: list[str] = []
    frames: list[dict] = []
    for axis, stack in rendered:
        for bit, frame in enumerate(stack):
            for role, image in (("pattern", frame), ("inverse", 255 - frame))[: 2 if inverse else 1]:
                name = f"pattern_{len(files):0{digits}d}.png"
                _write_png(out / name, image)
                files.append(name)
                frames.append(frame_entry(name, role, axis, bit))
    _write_png(out / "white.png", white)
    _write_png(out / "black.png", black)
    frames += [frame_entry("white.png", "white"), frame_entry("black.png", "black")]
    cells = {a: -(-(width if a == "columns" else height) // stripe) for a in axes}
    manifest = {
        "format": FORMAT, "layout": "edge",
        "code": code.name, "family": code.family, "construction": code.construction,
        "n": code.n, "k": code.k, "q": code.q, "d_min": code.d_min,
        "width": width, "height": height, "stripe": stripe, "orientation": orientation,
        "inverse": bool(inverse),
        "axes": {a: {"code": code.name, "cells": cells[a]} for a in axes},
        "columns_used": cells[axes[0]],
        "mapping": "projector column x sends codebook row x // stripe (rows: y // stripe)",
        "bit_order": "frame 'bit' b shows symbol b of the codeword (codebook column b), frame 0 first",
        "levels": "symbol s -> round(255 * s / (q - 1)); inverse = 255 - pattern",
        "patterns": files, "white": "white.png", "black": "black.png",
        "frames": frames,
    }
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return manifest


def write_opencv_graycode(directory: str | Path, width: int, height: int, *, step: int = 1,
                          overwrite: bool = False) -> dict:
    """Write OpenCV GrayCodePattern's frames for a ``width x height`` projector (``step`` pixels per
    Gray-code cell) as ``pattern_00.png`` .. ``pattern_NN.png`` (the last two white and black, the
    names and order of procam-calibration's ``gen_graycode_imgs.py``) plus ``manifest.json``.
    overwrite: as `write_patterns`.  Returns the manifest."""
    gw, gh = grid(width, height, step)
    bc, br = bits(gw, gh)
    stack = opencv_graycode(width, height, step=step)
    out = _prepare(directory, overwrite)
    roles: list[tuple[str, str | None, int | None]] = []
    for axis, nbits in (("columns", bc), ("rows", br)):
        for b in range(nbits):
            roles += [("pattern", axis, b), ("inverse", axis, b)]
    roles += [("white", None, None), ("black", None, None)]
    frames = []
    for i, (image, (role, axis, b)) in enumerate(zip(stack, roles)):
        name = f"pattern_{i:02d}.png"
        _write_png(out / name, image)
        frames.append(frame_entry(name, role, axis, b))
    manifest = {
        "format": FORMAT, "layout": "opencv-graycode",
        "width": width, "height": height, "stripe": step,
        "grid": [gw, gh],
        "axes": {"columns": {"code": f"gray-{bc}", "cells": gw}, "rows": {"code": f"gray-{br}", "cells": gh}},
        "mapping": "projector pixel (x, y) shows Gray-code cell (x // stripe, y // stripe) of a "
                   f"{gw}x{gh} cv::structured_light::GrayCodePattern",
        "bit_order": "bit 0 = most significant bit of gray(cell) = cell ^ (cell >> 1); pattern then inverse",
        "levels": "bit 1 -> 255, bit 0 -> 0; inverse = 255 - pattern",
        "patterns": [f["file"] for f in frames[:-2]], "white": frames[-2]["file"], "black": frames[-1]["file"],
        "frames": frames,
    }
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return manifest


def _write_png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), np.ascontiguousarray(image)):
        raise OSError(f"could not write {path}")
