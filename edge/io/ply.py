"""PLY point-cloud files: one writer and one reader for every place edge saves or checks a cloud.

Format: ``binary_little_endian 1.0`` (default) or ``ascii 1.0``; one ``vertex`` element with
float32 properties ``x y z`` (metres, in the frame the caller states, e.g. the camera optical
frame of REP 103: x right, y down, z forward) and optionally uchar ``red green blue``. Any PLY
reader (Open3D, MeshLab, CloudCompare, plyfile) opens the files.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["write_ply", "read_ply"]


def _check_points(xyz: np.ndarray, colors: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    xyz = np.asarray(xyz)
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {xyz.shape}")
    if not np.issubdtype(xyz.dtype, np.number):
        raise ValueError(f"points must be numeric, got dtype {xyz.dtype}")
    xyz = np.ascontiguousarray(xyz, dtype="<f4")
    if colors is not None:
        colors = np.asarray(colors)
        if colors.ndim == 1:
            colors = np.repeat(colors[:, None], 3, axis=1)
        if colors.shape != (xyz.shape[0], 3):
            raise ValueError(f"colors must have shape (N, 3) or (N,) with N = {xyz.shape[0]}, "
                             f"got {colors.shape}")
        if colors.dtype != np.uint8:
            raise ValueError(f"colors must be uint8, got dtype {colors.dtype}")
    return xyz, colors


def write_ply(path: str | os.PathLike, xyz: np.ndarray, *, colors: np.ndarray | None = None,
              binary: bool = True) -> Path:
    """Write points ``xyz`` (N, 3) (any float dtype, stored as float32, metres) to a PLY file.

    ``colors``: optional (N, 3) or (N,) uint8 (grey replicated to RGB). Returns the path written.
    Raises ValueError on a wrong shape or dtype, OSError if the file cannot be written.
    """
    xyz, colors = _check_points(xyz, colors)
    path = Path(path)
    props = ["property float x", "property float y", "property float z"]
    if colors is not None:
        props += ["property uchar red", "property uchar green", "property uchar blue"]
    header = "\n".join([
        "ply",
        "format binary_little_endian 1.0" if binary else "format ascii 1.0",
        "comment written by edge",
        f"element vertex {xyz.shape[0]}",
        *props,
        "end_header",
    ]) + "\n"
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        if binary:
            if colors is None:
                f.write(xyz.tobytes())
            else:
                rec = np.empty(xyz.shape[0], dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                                                   ("r", "u1"), ("g", "u1"), ("b", "u1")])
                rec["x"], rec["y"], rec["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
                rec["r"], rec["g"], rec["b"] = colors[:, 0], colors[:, 1], colors[:, 2]
                f.write(rec.tobytes())
        else:
            for i in range(xyz.shape[0]):
                line = f"{xyz[i, 0]:.9g} {xyz[i, 1]:.9g} {xyz[i, 2]:.9g}"  # 9 digits: float32 exactly
                if colors is not None:
                    line += f" {colors[i, 0]} {colors[i, 1]} {colors[i, 2]}"
                f.write((line + "\n").encode("ascii"))
    return path


def read_ply(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a PLY file written by `write_ply` (binary LE or ASCII, float x/y/z, optional uchar
    red/green/blue). Returns ``(xyz (N, 3) float32, colors (N, 3) uint8 or None)``.

    Raises ValueError naming what is wrong for a file that is not such a PLY or is truncated.
    """
    data = Path(path).read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise ValueError(f"{path}: not a PLY file (no 'ply' magic or 'end_header')")
    header = data[:end].decode("ascii", errors="replace").splitlines()
    body = data[end + len(b"end_header\n"):]
    fmt = next((ln.split()[1] for ln in header if ln.startswith("format ")), None)
    count = next((int(ln.split()[2]) for ln in header if ln.startswith("element vertex ")), None)
    props = [ln.split()[-1] for ln in header if ln.startswith("property ")]
    if fmt not in ("binary_little_endian", "ascii") or count is None or props[:3] != ["x", "y", "z"]:
        raise ValueError(f"{path}: unsupported PLY layout (format {fmt}, properties {props})")
    has_rgb = props[3:6] == ["red", "green", "blue"]
    if fmt == "ascii":
        rows = body.decode("ascii").split("\n")[:count]
        if len(rows) < count:
            raise ValueError(f"{path}: truncated: {len(rows)} of {count} vertices")
        table = np.array([r.split() for r in rows], dtype=np.float64).reshape(count, len(props))
        xyz = table[:, :3].astype(np.float32)
        colors = table[:, 3:6].astype(np.uint8) if has_rgb else None
        return xyz, colors
    dtype = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if has_rgb:
        dtype += [("r", "u1"), ("g", "u1"), ("b", "u1")]
    rec_dtype = np.dtype(dtype)
    if len(body) < count * rec_dtype.itemsize:
        raise ValueError(f"{path}: truncated: {len(body)} bytes for {count} vertices")
    rec = np.frombuffer(body, dtype=rec_dtype, count=count)
    xyz = np.stack([rec["x"], rec["y"], rec["z"]], axis=1).astype(np.float32)
    colors = np.stack([rec["r"], rec["g"], rec["b"]], axis=1) if has_rgb else None
    return xyz, colors
