"""The pattern-set manifest (``manifest.json``): what every frame of a pattern set is.

`edge patterns write` puts it next to the PNG frames; `edge decode-images DIR` reads it back
(``--layout manifest``, or automatically when DIR holds a ``manifest.json``), so the captured
images can be decoded without any other option.  Save the camera image of each projected frame
under the frame's file name (any image suffix: ``pattern_03.png`` may be captured as
``pattern_03.tif``) in one directory and copy ``manifest.json`` next to them.

Format ``"format": "edge-patterns/1"`` (JSON object):

* ``layout``: ``"edge"`` (an edge code, `edge.patterns.export.write_patterns`) or
  ``"opencv-graycode"`` (OpenCV GrayCodePattern, `edge.patterns.opencv`).
* ``width``, ``height``: projector pixels of every frame.
* ``stripe``: projector pixels per code cell along each coded axis (the ``graycode_step`` of
  procam-calibration): cell ``j`` covers projector pixels ``[j * stripe, (j + 1) * stripe)``.
* ``axes``: ``{"columns": {"code": NAME, "cells": N}, "rows": {...}}`` (one or both): the code
  (an `edge.codes.get_code` name) sent along projector columns (x) / rows (y) and how many of
  its codebook rows (cells) the frames use.
* ``frames``: the frames in projection order, each ``{"file", "role", "axis", "bit"}``:
  role ``pattern`` (symbol ``bit`` of the codeword of each cell, i.e. codebook column ``bit``;
  for Gray codes bit 0 is the most significant bit), ``inverse`` (255 minus the pattern of the same
  axis and bit), ``white`` (all on) or ``black`` (all off; these two have no axis / bit).
* ``levels``: binary symbols are 0 / 255, an N-ary symbol ``s`` is ``round(255 * s / (q - 1))``.

Older edge manifests (no ``format`` key: ``code``, ``orientation``, ``columns_used``,
``patterns``, ``white``, ``black``) are read as the equivalent single-axis layout.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

FORMAT = "edge-patterns/1"
MANIFEST = "manifest.json"
AXES = ("columns", "rows")
ROLES = ("pattern", "inverse", "white", "black")
LAYOUTS = ("edge", "opencv-graycode")


@dataclass(frozen=True)
class AxisSpec:
    """One coded axis: code name, cells used, pattern files by bit, inverse files by bit (or None)."""

    code: str
    cells: int
    patterns: tuple[str, ...]
    inverse: tuple[str, ...] | None


@dataclass(frozen=True)
class LayoutSpec:
    """A parsed manifest: layout name, projector width / height, stripe, axes by name, white / black files."""

    layout: str
    width: int
    height: int
    stripe: int
    axes: dict[str, AxisSpec]
    white: str
    black: str


def frame_entry(file: str, role: str, axis: str | None = None, bit: int | None = None) -> dict:
    """One ``frames`` entry of the manifest."""
    entry: dict = {"file": file, "role": role}
    if axis is not None:
        entry["axis"] = axis
        entry["bit"] = int(bit)  # type: ignore[arg-type]
    return entry


def _need(d: dict, key: str, kind: type, where: str):
    if key not in d:
        raise ValueError(f"{where}: expected key {key!r}, missing")
    value = d[key]
    if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise ValueError(f"{where}: expected {key!r} to be an integer, got {value!r}")
    if kind is not int and not isinstance(value, kind):
        raise ValueError(f"{where}: expected {key!r} to be a {kind.__name__}, got {type(value).__name__}")
    return value


def _legacy(m: dict, where: str) -> dict:
    """An edge manifest written before ``format`` existed -> the equivalent format-1 dict."""
    axis = _need(m, "orientation", str, where)
    if axis not in AXES:
        raise ValueError(f"{where}: expected orientation 'columns' or 'rows', got {axis!r}")
    files = _need(m, "patterns", list, where)
    frames = [frame_entry(f, "pattern", axis, i) for i, f in enumerate(files)]
    frames += [frame_entry(_need(m, "white", str, where), "white"), frame_entry(_need(m, "black", str, where), "black")]
    return {"format": FORMAT, "layout": "edge", "width": _need(m, "width", int, where),
            "height": _need(m, "height", int, where), "stripe": m.get("stripe", 1),
            "axes": {axis: {"code": _need(m, "code", str, where), "cells": _need(m, "columns_used", int, where)}},
            "frames": frames}


def parse_manifest(m: object, where: str = MANIFEST) -> LayoutSpec:
    """Check a manifest dict and return its `LayoutSpec`; ValueError naming the problem."""
    if not isinstance(m, dict):
        raise ValueError(f"{where}: expected a JSON object, got {type(m).__name__}")
    if "format" not in m and "patterns" in m:
        m = _legacy(m, where)
    fmt = m.get("format")
    if fmt != FORMAT:
        raise ValueError(f"{where}: expected format {FORMAT!r}, got {fmt!r}")
    layout = _need(m, "layout", str, where)
    if layout not in LAYOUTS:
        raise ValueError(f"{where}: expected layout one of {LAYOUTS}, got {layout!r}")
    width, height = _need(m, "width", int, where), _need(m, "height", int, where)
    stripe = _need(m, "stripe", int, where)
    if width < 1 or height < 1 or stripe < 1:
        raise ValueError(f"{where}: expected positive width, height and stripe, got {width}, {height}, {stripe}")
    axes_in = _need(m, "axes", dict, where)
    if not axes_in or set(axes_in) - set(AXES):
        raise ValueError(f"{where}: expected axes among {AXES}, got {sorted(axes_in)}")
    frames = _need(m, "frames", list, where)
    by_role: dict[tuple[str, str], dict[int, str]] = {}
    singles: dict[str, list[str]] = {"white": [], "black": []}
    for i, f in enumerate(frames):
        w = f"{where}: frames[{i}]"
        if not isinstance(f, dict):
            raise ValueError(f"{w}: expected an object, got {type(f).__name__}")
        file, role = _need(f, "file", str, w), _need(f, "role", str, w)
        if Path(file).name != file or file in ("", ".", ".."):
            raise ValueError(f"{w}: expected a plain file name, got {file!r}")
        if role not in ROLES:
            raise ValueError(f"{w}: expected role one of {ROLES}, got {role!r}")
        if role in singles:
            singles[role].append(file)
            continue
        axis, bit = _need(f, "axis", str, w), _need(f, "bit", int, w)
        if axis not in axes_in:
            raise ValueError(f"{w}: axis {axis!r} is not among the manifest's axes {sorted(axes_in)}")
        slot = by_role.setdefault((axis, role), {})
        if bit in slot:
            raise ValueError(f"{w}: {role} bit {bit} of axis {axis} appears twice")
        slot[bit] = file
    for role, files in singles.items():
        if len(files) != 1:
            raise ValueError(f"{where}: expected exactly one {role} frame, got {len(files)}")
    axes: dict[str, AxisSpec] = {}
    for axis, spec in axes_in.items():
        w = f"{where}: axes.{axis}"
        if not isinstance(spec, dict):
            raise ValueError(f"{w}: expected an object, got {type(spec).__name__}")
        code, cells = _need(spec, "code", str, w), _need(spec, "cells", int, w)
        pats = by_role.get((axis, "pattern"), {})
        n = len(pats)
        if n == 0 or sorted(pats) != list(range(n)):
            raise ValueError(f"{w}: expected pattern frames for bits 0..n-1, got bits {sorted(pats)}")
        inv = by_role.get((axis, "inverse"))
        if inv is not None and sorted(inv) != list(range(n)):
            raise ValueError(f"{w}: expected an inverse frame for every bit 0..{n - 1} or none, got bits {sorted(inv)}")
        if cells < 1:
            raise ValueError(f"{w}: expected cells >= 1, got {cells}")
        axes[axis] = AxisSpec(code=code, cells=cells, patterns=tuple(pats[b] for b in range(n)),
                              inverse=None if inv is None else tuple(inv[b] for b in range(n)))
    return LayoutSpec(layout=layout, width=width, height=height, stripe=stripe, axes=axes,
                      white=singles["white"][0], black=singles["black"][0])


def read_manifest(path: str | os.PathLike) -> LayoutSpec:
    """Read and check a ``manifest.json`` (FileNotFoundError / ValueError naming the problem)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"manifest not found: {p}")
    try:
        m = json.loads(p.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{p}: expected a JSON manifest, could not parse it ({exc})") from None
    return parse_manifest(m, str(p))
