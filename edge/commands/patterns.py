"""``edge patterns write --code NAME --size WxH DIR``: projector frames as PNG files + manifest.json."""

from __future__ import annotations

import argparse

from ._args import parse_size

from edge.codes import get_code
from edge.patterns import write_patterns



def _write(args: argparse.Namespace) -> int:
    width, height = parse_size(args.size)
    code = get_code(args.code)
    manifest = write_patterns(code, args.directory, width, height, stripe=args.stripe, orientation=args.orientation)
    print(f"wrote {len(manifest['patterns'])} patterns + white/black of {code.name} ({width}x{height}, "
          f"stripe {args.stripe}, {manifest['columns_used']} of {code.size} codewords) to {args.directory}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("patterns", help="render projector patterns")
    sub = parser.add_subparsers(dest="patterns_command", metavar="ACTION", required=True)
    p = sub.add_parser("write", help="write PNG frames, white/black and manifest.json to DIR")
    p.add_argument("--code", default="ecc-22-10", help="code name (default ecc-22-10)")
    p.add_argument("--size", default="1024x768", help="projector WIDTHxHEIGHT (default 1024x768)")
    p.add_argument("--stripe", type=int, default=1, help="projector columns per codeword (default 1)")
    p.add_argument("--orientation", choices=("columns", "rows"), default="columns")
    p.add_argument("directory", help="output directory")
    p.set_defaults(func=_write)
