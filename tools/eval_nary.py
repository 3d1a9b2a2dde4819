"""Validity rules on non-binary (q-ary) codes: `decode`'s defaults vs the alternatives.

    python tools/eval_nary.py [--size 160x120] [--seeds 0 1] [--gen sim pbs] [--codes nary8-3 ...]

Captures as in tools/eval_posterior.py (every one of the n + 2 frames at T / n, ambient 0.5 x the
projector, 12-bit), at three shot-noise levels sigma_s = 0.01 / 0.02 / 0.04 (variance sigma_r**2 +
sigma_s**2 * I, sigma_r 0.002): `edge.sim`'s flying scene (T = n: every frame at exposure 1, as the
10-frame codes of eval_posterior, so the 3-frame codes do not saturate; stripe = projector width /
codebook rows, rounded up) and the tests' plane / box / sphere renderer (T = 10, q-ary symbols at
s / (q - 1)).  Prints, per generator, code and noise level, the error rate (wrong or invalid over
lit pixels; a column more than one codebook row off is wrong) and the coverage (valid share of lit
pixels) of:

* ``defaults``: `decode` with no options;
* ``confidence``: ``validity="confidence"``;
* ``error+calib``: ``validity="error", levels="calibration"``;
* ``error+refit``: ``validity="error", levels="refit"``.

Before the q-ary routing of `DecodeSettings.level_source` the defaults ran the error rule on the
two-level split (`edge.decode.posterior.split_levels`) for these codes too; that column is kept
in docs/results/nary/README.md.  Cells: error rate / coverage / share of the published pixels more
than one row off.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from _plane_box_sphere import render, scene as pbs_scene  # noqa: E402
from edge.codes import get_code  # noqa: E402
from edge.commands._args import parse_size  # noqa: E402
from edge.decode import decode  # noqa: E402
from edge.sim import CameraModel, capture_code  # noqa: E402
from edge.sim.metrics import truth  # noqa: E402
from edge.sim.scenes import make_scene  # noqa: E402

CODES = ("nary3-6", "nary8-3", "ternary-golay-11-6", "rs8-7-3", "rs16-12-3")
NOISE = (0.01, 0.02, 0.04)  # sigma_s
RULES = {
    "defaults": {},
    "confidence": {"validity": "confidence"},
    "error+calib": {"validity": "error", "levels": "calibration"},
    "error+refit": {"validity": "error", "levels": "refit"},
}


def sim_capture(code, sigma_s, seed, size):
    """(frames, white, black, bit_depth, stripe, truth codebook row (H, W), lit (H, W) bool)."""
    scene = make_scene("flying", size[0], size[1], seed=seed)
    stripe = -(-int(scene.geometry.projector_width) // code.size)
    a = 0.8 * 0.5 / 1.5
    cam = CameraModel(bits=12, sigma_r=0.002, sigma_s=sigma_s, ambient=a, projector=0.8 - a,
                      total_exposure=float(code.n))
    cap = capture_code(scene, code, cam, rng=np.random.default_rng([seed, 7]), stripe=stripe)
    col, lit = truth(scene)
    return cap.frames, cap.white, cap.black, 12, stripe, col // stripe, lit


def pbs_capture(code, sigma_s, seed, size):
    col, albedo = pbs_scene(size[0], size[1], seed=seed + 3, columns=min(1024, code.size))
    f, w, b = render(code.codebook, col, albedo, ambient=0.06, projector=0.12, shot=sigma_s, bits=12,
                     seed=seed + 4, q=code.q)
    return f, w, b, 12, 1, col, np.ones(col.shape, bool)


GENERATORS = {"sim": ("edge.sim", sim_capture), "pbs": ("plane-box-sphere", pbs_capture)}


def rates(gen, code, sigma_s, seeds, size, options) -> tuple[float, float, float]:
    """(error rate, coverage, wrong share of the published) over lit pixels, summed over seeds."""
    e_sum = v_sum = o_sum = n_sum = 0
    for seed in seeds:
        f, w, b, bd, stripe, row, lit = gen(code, sigma_s, seed, size)
        d = decode(f, w, b, code, bit_depth=bd, stripe=stripe, **options)
        off = np.abs(d.column.astype(np.int64) - row) > 1
        e_sum += int(((off | ~d.valid) & lit).sum())
        v_sum += int((d.valid & lit).sum())
        o_sum += int((off & d.valid & lit).sum())
        n_sum += int(lit.sum())
    return e_sum / n_sum, v_sum / n_sum, o_sum / max(v_sum, 1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="160x120", help="scene size WxH (default 160x120)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="scene / noise seeds (default 0 1)")
    ap.add_argument("--gen", nargs="+", default=list(GENERATORS), choices=list(GENERATORS),
                    help=f"scene generators (default: all, {' '.join(GENERATORS)})")
    ap.add_argument("--codes", nargs="+", default=list(CODES), help=f"code names (default: the table's codes, {' '.join(CODES)})")
    ap.add_argument("--rules", nargs="+", default=list(RULES), choices=list(RULES),
                    help=f"validity rules / level sources compared (default: all, {' '.join(RULES)})")
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    for g in args.gen:
        label, gen = GENERATORS[g]
        print(f"\n## {label}: error rate (wrong or invalid over lit pixels) / coverage / wrong share of the "
              f"published, seeds {' '.join(map(str, args.seeds))}\n")
        print("| code | sigma_s | " + " | ".join(args.rules) + " |")
        print("|---" * (len(args.rules) + 2) + "|")
        for name in args.codes:
            code = get_code(name)
            for sigma_s in NOISE:
                cells = []
                for rule in args.rules:
                    e, v, o = rates(gen, code, sigma_s, args.seeds, size, RULES[rule])
                    cells.append(f"{e:.4f} / {v:.3f} / {o:.4f}")
                print(f"| {name} | {sigma_s} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    from edge.cli import tool_main

    raise SystemExit(tool_main(main, __file__))
