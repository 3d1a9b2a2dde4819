"""Procam triangulation against ground truth: a synthetic projector-camera rig looking at a plane.

The rig (distortion on both devices, a mostly vertical baseline like the shared capture's) is
rendered by ray casting: every camera pixel's undistorted ray meets the plane, the point is
projected into the projector (with its distortion) and the pixel shows that projector pixel of
OpenCV Gray-code frames with 2-pixel cells.  `edge decode-images` must find step 2, give depth
within the quantisation of a cell, and warn with the figure when told the wrong step.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edge.cli import main
from edge.decode.plane import fit_plane
from edge.decode.procam import ProcamCalibration, estimate_step, triangulate
from edge.io.ply import read_ply
from edge.patterns import opencv_graycode

CAM_W, CAM_H = 160, 120
PROJ_W, PROJ_H, STEP = 256, 192, 2
CAM_K = np.array([[220.0, 0, 80], [0, 220, 60], [0, 0, 1]])
CAM_D = np.array([-0.08, 0.02, 0.0, 0.0, 0.0])
PROJ_K = np.array([[520.0, 0, 128], [0, 520, 150], [0, 0, 1]])
PROJ_D = np.array([0.03, 0.0, 0.0, 0.0, 0.0])
PLANE_N = np.array([0.15, -0.1, -1.0]) / np.linalg.norm([0.15, -0.1, -1.0])
PLANE_P = np.array([0.0, 0.0, 900.0])  # mm


def _rig() -> ProcamCalibration:
    R = cv2.Rodrigues(np.array([0.12, 0.02, 0.0]))[0]
    centre = np.array([20.0, -180.0, 10.0])  # projector above the camera, mm
    return ProcamCalibration(cam_K=CAM_K, cam_dist=CAM_D, proj_K=PROJ_K, proj_dist=PROJ_D, R=R, t=-R @ centre)


def _truth(calib):
    xs, ys = np.meshgrid(np.arange(CAM_W), np.arange(CAM_H))
    px = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    d = cv2.undistortPoints(px.reshape(-1, 1, 2), CAM_K, CAM_D).reshape(-1, 2)
    d = np.c_[d, np.ones(len(d))]
    s = (PLANE_N @ PLANE_P) / (d @ PLANE_N)
    X = s[:, None] * d
    pp = cv2.projectPoints(X.reshape(-1, 1, 3), cv2.Rodrigues(calib.R)[0], calib.t, PROJ_K, PROJ_D)[0].reshape(-1, 2)
    return X.reshape(CAM_H, CAM_W, 3), pp.reshape(CAM_H, CAM_W, 2)


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    calib = _rig()
    X, pp = _truth(calib)
    pix = np.rint(pp).astype(np.int64)
    lit = (pix[..., 0] >= 0) & (pix[..., 0] < PROJ_W) & (pix[..., 1] >= 0) & (pix[..., 1] < PROJ_H)
    frames = opencv_graycode(PROJ_W, PROJ_H, step=STEP)
    rng = np.random.default_rng(0)
    seen = np.zeros((frames.shape[0], CAM_H, CAM_W), np.float64)
    seen[:, lit] = frames[:, pix[..., 1][lit], pix[..., 0][lit]]
    imgs = np.clip(25 + 0.75 * seen + rng.normal(0, 2.0, seen.shape), 0, 255).astype(np.uint8)
    d = tmp_path_factory.mktemp("rig")
    cap = d / "capture"
    cap.mkdir()
    for i, img in enumerate(imgs):
        assert cv2.imwrite(str(cap / f"graycode_{i:02d}.png"), img)
    fs = cv2.FileStorage(str(d / "calibration_result.xml"), cv2.FILE_STORAGE_WRITE)
    fs.write("img_shape", np.array([[CAM_H], [CAM_W]], np.float64))
    for name, m in (("cam_int", CAM_K), ("cam_dist", CAM_D.reshape(1, -1)), ("proj_int", PROJ_K),
                    ("proj_dist", PROJ_D.reshape(1, -1)), ("roration", calib.R), ("translation", calib.t.reshape(3, 1))):
        fs.write(name, m)
    fs.release()
    return dict(calib=calib, X=X, pp=pp, lit=lit, cap=cap, xml=d / "calibration_result.xml", dir=d)


def test_triangulate_exact_correspondences():
    calib = _rig()
    X, pp = _truth(calib)
    xs, ys = np.meshgrid(np.arange(CAM_W), np.arange(CAM_H))
    cam = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    tri = triangulate(cam, pp.reshape(-1, 2), calib)
    np.testing.assert_allclose(tri.points, X.reshape(-1, 3), atol=1e-3)  # mm
    assert tri.gap.max() < 1e-3 and tri.proj_error.max() < 1e-3 and tri.in_front.all()
    # a projector pixel off the epipolar line (the baseline is vertical: off in x) opens the rays;
    # along the line (y) it only moves the point
    off = triangulate(cam[:10], pp.reshape(-1, 2)[:10] + [40.0, 0.0], calib)
    assert off.proj_error.min() > 5 and off.gap.min() > 5
    along = triangulate(cam[:10], pp.reshape(-1, 2)[:10] + [0.0, 40.0], calib)
    assert along.proj_error.max() < off.proj_error.min() / 3


def test_decode_images_depth_matches_the_plane(rig, capsys):
    d = rig["dir"]
    argv = ["decode-images", str(rig["cap"]), "--projector", f"{PROJ_W // STEP}x{PROJ_H // STEP}",
            "--calibration", str(rig["xml"]), "--depth", str(d / "depth.png"), "--ply", str(d / "cloud.ply"),
            "--depth-picture", str(d / "depth_view.png")]
    assert main(argv) == 0
    out = capsys.readouterr()
    assert "graycode step 2, the step that fits" in out.out and "warning" not in out.err
    depth = cv2.imread(str(d / "depth.png"), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.shape == (CAM_H, CAM_W)
    valid = depth > 0
    assert valid.sum() >= 0.85 * rig["lit"].sum() and not (valid & ~rig["lit"]).any()
    z = rig["X"][..., 2]
    err = depth[valid].astype(np.float64) - z[valid]
    # one 2-pixel cell is about Z^2 * 2 / (f_p * baseline) = 900^2 * 2 / (520 * 180) = 17 mm of depth
    assert np.median(np.abs(err)) < 5.0 and np.percentile(np.abs(err), 99) < 15.0
    # the picture for viewing: black exactly where depth is invalid, TURBO's blue end near, red end far
    view = cv2.imread(str(d / "depth_view.png"), cv2.IMREAD_UNCHANGED)
    assert view.dtype == np.uint8 and view.shape == (CAM_H, CAM_W, 3)
    assert not view[~valid].any() and (view[valid].max(axis=1) > 0).all()
    near, far = depth <= np.percentile(depth[valid], 5), depth >= np.percentile(depth[valid], 95)
    b, r = view[..., 0].astype(int), view[..., 2].astype(int)
    assert ((b - r)[near & valid]).mean() > 50 and ((r - b)[far & valid]).mean() > 50
    xyz, _ = read_ply(d / "cloud.ply")
    assert xyz.shape[0] == valid.sum()
    fit = fit_plane(xyz.astype(np.float64) * 1000.0, 15.0)
    assert fit.inliers.mean() > 0.99 and abs(abs(fit.normal @ PLANE_N) - 1) < 1e-3


def test_wrong_step_is_reported(rig, capsys):
    argv = ["decode-images", str(rig["cap"]), "--projector", f"{PROJ_W // STEP}x{PROJ_H // STEP}",
            "--calibration", str(rig["xml"]), "--graycode-step", "1", "--depth", str(rig["dir"] / "d1.png")]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "warning: the calibration and graycode step 1 disagree: median projector reprojection error" in err
    assert "--graycode-step 2 gives" in err
    calib = rig["calib"]
    cells = np.where(rig["lit"][..., None], np.floor((np.rint(rig["pp"]) / STEP)), -1).astype(np.int32)
    best, errors = estimate_step(cells[..., 0], cells[..., 1], calib)
    assert best == 2 and errors[2] < 2.0 and errors[1] > 10 * errors[2]


def test_depth_needs_calibration_and_both_axes(rig, tmp_path, capsys):
    for option in ("--depth", "--depth-picture"):
        assert main(["decode-images", str(rig["cap"]), "--projector", "128x96", option, str(tmp_path / "d.png")]) == 2
        assert "expected --calibration" in capsys.readouterr().err
    pats = tmp_path / "cols"
    assert main(["patterns", "write", "--code", "gray-8", "--size", "256x8", str(pats)]) == 0
    assert main(["decode-images", str(pats), "--calibration", str(rig["xml"]), "--ply", str(tmp_path / "c.ply")]) == 2
    assert "calibrated for 160x120 camera images" in capsys.readouterr().err


def test_bad_output_paths_are_one_line_errors(rig, tmp_path, capsys):
    base = ["decode-images", str(rig["cap"]), "--projector", "128x96", "--calibration", str(rig["xml"])]
    assert main(base + ["--depth", str(tmp_path / "depth.jpg")]) == 2
    assert f"--depth {tmp_path / 'depth.jpg'}: expected a .png (or .tif) path" in capsys.readouterr().err
    for option, name in (("--ply", "cloud.ply"), ("--depth", "d.png"), ("--depth-picture", "v.png")):
        path = tmp_path / "no" / "such" / name  # the wording of every command's outputs
        assert main(base + [option, str(path)]) == 2
        assert f"{option} {path}: folder {path.parent} does not exist" in capsys.readouterr().err
    for bad in ("-1", "0", "nan"):  # refused before decoding, by name
        assert main(base + ["--max-error", bad, "--depth", str(tmp_path / "d.png")]) == 2
        assert f"--max-error: expected a reprojection error > 0 px, got {float(bad)}" in capsys.readouterr().err
    assert not (tmp_path / "d.png").exists()
    # an image written into an OpenCV capture's folder became one of its images: the next decode of
    # the folder failed ("expected 42 images, got 44")
    images = sorted(p.name for p in rig["cap"].iterdir())
    assert main(base + ["--out", str(rig["cap"] / "col.png")]) == 2
    assert "would become one of its images" in capsys.readouterr().err
    assert sorted(p.name for p in rig["cap"].iterdir()) == images
