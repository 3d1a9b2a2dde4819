"""Projector-camera geometry: a real procam calibration, triangulation and the code step.

Conventions (those of procam-calibration's ``calibrate.py`` and OpenCV's ``stereoCalibrate``):

* Camera frame: the camera's optical frame (REP 103 optical: x right, y down, z forward along
  the optical axis), origin at the camera centre; lengths in the calibration's unit, millimetres
  for procam-calibration (its ``chess_block_size``).
* ``R``, ``t``: a point ``X_c`` in the camera frame is ``X_p = R @ X_c + t`` in the projector frame.
* Pixels: OpenCV's (x = column, y = row), pixel centres at integers.
* Code step: a decoded Gray-code cell ``(c, r)`` is projector pixel ``(step * c, step * r)``, the
  rule procam-calibration's generator and calibration use (``gen_graycode_imgs.py
  -graycode_step``; ``calibrate.py`` multiplies the decoded cell by ``graycode_step``), so the
  calibrated projector intrinsics hold for exactly that rule.

Triangulation is the midpoint of the shortest segment between the camera ray and the projector
ray, both undistorted with their own intrinsics and distortion (``cv2.undistortPoints``).  Two
figures tell whether the correspondence and the calibration agree: the ray gap (length of that
segment, calibration units) and the projector reprojection error (pixels between the decoded
projector pixel and the projection of the triangulated point, distortion applied).  With the
shared capture_0 and its calibration the median projector error is about 1.2 px for step 2 and
about 290 px for step 1.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

#: Steps `estimate_step` tries when none is given.
STEP_CANDIDATES = tuple(range(1, 9))
#: Median projector reprojection error (px) above which calibration and correspondences disagree.
DISAGREE_PX = 5.0


@dataclass(frozen=True)
class ProcamCalibration:
    """Intrinsics, distortion and pose of a projector-camera pair.

    cam_K, proj_K: (3, 3) float64 pinhole matrices (pixels); cam_dist, proj_dist: (k,) float64
    OpenCV distortion coefficients (k in 4, 5, 8, 12, 14); R: (3, 3) rotation and t: (3,) translation
    (calibration units, mm for procam-calibration) from the camera frame to the projector frame;
    cam_size: (width, height) of the calibrated camera images or None; rms: the calibration's RMS
    reprojection error (px) or None.
    """

    cam_K: np.ndarray
    cam_dist: np.ndarray
    proj_K: np.ndarray
    proj_dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    cam_size: tuple[int, int] | None = None
    rms: float | None = None

    @property
    def projector_centre(self) -> np.ndarray:
        """(3,) projector centre in the camera frame, ``-R.T @ t``."""
        return -self.R.T @ self.t


@dataclass(frozen=True)
class Triangulated:
    """Output of `triangulate` for N correspondences.

    points: (N, 3) float64 in the camera frame (calibration units; NaN where the rays are
    parallel); gap: (N,) float64 ray gap (calibration units); proj_error: (N,) float64 projector
    reprojection error (px); in_front: (N,) bool, the point lies in front of both devices.
    """

    points: np.ndarray
    gap: np.ndarray
    proj_error: np.ndarray
    in_front: np.ndarray


def _matrix(fs: cv2.FileStorage, path: str, names: tuple[str, ...]) -> np.ndarray:
    for name in names:
        node = fs.getNode(name)
        if not node.empty():
            try:
                m = node.mat() if node.isMap() else None
            except cv2.error:
                m = None
            if m is None:
                raise ValueError(f"{path}: expected {name} to be an OpenCV matrix, got another node type")
            return np.asarray(m, dtype=np.float64)
    raise ValueError(f"{path}: expected a matrix named {' or '.join(names)}, found none")


def read_calibration(path: str | os.PathLike) -> ProcamCalibration:
    """Read an OpenCV FileStorage file (XML / YAML / JSON) as procam-calibration writes it.

    Keys: ``cam_int``, ``cam_dist``, ``proj_int``, ``proj_dist``, ``roration`` (procam-calibration's
    spelling) or ``rotation`` (a 3x3 matrix or a 3-vector Rodrigues rotation), ``translation``
    (3 values); optional ``img_shape`` (camera height, width) and ``rms``.  Raises
    FileNotFoundError for a missing file, ValueError naming the key for anything malformed.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"calibration file not found: {p}")
    try:
        fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError):  # the bindings raise SystemError for some unparsable files
        fs = None
    if fs is None or not fs.isOpened():
        raise ValueError(f"{p}: expected an OpenCV FileStorage file (XML/YAML/JSON), could not parse it")
    try:
        cam_K = _matrix(fs, str(p), ("cam_int",))
        proj_K = _matrix(fs, str(p), ("proj_int",))
        cam_dist = _matrix(fs, str(p), ("cam_dist",)).ravel()
        proj_dist = _matrix(fs, str(p), ("proj_dist",)).ravel()
        rot = _matrix(fs, str(p), ("roration", "rotation"))
        t = _matrix(fs, str(p), ("translation",)).ravel()
        cam_size = None
        if not fs.getNode("img_shape").empty():
            hw = _matrix(fs, str(p), ("img_shape",)).ravel()
            if hw.size != 2:
                raise ValueError(f"{p}: expected img_shape to hold (height, width), got {hw.size} values")
            cam_size = (int(hw[1]), int(hw[0]))
        rms_node = fs.getNode("rms")
        rms = float(rms_node.real()) if not rms_node.empty() and rms_node.isReal() else None
    finally:
        fs.release()
    for name, k in (("cam_int", cam_K), ("proj_int", proj_K)):
        if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0:
            raise ValueError(f"{p}: expected {name} to be a 3x3 camera matrix with positive focal lengths, "
                             f"got shape {k.shape}")
    for name, d in (("cam_dist", cam_dist), ("proj_dist", proj_dist)):
        if d.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
            raise ValueError(f"{p}: expected {name} to hold 4, 5, 8, 12 or 14 finite coefficients, got {d.size}")
    if rot.size == 3:
        rot = cv2.Rodrigues(rot.reshape(3, 1))[0]
    if rot.shape != (3, 3) or not np.allclose(rot @ rot.T, np.eye(3), atol=1e-4):
        raise ValueError(f"{p}: expected the rotation (roration / rotation) to be a 3x3 rotation matrix "
                         f"or a Rodrigues 3-vector, got shape {rot.shape}")
    if t.size != 3 or not np.all(np.isfinite(t)):
        raise ValueError(f"{p}: expected translation to hold 3 finite values, got {t.size}")
    return ProcamCalibration(cam_K=cam_K, cam_dist=cam_dist, proj_K=proj_K, proj_dist=proj_dist, R=rot,
                             t=t, cam_size=cam_size, rms=rms)


