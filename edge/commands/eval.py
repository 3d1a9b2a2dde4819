"""``edge eval``: simulator evaluation.

    edge eval sweep [--quick] [--out docs/results/eval] [--experiments a,b] [--levels auto|calibration]

runs the paper's comparisons (see `edge.eval.sweep`) with `edge.decode.decode` and its defaults,
with a progress bar, and writes PNG plots, results.json and README.md (claims, tables, per-albedo-band tables)
into ``--out``; a ``findings.md`` already in ``--out`` is inserted into the README.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("eval", help="evaluate decoders on simulated scenes")
    sub = parser.add_subparsers(dest="eval_command", metavar="EVAL_COMMAND")
    sweep = sub.add_parser("sweep", help="reproduce the paper's error-rate curves (plots + markdown)")
    sweep.add_argument("--quick", action="store_true", help="small images, one seed, 5 ratios (under a minute)")
    sweep.add_argument("--out", type=Path, default=Path("docs/results/eval"),
                       help="output folder, created if missing (default docs/results/eval)")
    sweep.add_argument("--experiments", default=None,
                       help="comma-separated subset of soft_quant,decode_quant,read_noise,arrangement,nary,levels,bits8")
    sweep.add_argument("--levels", choices=("auto", "calibration"), default="auto",
                       help="decoder on/off levels: the library default (auto: self-calibrated from each pixel's "
                            "samples) or the calibration frames")
    sweep.add_argument("--no-progress", action="store_true", help="no progress bar")
    sweep.set_defaults(func=run_sweep_command)
    parser.set_defaults(func=lambda args: (parser.print_help(), 2)[1])


def run_sweep_command(args: argparse.Namespace) -> int:
    from ..eval.sweep import DECODER_NAME, SweepConfig, edge_decoder, read_findings, run_sweep, write_report
    from ._args import output_dir

    cfg = SweepConfig.quick() if args.quick else SweepConfig()
    cfg = replace(cfg, levels=args.levels)
    if args.experiments:
        cfg = replace(cfg, experiments=tuple(e.strip() for e in args.experiments.split(",") if e.strip()))
    output_dir(args.out)  # before the sweep: an --out that cannot be written fails now, not after it
    decoder = edge_decoder()
    t0 = time.perf_counter()
    rows = run_sweep(cfg, decoder, progress=not args.no_progress)
    command = "edge eval sweep" + (" --quick" if args.quick else "") + (
        f" --experiments {args.experiments}" if args.experiments else "") + (
        f" --levels {args.levels}" if args.levels != "auto" else "") + f" --out {args.out}"
    path = write_report(rows, args.out, cfg, command=command, decoder_name=DECODER_NAME,
                        seconds=time.perf_counter() - t0, preamble=read_findings(args.out))
    print(f"wrote {path}", file=sys.stderr)
    return 0
