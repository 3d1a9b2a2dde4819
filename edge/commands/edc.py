"""``edge edc``: adaptive EDC re-projection on a simulated scene, and the EDC evaluation report."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._args import output_dir, parse_size


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("edc", help="error detection (CRC) and adaptive re-projection")
    sub = p.add_subparsers(dest="edc_command", metavar="ACTION", required=True)
    r = sub.add_parser("run", help="run the adaptive loop on a simulated GI scene and print per-round figures")
    r.add_argument("--scene", default="v-groove",
                   help="GI scene label of edge.eval.edc.GI_SCENES (v-groove, v-groove-30, bowl, scattering, "
                        "corner-30-2b, corner-45-2b, corner-60-gloss, corner-90-gloss, bowl-gloss, scatter-s1.5, "
                        "scatter-s4, scatter-s10, defocus-0.8, defocus-0.9)")
    r.add_argument("--code", default="xor02-10+crc5", help="EDC code name, or 'gupta' for the ensemble baseline (default %(default)s)")
    r.add_argument("--rounds", type=int, default=3, help="rounds of the adaptive loop at most (default 3)")
    r.add_argument("--size", default="256x192", help="camera WxH (default %(default)s)")
    r.add_argument("--seed", type=int, default=0, help="scene and noise seed (default 0)")
    r.add_argument("--binarisation", choices=("self", "calibrated"), default="self",
                   help="self: per-pixel min/max midpoint, no calibration frames; calibrated: white/black frames")
    r.add_argument("--no-support", action="store_true", help="switch the neighbour support check off")
    r.set_defaults(func=_run)
    e = sub.add_parser("eval", help="write the error-map ROC and loop comparison report")
    e.add_argument("--out", type=Path, default=Path("docs/results/edc"),
                   help="output folder (default docs/results/edc)")
    e.add_argument("--size", default="256x192", help="camera WxH (default 256x192)")
    e.add_argument("--seed", type=int, default=0, help="scene and noise seed (default 0)")
    e.set_defaults(func=_eval)



def _camera_size(text: str, labels: str | list[str]) -> tuple[int, int]:
    """``--size`` WxH -> (width, height) pixels, large enough for the GI scene(s) ``labels``
    (`edge.eval.edc.check_gi_size`, the one size rule of both actions); ValueError naming --size."""
    from edge.eval.edc import check_gi_size

    w, h = parse_size(text)
    try:
        check_gi_size(labels, w, h)
    except ValueError as exc:
        raise ValueError(f"--size: {exc}") from None
    return w, h


def _check_seed(seed: int) -> None:
    if seed < 0:  # numpy's "expected non-negative integer" named no option
        raise ValueError(f"--seed must be >= 0, got {seed}")


def _run(args: argparse.Namespace) -> int:
    from edge.eval.edc import gi_camera, make_gi_scene, score_loop
    from edge.edc.gupta import EnsembleScheme

    camera = gi_camera(args.scene)  # an unknown label: ValueError (one line, exit 2)
    w, h = _camera_size(args.size, args.scene)
    _check_seed(args.seed)
    if args.rounds < 1:
        raise ValueError(f"--rounds must be >= 1, got {args.rounds}")
    scene = make_gi_scene(args.scene, w, h, args.seed)
    scheme = EnsembleScheme() if args.code == "gupta" else args.code
    opts = {"neighbour_tolerance": None} if args.no_support else {}
    score, result = score_loop(scene, camera, scheme, rng=args.seed + 2, max_rounds=args.rounds,
                               binarisation=args.binarisation, **opts)
    for r in result.rounds:
        print(f"round {r.round}: {r.frames} frames ({r.calibration_frames} calibration), checked {r.checked}, "
              f"resolved {r.resolved}, failing {r.failing}, unsupported {r.unsupported}, lit {r.lit_fraction:.3f}")
    print(f"{score.scheme} on {args.scene}: {score.rounds} rounds, {score.frames_total} frames, stop: "
          f"{score.stop_reason}; single-pass errors {score.single_errors}, left {score.errors_left} "
          f"({score.errors_left_unreached} unreached) "
          f"(removed {score.removed:.1%}); correct pixels invalidated {score.wrongly_invalidated:.2%}")
    print(f"lit pixels {score.lit_pixels}: correct {score.single_correct_lit:.2%} -> {score.correct_lit:.2%}, "
          f"wrong {score.single_wrong_lit:.2%} -> {score.wrong_lit:.2%}; unlit pixels reported (wrong) "
          f"{score.single_wrong_unlit} -> {score.wrong_unlit}")
    return 0


def _eval(args: argparse.Namespace) -> int:
    from edge.eval.edc import GI_SCENES, run_report

    w, h = _camera_size(args.size, list(GI_SCENES))
    _check_seed(args.seed)
    run_report(output_dir(args.out), width=w, height=h, seed=args.seed, command=f"edge edc eval --size {args.size}")
    print(f"wrote {args.out}/README.md, roc.png, loop.png")
    return 0