def _normalised(px: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """(N, 2) pixels -> (N, 3) undistorted ray directions (x, y, 1)."""
    if px.shape[0] == 0:
        return np.zeros((0, 3))
    xy = cv2.undistortPoints(np.ascontiguousarray(px, np.float64).reshape(-1, 1, 2), K, dist).reshape(-1, 2)
    return np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1)


def triangulate(cam_px: np.ndarray, proj_px: np.ndarray, calib: ProcamCalibration) -> Triangulated:
    """Triangulate N camera pixels with their projector pixels.

    cam_px, proj_px: (N, 2) float pixel coordinates (x, y) in the camera and the projector.
    Returns `Triangulated` (points in the camera frame, calibration units).
    """
    cam_px = np.asarray(cam_px, np.float64)
    proj_px = np.asarray(proj_px, np.float64)
    if cam_px.ndim != 2 or cam_px.shape[1] != 2 or proj_px.shape != cam_px.shape:
        raise ValueError(f"triangulate: expected two (N, 2) pixel arrays, got {cam_px.shape} and {proj_px.shape}")
    dc = _normalised(cam_px, calib.cam_K, calib.cam_dist)
    dp = _normalised(proj_px, calib.proj_K, calib.proj_dist) @ calib.R  # rows: R.T @ d, camera frame
    o = calib.projector_centre
    # closest points of s * dc (camera ray) and o + u * dp (projector ray)
    a = np.einsum("ij,ij->i", dc, dc)
    b = np.einsum("ij,ij->i", dc, dp)
    c = np.einsum("ij,ij->i", dp, dp)
    d = dc @ o
    e = dp @ o
    den = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (c * d - b * e) / den
        u = (b * d - a * e) / den
    p1 = s[:, None] * dc
    p2 = o + u[:, None] * dp
    points = 0.5 * (p1 + p2)
    gap = np.linalg.norm(p1 - p2, axis=1)
    parallel = ~np.isfinite(s) | ~np.isfinite(u) | (np.abs(den) < 1e-15)
    points[parallel] = np.nan
    gap[parallel] = np.nan
    in_front = (s > 0) & (u > 0) & ~parallel
    proj_error = np.full(cam_px.shape[0], np.nan)
    ok = np.isfinite(points).all(axis=1)
    if ok.any():
        rvec = cv2.Rodrigues(calib.R)[0]
        pp = cv2.projectPoints(points[ok].reshape(-1, 1, 3), rvec, calib.t.reshape(3, 1), calib.proj_K,
                               calib.proj_dist)[0].reshape(-1, 2)
        proj_error[ok] = np.linalg.norm(pp - proj_px[ok], axis=1)
    return Triangulated(points=points, gap=gap, proj_error=proj_error, in_front=in_front)


