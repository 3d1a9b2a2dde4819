"""Metric depth from a real procam capture: run `edge decode-images` with the calibration, fit a plane.

Usage: python tools/eval_procam.py [--capture ../shared/data/procam-graycode/capture_0]
       [--calibration .../calibration_result.xml] [--out docs/results/procam] [--inlier-mm 20]

Runs exactly ``edge decode-images CAPTURE --layout opencv-graycode --projector 1024x768
--calibration CAL --depth depth.png --ply cloud.ply`` (default graycode step: estimated from the
calibration), reads the PLY back, fits a plane (RANSAC + least squares, inliers within
--inlier-mm) and writes OUT/cloud.png (depth image, residual to the plane, 3D view of the cloud)
and OUT/README.md with the figures (coverage, inlier share, RMS).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
CAPTURE = "../shared/data/procam-graycode/capture_0"
CALIBRATION = "../shared/data/procam-graycode/calibration_result.xml"


def _path(text: str) -> Path:
    """A path as given, else relative to the repo root (the defaults are relative to it)."""
    p = Path(text)
    return p if p.exists() or p.is_absolute() else REPO / p


def run(capture: str, calibration: str, out: Path, inlier_mm: float) -> dict:
    """Run the command on ``capture`` / ``calibration`` (paths as shown in the README), write
    OUT/cloud.png and OUT/README.md, return the figures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from edge.cli import main
    from edge.decode.plane import fit_plane
    from edge.io.ply import read_ply

    with tempfile.TemporaryDirectory() as tmp:
        depth_png, ply = Path(tmp) / "depth.png", Path(tmp) / "cloud.ply"
        argv = ["decode-images", str(_path(capture).resolve()), "--layout", "opencv-graycode", "--projector",
                "1024x768", "--calibration", str(_path(calibration).resolve()), "--depth", "depth.png", "--ply",
                "cloud.ply"]
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf), contextlib.chdir(tmp):
            rc = main(argv)
        log = buf.getvalue()
        if rc != 0:
            raise SystemExit(f"edge decode-images failed (exit {rc}):\n{log}")
        depth = cv2.imread(str(depth_png), cv2.IMREAD_UNCHANGED)
        xyz, _ = read_ply(ply)
    mm = xyz.astype(np.float64) * 1000.0
    fit = fit_plane(mm, inlier_mm)
    valid = depth > 0
    res_img = np.full(depth.shape, np.nan)
    res_img[valid] = fit.residuals  # PLY vertices are the depth pixels in row-major order
    figures = {
        "pixels": int(depth.size), "with_depth": int(valid.sum()), "coverage": float(valid.mean()),
        "inlier_share": float(fit.inliers.mean()), "inlier_coverage": float(fit.inliers.sum() / depth.size),
        "rms_mm": fit.rms, "median_z_mm": float(np.median(depth[valid])),
        "normal": [float(v) for v in fit.normal], "log": log.strip(),
    }
    out.mkdir(parents=True, exist_ok=True)
    fine = fit_plane(mm, inlier_mm / 2)
    figures["half_inlier_share"], figures["half_rms_mm"] = float(fine.inliers.mean()), fine.rms
    fig = plt.figure(figsize=(13, 10))
    turbo = plt.get_cmap("turbo").with_extremes(bad="black")
    coolwarm = plt.get_cmap("coolwarm").with_extremes(bad="black")
    ax = fig.add_subplot(2, 2, 1)
    shown = np.where(valid, depth.astype(np.float64), np.nan)
    lo, hi = np.percentile(depth[valid], [1, 99])
    im = ax.imshow(shown, cmap=turbo, vmin=lo, vmax=hi)
    ax.set_title("depth.png: Z (mm), black = invalid")
    ax.axis("off")
    fig.colorbar(im, ax=ax, fraction=0.04)
    ax = fig.add_subplot(2, 2, 2)
    im = ax.imshow(res_img, cmap=coolwarm, vmin=-3 * inlier_mm, vmax=3 * inlier_mm)
    ax.set_title(f"signed distance to the fitted plane (mm): RMS {fit.rms:.1f} mm\n"
                 f"over the {fit.inliers.mean() * 100:.1f} % of the cloud within {inlier_mm:g} mm")
    ax.axis("off")
    fig.colorbar(im, ax=ax, fraction=0.04)
    sel = np.arange(0, mm.shape[0], max(1, mm.shape[0] // 25000))
    p = mm[sel] / 1000.0
    colour = np.clip(fit.residuals[sel], -3 * inlier_mm, 3 * inlier_mm)
    ax = fig.add_subplot(2, 2, 3)
    # edge-on view along the fitted plane: height in the plane (the camera's -y projected on it)
    up = np.array([0.0, -1.0, 0.0])
    up = up - (up @ fit.normal) * fit.normal
    up /= np.linalg.norm(up)
    ax.scatter(p @ up, fit.residuals[sel], c=colour, cmap=coolwarm, s=0.3, linewidths=0)
    ax.set_ylim(-4 * inlier_mm, 4 * inlier_mm)
    ax.axhspan(-inlier_mm, inlier_mm, color="0.9", zorder=-1)
    ax.set_xlabel("height in the plane (m)")
    ax.set_ylabel("distance to the plane (mm)")
    ax.set_title("cloud.ply seen edge-on along the fitted plane (every %dth point; grey: inlier band)"
                 % (sel[1] - sel[0] if sel.size > 1 else 1), fontsize=10)
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(2, 2, 4, projection="3d")
    ax.scatter(p[:, 0], p[:, 2], -p[:, 1], c=colour, cmap=coolwarm, s=0.2, linewidths=0)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    ax.set_zlabel("-y (m)")
    ax.view_init(elev=20, azim=-60)
    ax.set_title(f"cloud.ply in 3D ({mm.shape[0]} points)")
    fig.tight_layout()
    buf_png = io.BytesIO()
    fig.savefig(buf_png, format="png", dpi=72)
    plt.close(fig)
    from PIL import Image  # matplotlib's own dependency

    buf_png.seek(0)
    Image.open(buf_png).convert("RGB").quantize(256).save(out / "cloud.png", optimize=True)  # palette PNG: small
    text = f"""# Metric depth from a real procam capture

Command: `python tools/eval_procam.py` (runs `edge decode-images {capture} --layout
opencv-graycode --projector 1024x768 --calibration {calibration} --depth depth.png
--ply cloud.ply`, then fits a plane with `edge.decode.plane.fit_plane`, RANSAC + least squares,
inliers within {inlier_mm:g} mm). Pinned by `tests/test_decode_procam.py`.

Scene: a chessboard taped to a wall, a table edge at the bottom (procam-calibration's sample
data, 1280x1024 camera). Output of the command:

```
{figures['log']}
```

| figure | value |
|---|---|
| pixels with depth (coverage) | {figures['coverage'] * 100:.1f} % of {figures['pixels']} |
| median Z | {figures['median_z_mm']:.0f} mm |
| plane inliers (within {inlier_mm:g} mm) | {figures['inlier_share'] * 100:.1f} % of the cloud ({figures['inlier_coverage'] * 100:.1f} % of all pixels) |
| RMS distance of the inliers to the plane | {figures['rms_mm']:.2f} mm |
| the same with inliers within {inlier_mm / 2:g} mm | {figures['half_inlier_share'] * 100:.1f} % of the cloud, RMS {figures['half_rms_mm']:.2f} mm |

![depth, residual to the plane, cloud](cloud.png)

Reading: the plane found is the chessboard's. The board does not lie flat on the wall: it
leans, its lower edge some 10 cm in front of the wall (blue in the residual, below the band in the
edge-on view), so the wall is a second surface, not an error. On the board the residual shows
diagonal bands: the quantisation of the projector position to 2-pixel
code cells (one cell is about 11 mm of depth at 3.7 m with this rig's 0.64 m baseline, an RMS of
about 3 mm). Holes are the black squares (too little contrast) and the shiny tape.
"""
    (out / "README.md").write_text(text)
    return figures


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--capture", default=CAPTURE, help=f"capture directory (default {CAPTURE})")
    p.add_argument("--calibration", default=CALIBRATION, help=f"calibration file (default {CALIBRATION})")
    p.add_argument("--out", type=Path, default=REPO / "docs" / "results" / "procam", help="output folder (default docs/results/procam)")
    p.add_argument("--inlier-mm", type=float, default=20.0, help="plane inlier distance in mm (default 20)")
    a = p.parse_args(argv)
    figures = run(a.capture, a.calibration, a.out, a.inlier_mm)
    print(f"coverage {figures['coverage'] * 100:.2f} %, plane inliers {figures['inlier_share'] * 100:.2f} % of the "
          f"cloud, RMS {figures['rms_mm']:.2f} mm; wrote {a.out / 'cloud.png'} and {a.out / 'README.md'}")
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
