"""``edge patterns write [--layout edge|opencv-graycode] [--code NAME] --size WxH DIR``: projector
frames as PNG files + manifest.json (`edge.patterns.manifest`), which `edge decode-images` reads back."""

from __future__ import annotations

import argparse

from ._args import parse_size

from edge.codes import get_code
from edge.patterns import write_opencv_graycode, write_patterns

DEFAULT_CODE = "ecc-22-10"


def _write(args: argparse.Namespace) -> int:
    width, height = parse_size(args.size)
    if args.stripe < 1:
        raise ValueError(f"--stripe / --graycode-step: expected a positive integer, got {args.stripe}")
    if args.layout == "opencv-graycode":
        for option, value, default in (("--code", args.code, None), ("--orientation", args.orientation, None)):
            if value is not default:
                raise ValueError(f"{option}: does not apply to --layout opencv-graycode (Gray codes of "
                                 f"ceil(log2) bits, columns then rows), got {value!r}")
        if args.inverse:
            raise ValueError("--inverse: does not apply to --layout opencv-graycode (it always has inverse frames)")
        m = write_opencv_graycode(args.directory, width, height, step=args.stripe, overwrite=args.overwrite)
        cols, rows = m["axes"]["columns"], m["axes"]["rows"]
        print(f"wrote {len(m['frames'])} frames of OpenCV's GrayCodePattern for a {m['grid'][0]}x{m['grid'][1]} grid "
              f"({width}x{height} pixels, step {args.stripe}): {cols['code']} columns and {rows['code']} rows, each "
              f"bit with its inverse, then white and black, plus manifest.json, to {args.directory}")
        return 0
    code = get_code(args.code or DEFAULT_CODE)
    orientation = args.orientation or "columns"
    manifest = write_patterns(code, args.directory, width, height, stripe=args.stripe, orientation=orientation,
                              inverse=args.inverse, overwrite=args.overwrite)
    print(f"wrote {len(manifest['patterns'])} patterns + white/black of {code.name} ({width}x{height}, "
          f"stripe {args.stripe}, {orientation}{', with inverses' if args.inverse else ''}, "
          f"{manifest['columns_used']} of {code.size} codewords) and manifest.json to {args.directory}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("patterns", help="render projector patterns")
    sub = parser.add_subparsers(dest="patterns_command", metavar="ACTION", required=True)
    p = sub.add_parser("write", help="write PNG frames, white/black and manifest.json to DIR",
                       description="Write a pattern set for a real projector: PNG frames in projection order and a "
                                   "manifest.json naming each frame's role, which `edge decode-images` reads back.")
    p.add_argument("--layout", choices=("edge", "opencv-graycode"), default="edge",
                   help="edge: the frames of --code (default); opencv-graycode: exactly OpenCV GrayCodePattern's "
                        "images (column bits, then row bits, each with its inverse, then white, black) as "
                        "procam-calibration's gen_graycode_imgs.py writes them")
    p.add_argument("--code", default=None, help=f"code name for --layout edge (default {DEFAULT_CODE})")
    p.add_argument("--size", default="1024x768", help="projector WIDTHxHEIGHT in pixels (default 1024x768)")
    p.add_argument("--stripe", "--graycode-step", dest="stripe", type=int, default=1,
                   help="projector pixels per code cell (procam-calibration's graycode_step; default 1)")
    p.add_argument("--orientation", choices=("columns", "rows", "both"), default=None,
                   help="--layout edge: code along projector columns (default), rows, or both (columns, then rows)")
    p.add_argument("--inverse", action="store_true",
                   help="--layout edge: follow every pattern frame by its inverse (255 minus it)")
    p.add_argument("directory", help="output directory")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a pattern set already in DIR (its pattern_*.png, white/black and manifest; "
                        "without it such a directory is refused: fewer new frames would leave old ones behind)")
    p.set_defaults(func=_write)