def correspondences(column: np.ndarray, row: np.ndarray, step: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera / projector pixel pairs from decoded cell maps.

    column, row: (H, W) int decoded Gray-code cells (-1 = invalid).  Returns (mask (H, W) bool of
    pixels with both valid, cam_px (N, 2) float64 (x, y), proj_px (N, 2) float64
    ``step * (column, row)``), N = mask.sum(), in row-major pixel order.
    """
    column = np.asarray(column)
    row = np.asarray(row)
    if column.shape != row.shape or column.ndim != 2:
        raise ValueError(f"correspondences: expected two (H, W) maps of one shape, got {column.shape} and {row.shape}")
    if int(step) != step or step < 1:
        raise ValueError(f"graycode step: expected a positive integer, got {step!r}")
    mask = (column >= 0) & (row >= 0)
    ys, xs = np.nonzero(mask)
    cam_px = np.stack([xs, ys], axis=1).astype(np.float64)
    proj_px = np.stack([column[mask], row[mask]], axis=1).astype(np.float64) * float(step)
    return mask, cam_px, proj_px


def estimate_step(column: np.ndarray, row: np.ndarray, calib: ProcamCalibration,
                  candidates: tuple[int, ...] = STEP_CANDIDATES, sample: int = 20000,
                  seed: int = 0) -> tuple[int, dict[int, float]]:
    """The code step that makes the capture agree with the calibration.

    Triangulates a random sample of at most ``sample`` valid pixels for each candidate step and
    returns (step with the smallest median projector reprojection error, {step: median error px}).
    """
    mask, cam_px, cells = correspondences(column, row, 1)
    if cam_px.shape[0] == 0:
        raise ValueError("graycode step: no pixel has both a valid column and a valid row to estimate it from")
    rng = np.random.default_rng(seed)
    idx = rng.choice(cam_px.shape[0], min(sample, cam_px.shape[0]), replace=False)
    errors: dict[int, float] = {}
    for s in candidates:
        tri = triangulate(cam_px[idx], cells[idx] * float(s), calib)
        err = np.where(tri.in_front, tri.proj_error, np.inf)
        errors[int(s)] = float(np.median(err))
    best = min(errors, key=lambda s: errors[s])
    return best, errors


def depth_image(points: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W) uint16 depth in millimetres (Z along the camera optical axis, rounded; 0 = invalid).

    points: (N, 3) camera-frame points in millimetres for the N True pixels of ``mask`` (row-major
    order, NaN = invalid); Z <= 0 or >= 65535.5 mm is invalid.
    """
    z = np.asarray(points, np.float64)[:, 2]
    depth = np.zeros(mask.shape, np.uint16)
    ok = np.isfinite(z) & (z > 0.5) & (z < 65535.5)
    vals = np.zeros(z.shape, np.uint16)
    vals[ok] = np.rint(z[ok]).astype(np.uint16)
    depth[mask] = vals
    return depth


#: Default largest projector reprojection error (px) of a pixel with depth, per unit of step.
MAX_ERROR_PER_STEP = 2.0
#: ... and never below this many pixels.
MAX_ERROR_MIN_PX = 3.0


def default_max_error(step: int) -> float:
    """Default `reconstruct` max_error: ``max(3, 2 * step)`` projector pixels (a cell spans ``step``
    pixels, so a correct correspondence is off by up to about ``step / sqrt(2)`` from the ray)."""
    return max(MAX_ERROR_MIN_PX, MAX_ERROR_PER_STEP * float(step))


@dataclass(frozen=True)
class Reconstruction:
    """Metric depth of a decoded procam capture.

    mask: (H, W) bool, pixels with depth; points: (N, 3) float64 camera-frame points (calibration
    units, mm) of the N mask pixels in row-major order; depth: (H, W) uint16 Z in mm (0 = invalid);
    decoded: pixels with a valid column and row; median_error: median projector reprojection
    error (px) and median_gap: median ray gap (units) over the decoded pixels in front of both
    devices; rejected: decoded pixels dropped for an error above max_error (or behind a device).
    """

    mask: np.ndarray
    points: np.ndarray
    depth: np.ndarray
    decoded: int
    median_error: float
    median_gap: float
    rejected: int
    max_error: float


def reconstruct(column: np.ndarray, row: np.ndarray, calib: ProcamCalibration, step: int = 1,
                max_error: float | None = None) -> Reconstruction:
    """Triangulate every pixel with a decoded column and row (cells; -1 invalid) with code step
    ``step``; keep those in front of both devices whose projector reprojection error is at most
    ``max_error`` px (default `default_max_error`) and whose Z fits a uint16 in mm."""
    if max_error is None:
        max_error = default_max_error(step)
    if not max_error > 0:
        raise ValueError(f"max reprojection error: expected > 0 px, got {max_error}")
    dmask, cam_px, proj_px = correspondences(column, row, step)
    tri = triangulate(cam_px, proj_px, calib)
    front = tri.in_front
    med_err = float(np.median(tri.proj_error[front])) if front.any() else float("nan")
    med_gap = float(np.median(tri.gap[front])) if front.any() else float("nan")
    z = tri.points[:, 2]
    keep = front & (tri.proj_error <= max_error) & (z > 0.5) & (z < 65535.5)
    mask = np.zeros(dmask.shape, bool)
    mask[dmask] = keep
    points = tri.points[keep]
    return Reconstruction(mask=mask, points=points, depth=depth_image(points, mask), decoded=int(dmask.sum()),
                          median_error=med_err, median_gap=med_gap, rejected=int((~keep).sum()),
                          max_error=float(max_error))
