#!/usr/bin/env python
"""Run the evaluation sweep (paper section 3.2.5, appendices B-D) and write plots + tables.

    python tools/eval_sweep.py [--quick] [--out docs/results/eval] [--decoder edge|reference]

Same as ``edge eval sweep``.  ``--decoder reference`` uses the small brute-force soft/hard
decoder below (numpy, slow, soft and hard only) instead of ``edge.decode``; it exists to check the
sweep's plumbing independently of the production decoders.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from edge.codes import Code
from edge.commands._args import output_dir
from edge.decode.settings import DecodeSettings
from edge.eval.sweep import DECODER_NAME, SweepConfig, edge_decoder, load_rows, read_findings, run_sweep, write_report
from edge.capture import CodedCapture


def reference_decoder(cap: CodedCapture, code: Code, settings: DecodeSettings,
                      band: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Brute-force decoder over the disparity band: squared distance of normalised intensities
    ("soft") or Hamming distance of thresholded symbols ("hard") to every candidate codeword, for
    every pixel (no validity rule).  levels="auto": each pixel's on / off levels split from its
    own n + 2 samples (`edge.decode.posterior.split_levels`, the library's self-calibration);
    "calibration": the white / black frames.  Reads only ``settings.method`` and ``settings.levels``."""
    method, levels = settings.method, settings.levels
    f = cap.frames.astype(np.float32)
    white = cap.white.astype(np.float32)
    black = cap.black.astype(np.float32)
    if levels == "auto":
        from edge.decode.posterior import split_levels

        scale = np.float32(1.0 / ((1 << cap.bits) - 1))
        on, off, _ = split_levels(f, white, black, float(scale))
        return _brute(f * scale, on, off, code, method, band, cap.stripe, 1e-6)
    return _brute(f, white, black, code, method, band, cap.stripe, 1.0)


def _brute(f: np.ndarray, white: np.ndarray, black: np.ndarray, code: Code, method: str, band: tuple[int, int],
           stripe: int, min_span: float) -> tuple[np.ndarray, np.ndarray]:
    span = np.maximum(white - black, min_span)
    r = (f - black[None]) / span[None]
    q = code.q
    if method == "hard":
        r = np.clip(np.floor(r * (q - 1) + 0.5), 0, q - 1)
    templates = code.codebook.T.astype(np.float32) / (1.0 if method == "hard" else q - 1)  # (n, size)
    n, h, w = f.shape
    x = np.arange(w)
    best = np.full((h, w), np.inf, np.float32)
    col = np.full((h, w), -1, np.int32)
    for d in range(band[0], band[1] + 1):
        cand = (x - d) // stripe
        ok = (cand >= 0) & (cand < code.size) & (x - d >= 0)
        c = np.where(ok, cand, 0)
        t = templates[:, c]                                      # (n, W)
        if method == "hard":
            cost = (r != t[:, None, :]).sum(axis=0).astype(np.float32)
        else:
            cost = ((r - t[:, None, :]) ** 2).sum(axis=0)
        cost[:, ~ok] = np.inf
        better = cost < best
        best = np.where(better, cost, best)
        col = np.where(better, c[None, :].astype(np.int32), col)
    return col, col >= 0


reference_decoder.methods = ("soft", "hard")  # type: ignore[attr-defined]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small images, one seed, 5 ratios")
    ap.add_argument("--out", type=Path, default=Path("docs/results/eval"),
                    help="output folder (default docs/results/eval)")
    ap.add_argument("--decoder", choices=("edge", "reference"), default="edge",
                    help="edge: the library's decode(); reference: the small brute-force decoder (default edge)")
    ap.add_argument("--experiments", default=None, help="comma-separated subset of experiments")
    ap.add_argument("--report-only", action="store_true",
                    help="rewrite README.md and plots from --out/results.json (e.g. after editing findings.md)")
    ap.add_argument("--levels", choices=("auto", "calibration"), default="auto",
                    help="decoder on/off levels: the library default (auto: self-calibrated) or the calibration frames")
    args = ap.parse_args(argv)
    if args.report_only:
        import json

        cfg, rows = load_rows(args.out / "results.json")
        head = (args.out / "README.md").read_text().splitlines()[2] if (args.out / "README.md").exists() else ""
        command = head.split("`")[1] if head.count("`") >= 2 else "python tools/eval_sweep.py"
        seconds = float(json.loads((args.out / "results.json").read_text()).get("seconds", 0.0))
        path = write_report(rows, args.out, cfg, command=command, decoder_name=DECODER_NAME, seconds=seconds,
                            preamble=read_findings(args.out))
        print(path)
        return 0
    cfg = SweepConfig.quick() if args.quick else SweepConfig()
    if args.levels != cfg.levels:
        from dataclasses import replace

        cfg = replace(cfg, levels=args.levels)
    if args.experiments:
        from dataclasses import replace

        cfg = replace(cfg, experiments=tuple(e.strip() for e in args.experiments.split(",")))
    output_dir(args.out)  # before the sweep: an --out that cannot be written fails now, not after it
    decoder = reference_decoder if args.decoder == "reference" else edge_decoder()
    t0 = time.perf_counter()
    rows = run_sweep(cfg, decoder)
    cmd = "python tools/eval_sweep.py " + " ".join(argv if argv is not None else sys.argv[1:])
    path = write_report(rows, args.out, cfg, command=cmd.strip(), decoder_name=(
        "tools/eval_sweep.py reference brute-force decoder" if args.decoder == "reference" else DECODER_NAME),
        seconds=time.perf_counter() - t0, preamble=read_findings(args.out))
    print(path.read_text())
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
