"""``edge decode-images DIR [--calibration FILE --depth depth.png --ply cloud.ply] [--out col.png]``.

Decodes a directory of real captures: projector columns and rows per camera pixel, and with a
procam calibration (procam-calibration's ``calibration_result.xml``) metric depth and a point
cloud.  Outputs (each optional):

* ``--out``: colour-mapped column picture (invalid black) and a confidence picture
  (``<out>_confidence.png`` unless --confidence-out is given).
* ``--column-map`` / ``--row-map``: uint16 PNG, the projector pixel column / row of each camera
  pixel (``graycode step * decoded cell``), 65535 = invalid.
* ``--depth``: uint16 PNG in camera pixels, Z along the camera optical axis in millimetres,
  0 = invalid (ROS REP 118 16UC1).  Needs --calibration and a layout with columns and rows.
* ``--depth-picture``: the same depth colour-mapped for viewing (TURBO over the 1st..99th
  percentile of the valid depths, invalid black).  Needs what --depth needs.
* ``--ply``: one vertex per pixel with depth, x y z in metres in the camera optical frame
  (x right, y down, z forward), coloured with the white frame.  Needs what --depth needs.

Every output path is checked before the decode; one that names an input (a file of DIR,
--manifest or --calibration) is refused, so the command never writes over its capture.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import cv2
import numpy as np

from ..decode import METHODS
from ..decode.layouts import LAYOUTS, decode_axes, is_capture_image, load, resolve_layout
from ..decode.procam import DISAGREE_PX, estimate_step, read_calibration, reconstruct
from ..io.ply import write_ply
from ._args import check_output_file, parse_size
from ._pictures import colorize_depth, column_image, confidence_image

#: Value of an invalid pixel in the uint16 column / row maps.
MAP_INVALID = 65535


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("decode-images", help="decode structured-light captures to column/row maps, depth and PLY",
                              description="\n\n".join(__doc__.split("\n\n")[1:]).strip(),
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("directory", help="directory holding the capture images")
    p.add_argument("--layout", default="auto", choices=LAYOUTS,
                   help="file layout: opencv-graycode (42 images for a 1024x768 grid, file-name order), manifest "
                        "(DIR/manifest.json from `edge patterns write`), auto (default: manifest if DIR has one)")
    p.add_argument("--manifest", default=None, help="manifest.json to use instead of DIR/manifest.json (implies --layout manifest)")
    p.add_argument("--projector", default="1024x768",
                   help="opencv-graycode: the Gray-code grid WIDTHxHEIGHT in code cells, i.e. projector pixels / "
                        "--graycode-step (default 1024x768)")
    p.add_argument("--method", default="soft", choices=METHODS, help="decoder (default soft)")
    p.add_argument("--out", default=None, help="PNG for the colour-mapped column picture")
    p.add_argument("--confidence-out", default=None, help="PNG for the confidence picture (default <out>_confidence.png with --out)")
    p.add_argument("--column-map", default=None, help="uint16 PNG of the projector column per pixel (65535 = invalid)")
    p.add_argument("--row-map", default=None, help="uint16 PNG of the projector row per pixel (65535 = invalid)")
    p.add_argument("--calibration", default=None,
                   help="OpenCV FileStorage procam calibration (cam_int, cam_dist, proj_int, proj_dist, roration or "
                        "rotation, translation in mm), as procam-calibration's calibrate.py writes it")
    p.add_argument("--graycode-step", type=int, default=None,
                   help="projector pixels per code cell (procam-calibration's graycode_step). Default: the manifest's "
                        "stripe; else, with --calibration, the step 1..8 that best fits the calibration (printed); else 1")
    p.add_argument("--max-error", type=float, default=None,
                   help="drop depth where the projector reprojection error exceeds this many pixels (default max(3, 2*step))")
    p.add_argument("--depth", default=None, help="uint16 PNG depth in mm along the camera axis, 0 = invalid (needs --calibration)")
    p.add_argument("--depth-picture", default=None,
                   help="PNG of the depth colour-mapped for viewing (TURBO, near blue, invalid black; needs --calibration)")
    p.add_argument("--ply", default=None, help="PLY point cloud in metres, camera optical frame (needs --calibration)")
    p.set_defaults(func=run)


def pixel_map(cells: np.ndarray, step: int) -> np.ndarray:
    """(H, W) int cells (-1 invalid) -> (H, W) uint16 projector pixels ``step * cell``, `MAP_INVALID` invalid."""
    px = cells.astype(np.int64) * int(step)
    if px.size and px.max() >= MAP_INVALID:
        raise ValueError(f"--graycode-step {step}: projector pixels up to {int(px.max())} do not fit a uint16 map")
    return np.where(cells >= 0, px, MAP_INVALID).astype(np.uint16)


_SIXTEEN_BIT = (".png", ".tif", ".tiff")


def _imwrite(path: str, image: np.ndarray, option: str) -> None:
    if image.dtype == np.uint16 and Path(path).suffix.lower() not in _SIXTEEN_BIT:
        raise ValueError(f"{option} {path}: expected a .png (or .tif) path for a 16-bit image")
    ok = False
    try:
        ok = cv2.imwrite(path, image)
    except cv2.error:
        ok = False
    if not ok:
        raise ValueError(f"{option} {path}: OpenCV could not write the image (expected a writable .png path)")


def _warn(text: str) -> None:
    print(f"edge decode-images: warning: {text}", file=sys.stderr)


def _check_outputs(args: argparse.Namespace) -> None:
    """Before decoding: every output path can be written and none is an input (a file of the capture
    directory, --manifest, --calibration), which it would replace."""
    outputs = [(option, getattr(args, option[2:].replace("-", "_")))
               for option in ("--out", "--confidence-out", "--column-map", "--row-map", "--depth", "--depth-picture",
                             "--ply")]
    if args.out is not None and args.confidence_out is None:
        out = Path(args.out)
        outputs.append(("--out", str(out.with_name(out.stem + "_confidence.png"))))
    folder = Path(args.directory)
    inputs = [p for p in folder.iterdir() if p.is_file()] if folder.is_dir() else []
    inputs += [Path(p) for p in (args.manifest, args.calibration) if p is not None and os.path.isfile(p)]
    every_image = folder.is_dir() and resolve_layout(folder, args.layout, args.manifest) == "opencv-graycode"
    for option, path in outputs:
        if path is None:
            continue
        check_output_file(path, option=option)
        if os.path.exists(path) and any(os.path.samefile(path, p) for p in inputs):
            raise ValueError(f"{option} {path} is an input of this command (the capture in {args.directory}, "
                             f"--manifest or --calibration); write to another file")
        parent = os.path.dirname(os.path.abspath(path))  # exists: check_output_file above
        if every_image and is_capture_image(path) and os.path.samefile(parent, folder):
            raise ValueError(f"{option} {path}: an image in the capture folder {args.directory} would become one "
                             f"of its images (the opencv-graycode layout reads every image there); write it elsewhere")


def run(args: argparse.Namespace) -> int:
    projector = parse_size(args.projector, option="--projector", minimum=2)
    _check_outputs(args)
    if args.max_error is not None and not args.max_error > 0:
        raise ValueError(f"--max-error: expected a reprojection error > 0 px, got {args.max_error}")
    if args.graycode_step is not None and args.graycode_step < 1:
        raise ValueError(f"--graycode-step: expected a positive integer, got {args.graycode_step}")
    for option in ("--depth", "--column-map", "--row-map"):
        path = getattr(args, option[2:].replace("-", "_"))
        if path is not None and Path(path).suffix.lower() not in _SIXTEEN_BIT:
            raise ValueError(f"{option} {path}: expected a .png (or .tif) path for a 16-bit image")
    geometric = args.depth is not None or args.depth_picture is not None or args.ply is not None
    if geometric and args.calibration is None:
        raise ValueError("--depth / --depth-picture / --ply: expected --calibration FILE (a procam calibration_result.xml)")
    calib = read_calibration(args.calibration) if args.calibration else None
    cap = load(args.directory, args.layout, projector, manifest=args.manifest)  # resolve_layout: "auto"
    if calib is not None and calib.cam_size is not None and calib.cam_size != (cap.white.shape[1], cap.white.shape[0]):
        raise ValueError(f"--calibration: calibrated for {calib.cam_size[0]}x{calib.cam_size[1]} camera images, "
                         f"the capture is {cap.white.shape[1]}x{cap.white.shape[0]}")
    need_rows = geometric or args.row_map is not None or calib is not None
    axes = ("columns", "rows") if need_rows else ("columns",)
    dec = decode_axes(cap, axes, method=args.method)
    if geometric and not {"columns", "rows"} <= set(dec):
        raise ValueError(f"--depth / --depth-picture / --ply: expected a capture that codes both projector columns and rows, "
                         f"{args.directory} codes only {', '.join(dec) or 'nothing'} "
                         f"(write patterns with --orientation both)")
    for option, axis in (("--out", "columns"), ("--column-map", "columns"), ("--row-map", "rows")):
        if getattr(args, option[2:].replace("-", "_")) is not None and axis not in dec:
            raise ValueError(f"{option}: the capture codes no projector {axis}")
    col, row = dec.get("columns"), dec.get("rows")
    parts = [f"columns {col.valid.mean() * 100:.2f}%" if col is not None else None,
             f"rows {row.valid.mean() * 100:.2f}%" if row is not None else None]
    print(f"decoded {', '.join(p for p in parts if p)} of {cap.white.size} pixels ({args.method}, layout {cap.layout})")

    step = args.graycode_step or cap.stripe
    if calib is not None and col is not None and row is not None:
        best, errors = estimate_step(col.column, row.column, calib)
        tried = ", ".join(f"{s}: {e:.1f} px" for s, e in errors.items() if np.isfinite(e))
        behind = [str(s) for s, e in errors.items() if not np.isfinite(e)]
        if behind:
            tried += f"; step {', '.join(behind)}: most points behind a device"
        if step is None:
            step = best
            print(f"graycode step {step}, the step that fits the calibration best (median projector "
                  f"reprojection error per step {tried})")
        if errors.get(step, np.inf) > DISAGREE_PX:
            hint = (f"; --graycode-step {best} gives {errors[best]:.1f} px" if best != step and errors[best] <= DISAGREE_PX
                    else "; no step 1..8 fits: is this the calibration of this projector-camera pair?")
            _warn(f"the calibration and graycode step {step} disagree: median projector reprojection error "
                  f"{errors.get(step, float('nan')):.1f} px (more than {DISAGREE_PX:g} px){hint}")
    step = step or 1

    written: list[str] = []
    if args.out is not None:
        _imwrite(args.out, column_image(col.column, cap.columns), "--out")
        out = Path(args.out)
        conf_out = args.confidence_out or str(out.with_name(out.stem + "_confidence.png"))
        _imwrite(conf_out, confidence_image(col.confidence), "--confidence-out")
        written += [args.out, conf_out]
    elif args.confidence_out is not None and col is not None:
        _imwrite(args.confidence_out, confidence_image(col.confidence), "--confidence-out")
        written.append(args.confidence_out)
    if args.column_map is not None:
        _imwrite(args.column_map, pixel_map(col.column, step), "--column-map")
        written.append(args.column_map)
    if args.row_map is not None:
        _imwrite(args.row_map, pixel_map(row.column, step), "--row-map")
        written.append(args.row_map)
    if calib is not None and col is not None and row is not None:
        rec = reconstruct(col.column, row.column, calib, step, args.max_error)
        z = rec.depth[rec.mask]
        zr = f", Z {z.min()}..{z.max()} mm (median {int(np.median(z))})" if z.size else ""
        print(f"triangulated {rec.mask.sum()} pixels ({rec.mask.mean() * 100:.2f}%) with graycode step {step}: "
              f"median projector reprojection error {rec.median_error:.2f} px, median ray gap {rec.median_gap:.2f} mm, "
              f"{rec.rejected} of {rec.decoded} decoded pixels dropped (error > {rec.max_error:g} px){zr}")
        if args.depth is not None:
            _imwrite(args.depth, rec.depth, "--depth")
            written.append(args.depth)
        if args.depth_picture is not None:
            _imwrite(args.depth_picture, colorize_depth(rec.depth), "--depth-picture")
            written.append(args.depth_picture)
        if args.ply is not None:
            grey = cap.white[rec.mask]
            if grey.dtype != np.uint8:
                grey = (grey.astype(np.float64) * (255.0 / max(int(cap.white.max()), 1))).astype(np.uint8)
            try:
                write_ply(args.ply, rec.points / 1000.0, colors=grey)
            except OSError as exc:
                raise ValueError(f"--ply {args.ply}: {exc.strerror}") from None
            written.append(args.ply)
    print(f"wrote {', '.join(written)}" if written else
          "wrote nothing (give --out, --column-map, --row-map, --depth, --depth-picture or --ply)")
    return 0
