"""Metric depth from the real procam capture (../shared/data/procam-graycode/capture_0).

One run of the documented command (default graycode step: estimated from the calibration):

    edge decode-images capture_0 --layout opencv-graycode --projector 1024x768 \
        --calibration calibration_result.xml --depth depth.png --ply cloud.ply \
        --column-map col.png --row-map row.png

The scene is a chessboard on a wall: the cloud's largest plane (RANSAC + least squares,
inliers within 20 mm, as tools/eval_procam.py) must hold >= 70 % of the points at an RMS of at
most 8.5 mm (measured: 72.5 %, 7.73 mm), and >= 62 % of the camera pixels must have depth
(measured: 64.4 %).  Figures: docs/results/procam/README.md.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from _tools import load_tool
from edge.decode.plane import fit_plane
from edge.decode.procam import estimate_step, read_calibration, reconstruct
from edge.io.ply import read_ply

REPO = Path(__file__).resolve().parents[1]
REAL_DATA = load_tool("real_data")  # beside the repository, or under $EDGE_SHARED_DIR
DATA, CAPTURE, CALIBRATION = REAL_DATA.PROCAM, REAL_DATA.REAL_CAPTURE, REAL_DATA.CALIBRATION
# the real data sit beside the repository (or at EDGE_SHARED_DIR); a checkout without them skips
pytestmark = pytest.mark.skipif(not (CAPTURE.is_dir() and CALIBRATION.is_file()),
                                reason=f"real capture or calibration not found under {DATA}")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("procam")
    files = {k: out / f"{k}.png" for k in ("depth", "col", "row")}
    files["ply"] = out / "cloud.ply"
    res = subprocess.run(
        [sys.executable, "-m", "edge.cli", "decode-images", str(CAPTURE), "--layout", "opencv-graycode",
         "--projector", "1024x768", "--calibration", str(CALIBRATION), "--depth", str(files["depth"]),
         "--ply", str(files["ply"]), "--column-map", str(files["col"]), "--row-map", str(files["row"])],
        capture_output=True, text=True, cwd=REPO,
    )
    assert res.returncode == 0, res.stderr
    return res, files


def test_step_is_estimated_and_agrees(run):
    res, _ = run
    assert "graycode step 2, the step that fits the calibration best" in res.stdout
    assert "warning" not in res.stderr
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("triangulated"))
    err = float(line.split("median projector reprojection error ")[1].split(" px")[0])
    assert err < 1.5  # field notes: about 1.2 px with step 2


def test_depth_png_is_a_plane(run):
    _, files = run
    depth = cv2.imread(str(files["depth"]), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.shape == (1024, 1280)
    valid = depth > 0
    assert valid.mean() >= 0.62
    assert 3550 <= np.median(depth[valid]) <= 3800  # the wall is about 3.7 m away
    xyz, colors = read_ply(files["ply"])
    assert xyz.shape == (int(valid.sum()), 3) and colors is not None
    # PLY in metres, one vertex per depth pixel in row-major order, z = depth
    assert np.abs(xyz[:, 2] * 1000.0 - depth[valid]).max() <= 0.51
    fit = fit_plane(xyz.astype(np.float64) * 1000.0, 20.0)
    print(f"coverage {valid.mean():.4f}, inliers {fit.inliers.mean():.4f}, rms {fit.rms:.2f} mm")
    assert fit.inliers.mean() >= 0.70
    assert fit.rms <= 8.5
    assert abs(fit.normal[2]) > 0.95  # the wall faces the camera


def test_column_and_row_maps(run):
    _, files = run
    col = cv2.imread(str(files["col"]), cv2.IMREAD_UNCHANGED)
    row = cv2.imread(str(files["row"]), cv2.IMREAD_UNCHANGED)
    assert col.dtype == row.dtype == np.uint16 and col.shape == row.shape == (1024, 1280)
    cv, rv = col != 65535, row != 65535
    assert cv.mean() > 0.7 and rv.mean() > 0.7
    # projector pixels = step 2 * Gray-code cell of a 1024x768 grid
    assert np.all(col[cv] % 2 == 0) and col[cv].max() < 2048 and row[rv].max() < 1536
    # the maps hold what depth was made of: re-triangulating them gives the same depth
    # (every 4th pixel of every 4th row, to keep the test short)
    calib = read_calibration(CALIBRATION)
    grid = np.zeros(col.shape, bool)
    grid[::4, ::4] = True
    cells_c = np.where(cv & grid, col.astype(np.int32) // 2, -1)
    cells_r = np.where(rv & grid, row.astype(np.int32) // 2, -1)
    rec = reconstruct(cells_c, cells_r, calib, 2)
    depth = cv2.imread(str(files["depth"]), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(rec.depth[grid], depth[grid])
    best, errors = estimate_step(cells_c, cells_r, calib)
    assert best == 2 and errors[2] < 1.5 and errors[1] > 100  # field notes: ~1.2 px vs ~260 px


def test_calibration_reader_accepts_rotation_spelling(tmp_path):
    calib = read_calibration(CALIBRATION)
    assert calib.cam_size == (1280, 1024) and calib.t.shape == (3,)
    assert abs(calib.rms - 0.8566) < 1e-3
    np.testing.assert_allclose(calib.R @ calib.R.T, np.eye(3), atol=1e-6)
    fs = cv2.FileStorage(str(tmp_path / "c.yml"), cv2.FILE_STORAGE_WRITE)
    for name, m in (("cam_int", calib.cam_K), ("cam_dist", calib.cam_dist), ("proj_int", calib.proj_K),
                    ("proj_dist", calib.proj_dist), ("rotation", cv2.Rodrigues(calib.R)[0]),
                    ("translation", calib.t)):
        fs.write(name, m)
    fs.release()
    other = read_calibration(tmp_path / "c.yml")
    np.testing.assert_allclose(other.R, calib.R, atol=1e-9)
    assert other.cam_size is None
    (tmp_path / "bad.xml").write_text("<?xml version=\"1.0\"?>\n<opencv_storage>\n<cam_int>1</cam_int>\n</opencv_storage>\n")
    with pytest.raises(ValueError, match="cam_int"):
        read_calibration(tmp_path / "bad.xml")
    (tmp_path / "junk.xml").write_bytes(b"\x00\x01 not a calibration")
    with pytest.raises(ValueError, match="FileStorage"):
        read_calibration(tmp_path / "junk.xml")
    with pytest.raises(FileNotFoundError):
        read_calibration(tmp_path / "missing.xml")
