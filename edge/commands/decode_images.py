"""``edge decode-images DIR --layout opencv-graycode --projector 1024x768 --out col.png``.

Decodes a directory of real captures and writes a colour-mapped column map (invalid pixels
black) and a confidence map (``<out>_confidence.png`` unless --confidence-out is given).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from ..decode import METHODS, decode
from ..decode.layouts import LAYOUTS, load
from ._args import parse_size


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("decode-images", help="decode a directory of structured-light captures to a column map",
                              description=__doc__.splitlines()[0])
    p.add_argument("directory", help="directory holding the capture images")
    p.add_argument("--layout", default="opencv-graycode", choices=LAYOUTS, help="file layout of the capture")
    p.add_argument("--projector", default="1024x768", help="projector size WIDTHxHEIGHT (default 1024x768)")
    p.add_argument("--method", default="soft", choices=METHODS, help="decoder (default soft)")
    p.add_argument("--out", required=True, help="PNG for the colour-mapped column map")
    p.add_argument("--confidence-out", default=None, help="PNG for the confidence map (default <out>_confidence.png)")
    p.set_defaults(func=run)


def column_image(column: np.ndarray, columns: int) -> np.ndarray:
    """(H, W) int32 columns (-1 invalid) -> (H, W, 3) uint8 BGR (turbo colour map, invalid black)."""
    scaled = np.clip(column.astype(np.float64) * (255.0 / max(columns - 1, 1)), 0, 255).astype(np.uint8)
    img = cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO)
    img[column < 0] = 0
    return img


def confidence_image(confidence: np.ndarray) -> np.ndarray:
    """(H, W) float32 in [0, 1] -> (H, W) uint8 0..255."""
    return np.clip(np.rint(confidence * 255.0), 0, 255).astype(np.uint8)


def run(args: argparse.Namespace) -> int:
    projector = parse_size(args.projector, option="--projector", minimum=2)
    cap = load(args.directory, args.layout, projector)
    d = decode(cap.frames, cap.white, cap.black, cap.code, method=args.method, inverse=cap.inverse,
               columns=cap.columns)
    out = Path(args.out)
    conf_out = Path(args.confidence_out) if args.confidence_out else out.with_name(out.stem + "_confidence.png")
    if not cv2.imwrite(str(out), column_image(d.column, cap.columns)):
        raise ValueError(f"--out: expected a writable PNG path, got {out}")
    if not cv2.imwrite(str(conf_out), confidence_image(d.confidence)):
        raise ValueError(f"--confidence-out: expected a writable PNG path, got {conf_out}")
    print(f"decoded {d.valid.mean() * 100:.2f}% of {d.valid.size} pixels ({args.method}); "
          f"wrote {out} and {conf_out}")
    return 0
