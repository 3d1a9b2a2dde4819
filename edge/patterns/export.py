"""Write projector frames as PNG files plus a JSON manifest (for a real projector)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from ..codes.code import Code
from .render import calibration, render

MANIFEST = "manifest.json"


def write_patterns(code: Code, directory: str | Path, width: int, height: int, *, stripe: int = 1,
                   orientation: str = "columns") -> dict:
    """Write ``pattern_00.png`` .. (frame order), ``white.png``, ``black.png`` and ``manifest.json``.

    Returns the manifest (code name, n, k, q, d_min, size, stripe, orientation, files in projection
    order, and the column mapping rule).
    """
    frames = render(code, width, height, stripe=stripe, orientation=orientation)
    white, black = calibration(width, height)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    digits = max(2, len(str(code.n - 1)))
    files = []
    for i, frame in enumerate(frames):
        name = f"pattern_{i:0{digits}d}.png"
        _write_png(out / name, frame)
        files.append(name)
    _write_png(out / "white.png", white)
    _write_png(out / "black.png", black)
    manifest = {
        "code": code.name, "family": code.family, "construction": code.construction,
        "n": code.n, "k": code.k, "q": code.q, "d_min": code.d_min,
        "width": width, "height": height, "stripe": stripe, "orientation": orientation,
        "columns_used": -(-(width if orientation == "columns" else height) // stripe),
        "mapping": "projector column x sends codebook row x // stripe (rows: y // stripe)",
        "levels": "symbol s -> round(255 * s / (q - 1))",
        "patterns": files, "white": "white.png", "black": "black.png",
    }
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return manifest


def _write_png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), np.ascontiguousarray(image)):
        raise OSError(f"could not write {path}")
